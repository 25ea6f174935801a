"""Adaptive representatives for the reduction (the paper's open question: which loops).

Start from the corner form; after each solve of the condensed reduced model
(``condensed.CondensedNLP``):

1. **Indicator** per loop: the full model's stationarity residual at the prolonged reduced
   solution: the gradient of the Lagrangian with respect to every loop's coefficients (loop
   starts chained along courses, the reduced solve's clamp multipliers) minus its least-squares
   fit by the continuity constraints' rows (18)-(19), i.e. with the best continuity
   multipliers; η_ij is its norm on loop (i, j). It is zero at a full-model solution. (Measured
   first: the same gradient in the free coordinates of the all-representative map ranked the
   loops near the start of each course highest, a lever-arm effect of the continuity
   recursion, and steered refinement away from the pulled corner.)
2. **Marking**: between consecutive representative courses (wales) the indicator's squares are
   summed over the loops the interval interpolates; every interval scoring at least
   ``MARK`` × the largest, per parameter its bisection adds, is bisected (tensor grid).
3. **Re-solve** warm-started from the previous solution lifted exactly into the finer grid
   (the spaces are nested: piecewise-linear hats on a refined grid contain the coarse ones), so
   the energy cannot rise.
4. **Estimate**: the RMS centreline distance between the last two solutions (length units);
   stop when it is at most ``tolerance`` or the next grid would exceed ``max_parameters``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from .basis import continuity_rows, n_coeffs
from .condensed import CondensedNLP
from .problem import Reduction, WeftProblem
from .reduction import default_reduction
from .results import centrelines
from .solve import SolveReport, WeftSolver, solve

MARK = 0.5


@dataclass
class AdaptiveStep:
    """One grid of the refinement and its solve."""

    courses: tuple[int, ...]
    wales: tuple[int, ...]
    n_parameters: int
    energy: float
    iterations: int
    solve_s: float
    success: bool
    indicator: float              # sqrt(Σ η²) over all loops
    estimate: float | None        # RMS centreline change from the previous grid (length units)
    lines: np.ndarray | None = field(default=None, repr=False)   # sampled centrelines

    def as_dict(self) -> dict:
        return {"representative_courses": list(self.courses),
                "representative_wales": list(self.wales), "n_parameters": self.n_parameters,
                "energy": self.energy, "iterations": self.iterations, "solve_s": self.solve_s,
                "success": self.success, "indicator": self.indicator, "estimate": self.estimate}


@dataclass
class AdaptiveRun:
    """The final model and report, and every step taken."""

    cnlp: CondensedNLP
    report: SolveReport
    steps: list[AdaptiveStep] = field(default_factory=list)
    build_s: float = 0.0


def loop_indicator(cnlp: CondensedNLP, x: np.ndarray, lam: np.ndarray,
                   p: np.ndarray | None = None) -> np.ndarray:
    """η (m, n): per loop, the norm of the full model's Lagrangian gradient at the prolonged
    solution x, projected onto the continuity constraints' null space (module docstring)."""
    pr = cnlp.problem
    m, n, nc = pr.courses, pr.wales, n_coeffs(pr.t)
    ga, _ = cnlp.coefficient_gradient(cnlp.w(x), cnlp.p0 if p is None else p, 1.0, lam)
    G = ga.reshape(m, n * nc)
    if n > 1:
        E, S = continuity_rows(pr.L, pr.t)
        C = np.zeros((2 * (n - 1), n * nc))
        for j in range(n - 1):
            C[2 * j:2 * j + 2, j * nc:(j + 1) * nc] = E
            C[2 * j:2 * j + 2, (j + 1) * nc:(j + 2) * nc] = -S
        G = G - np.linalg.solve(C @ C.T, C @ G.T).T @ C
    return np.linalg.norm(G.reshape(m, n, nc), axis=2)


def _bisections(reps: tuple[int, ...], scores: np.ndarray) -> list[tuple[float, int]]:
    """(score, new index) for every representative interval that can be bisected; ``scores``
    are per course (wale) sums of η²."""
    out = []
    for lo, hi in zip(reps[:-1], reps[1:]):
        if hi - lo > 1:
            out.append((float(scores[lo - 1:hi].sum()), (lo + hi) // 2))
    return out


def refine(red: Reduction, eta: np.ndarray, t: int) -> Reduction:
    """Bisect every interval whose indicator per added parameter is at least MARK × the best."""
    p, q = len(red.courses), len(red.wales)
    cand = [(s / (q * 2 * t + 2), "c", k) for s, k in _bisections(red.courses, (eta ** 2).sum(1))]
    cand += [(s / (p * 2 * t), "w", k) for s, k in _bisections(red.wales, (eta ** 2).sum(0))]
    if not cand:
        return red
    best = max(c[0] for c in cand)
    courses, wales = set(red.courses), set(red.wales)
    for score, axis, k in cand:
        if score >= MARK * best:
            (courses if axis == "c" else wales).add(k)
    return replace(red, courses=tuple(sorted(courses)), wales=tuple(sorted(wales)))


def n_reduced_parameters(pr: WeftProblem, red: Reduction) -> int:
    """The paper's count for a grid: p·q·2t + 2p + 2m."""
    return len(red.courses) * len(red.wales) * 2 * pr.t + 2 * len(red.courses) + 2 * pr.courses


def solve_adaptive(pr: WeftProblem, samples: int = 21,
                   continuation: int | None = None) -> AdaptiveRun:
    """Refine the representatives from the corners (module docstring); return the last solve."""
    cfg = pr.reduction or Reduction((1, pr.courses), (1, pr.wales), adaptive=True)
    tol = cfg.tolerance if cfg.tolerance is not None else 0.1 * pr.L
    budget = cfg.max_parameters or (pr.n_loops * n_coeffs(pr.t) + 2 * pr.courses) * 3 // 10
    corner = default_reduction(pr)
    red = replace(cfg, courses=corner.courses, wales=corner.wales)
    run, prev_lines, start = None, None, None
    while True:
        t0 = time.perf_counter()
        cnlp = CondensedNLP(pr, red)
        solver = WeftSolver(cnlp)
        build_s = time.perf_counter() - t0
        x0 = None if start is None else cnlp.lift(*start)
        rep = solve(cnlp, solver, x0=x0, continuation=continuation)
        coeffs, starts = cnlp.coefficients(rep.x), cnlp.starts(rep.x)
        lines = centrelines(coeffs, starts, pr.L, pr.t, samples)[0]
        eta = loop_indicator(cnlp, rep.x, rep.lam_g)
        est = None if prev_lines is None else float(
            np.sqrt(np.mean(np.sum((lines - prev_lines) ** 2, axis=-1))))
        spring, bend, _ = cnlp.energy(rep.x, cnlp.p0)
        step = AdaptiveStep(red.courses, red.wales, cnlp.n_parameters, spring + bend,
                            rep.iterations, rep.solve_s, rep.success,
                            float(np.sqrt((eta ** 2).sum())), est, lines)
        if run is None:
            run = AdaptiveRun(cnlp, rep, [step], build_s)
        else:
            rep.add_effort(run.report)
            run.cnlp, run.report, run.build_s = cnlp, rep, run.build_s + build_s
            run.steps.append(step)
        finer = refine(red, eta, pr.t)
        if (not rep.success or (est is not None and est <= tol) or finer == red
                or n_reduced_parameters(pr, finer) > budget):
            return run
        red, prev_lines, start = finer, lines, (coeffs, starts)
