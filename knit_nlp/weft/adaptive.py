"""Adaptive representatives for the reduction (the paper's open question: which loops).

Start from the corner form; after each solve of the condensed reduced model
(``condensed.CondensedNLP``):

1. **Indicator** per loop: the full model's first Newton steps from the prolonged reduced
   solution (``PROBE_ITERATIONS`` IPOPT iterations of the full NLP, built once, started from
   the lifted loops), measured as each loop's RMS centreline displacement η_ij in length
   units. Near the full solution this is the reduced solution's error, so it is zero at a full
   solution and its RMS over the fabric is the error *estimate*. Measured against the true
   error (Spearman rank correlation over loops; estimate against true RMS):
   one step from the corner form: 0.97 (12 × 12 diagonal pull; 8.1 against 6.0), 0.98
   (8 × 8 course pull; 0.21 against 0.19), 0.36 (9 × 7 diagonal; 1.2 against 4.6);
   30 × 30 diagonal: from the corner form −0.33 (1.1 against 14.3; 3 steps −0.30, 2.0),
   from the even 6 × 6 grid −0.44 after one step (0.05 against 6.2) but 0.96 after three
   (7.6) and 1.00 after six (6.17 against 6.17). Far from the full solution the Hessian is
   indefinite and IPOPT's regularisation shortens the steps, so the estimate is then too low.
   The full model's stationarity residual (gradient of the Lagrangian with the best
   continuity multipliers) was tried first and ranked loops against the error (−0.39, −0.53;
   0.09): it is largest beside the clamps, while the error accumulates far from them.
2. **Marking**: between consecutive representative courses (wales) the indicator's squares are
   summed over the loops the interval interpolates; every interval scoring at least
   ``MARK`` × the largest, per parameter its bisection adds, is bisected (tensor grid).
3. **Re-solve** warm-started from the previous solution lifted exactly into the finer grid
   (the spaces are nested: piecewise-linear hats on a refined grid contain the coarse ones), so
   the energy cannot rise.
4. **Stop** when the estimate is at most ``tolerance`` or the next grid would exceed
   ``max_parameters``.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from .condensed import CondensedNLP
from .nlp import build_nlp, n_parameters
from .parametrisation import Adaptive, Full, Reduced
from .problem import WeftProblem
from .sampling import centrelines, solution_centrelines
from .solve import SolveReport, WeftSolver, solve

MARK = 0.5
PROBE_ITERATIONS = 3


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
    estimate: float               # RMS of η over the loops: the estimated RMS error (length)
    lines: np.ndarray | None = field(default=None, repr=False)   # sampled centrelines

    def as_dict(self) -> dict:
        return {"representative_courses": list(self.courses),
                "representative_wales": list(self.wales), "n_parameters": self.n_parameters,
                "energy": self.energy, "iterations": self.iterations, "solve_s": self.solve_s,
                "success": self.success, "estimate": self.estimate}


@dataclass
class AdaptiveRun:
    """The final model and report, and every step taken."""

    cnlp: CondensedNLP
    solver: WeftSolver
    report: SolveReport
    steps: list[AdaptiveStep] = field(default_factory=list)
    build_s: float = 0.0


class NewtonProbe:
    """A few IPOPT iterations of the full model (built once) from a prolonged reduced solution."""

    def __init__(self, pr: WeftProblem) -> None:
        self.full = build_nlp(pr)
        self.solver = WeftSolver(self.full, max_iter=PROBE_ITERATIONS)

    def step(self, coeffs: np.ndarray, starts: np.ndarray, samples: int) -> np.ndarray:
        """η (m, n): per loop, the RMS centreline displacement (length units) of the full
        model's first Newton steps from the loops ``coeffs``, ``starts`` (module docstring)."""
        pr = self.full.problem
        x0 = self.full.lift(coeffs, starts)
        rep = self.solver.once(self.full.p0, x0)
        before = centrelines(coeffs, starts, pr.L, pr.t, samples)[0]
        after = solution_centrelines(self.full, rep.x, samples)
        return np.sqrt(np.mean(np.sum((after - before) ** 2, axis=-1), axis=-1))


def _bisections(reps: tuple[int, ...], scores: np.ndarray) -> list[tuple[float, int]]:
    """(score, new index) for every representative interval that can be bisected; ``scores``
    are per course (wale) sums of η²."""
    out = []
    for lo, hi in zip(reps[:-1], reps[1:]):
        if hi - lo > 1:
            out.append((float(scores[lo - 1:hi].sum()), (lo + hi) // 2))
    return out


def refine(red: Reduced, eta: np.ndarray, t: int) -> Reduced:
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


def solve_adaptive(pr: WeftProblem, cfg: Adaptive = Adaptive(), samples: int = 21,
                   continuation: int | None = None) -> AdaptiveRun:
    """Refine the representatives from the corners (module docstring); return the last solve."""
    tol = cfg.tolerance if cfg.tolerance is not None else 0.1 * pr.L
    budget = cfg.max_parameters or n_parameters(pr, Full()) * 3 // 10
    red = Reduced().resolve(pr.courses, pr.wales)
    probe = NewtonProbe(pr)
    run, start = None, None
    while True:
        t0 = time.perf_counter()
        cnlp = CondensedNLP(pr, red)
        solver = WeftSolver(cnlp)
        build_s = time.perf_counter() - t0
        x0 = None if start is None else cnlp.lift(*start)
        rep = solve(cnlp, solver, x0=x0, continuation=continuation)
        coeffs, starts = cnlp.coefficients(rep.x), cnlp.starts(rep.x)
        lines = centrelines(coeffs, starts, pr.L, pr.t, samples)[0]
        eta = probe.step(coeffs, starts, samples)
        est = float(np.sqrt(np.mean(eta ** 2)))
        spring, bend, _ = cnlp.energy(rep.x, cnlp.p0)
        step = AdaptiveStep(red.courses, red.wales, cnlp.n_parameters, spring + bend,
                            rep.iterations, rep.solve_s, rep.success, est, lines)
        if run is None:
            run = AdaptiveRun(cnlp, solver, rep, [step], build_s)
        else:
            rep.add_effort(run.report)
            run.cnlp, run.solver, run.report = cnlp, solver, rep
            run.build_s += build_s
            run.steps.append(step)
        finer = refine(red, eta, pr.t)
        if (not rep.success or est <= tol or finer == red
                or n_parameters(pr, finer) > budget):
            return run
        red, start = finer, (coeffs, starts)
