"""Adaptive representatives for the reduction (the paper's open question: which loops).

Start from the corner form; after each solve of the condensed reduced model
(``transcribe(problem, Reduced(...))``) on the tensor grid G:

1. **Hierarchical indicator.** For each axis (courses, wales) whose representatives are not yet
   every index, the *candidate* grid bisects every interval of that axis (``bisect``) and is
   solved warm-started from G's solution lifted exactly (the spaces are nested: piecewise-linear
   hats on a refined grid contain the coarse ones). δ_a per loop is the RMS centreline distance
   (length units) between G's solution and candidate a's. The indicator is
   η = √(Σ_a (R_a·δ_a)²), R_a the number of bisections axis a still needs before every index is
   representative; the *estimate* is the RMS of η over the loops. The factor R_a is the
   telescoping sum of the remaining bisections' changes assuming no saturation (each later
   change as large as this one): measured on the 30 × 30 diagonal pull the changes do not
   shrink until the grid is nearly full (RMS 3.9, 4.0, 3.3, 3.7 along 2² → 3² → 5² → 9² → 17²)
   so the plain difference δ underestimates the error 2.5-6 × on coarse grids (true RMS 14.3,
   difference 2.6 from the corners). η is zero where G's solution is also the finer grids'
   (at the full solution, when G contains it) and ranks loops like the true error: along the
   30 × 30 run (docs/measurements.md) Spearman 0.81-0.96 over the loops and estimate / true RMS 0.90-2.0.
   Measured and not kept: a few full-model IPOPT iterations from the lifted solution (the
   previous indicator): far from the full solution the Hessian is indefinite and IPOPT's
   regularisation shortens the steps, so it estimated 0.31 for a true RMS error of 10.6 and
   ranked loops against the error (Spearman −0.33 from the corners); the full model's
   stationarity residual (largest beside the clamps, while the error accumulates far from them).
2. **Marking.** Each representative interval of either axis scores the δ_a² summed over the
   loops it interpolates, per parameter its bisection adds; every interval scoring at least
   ``MARK`` × the best is bisected, best first, as long as the grid stays within
   ``max_parameters`` (a candidate's solve is reused when the marked grid is that candidate;
   otherwise the marked grid is solved warm-started from G's solution, again exactly nested).
   So the energy never rises. Measured on the 30 × 30 diagonal pull: choosing instead the
   candidate axis with the largest energy drop per parameter ended at 1 740 parameters with an
   estimate above the tolerance (true RMS 0.64, 12 grids); MARK = 0.5 at 2 032 (0.25, 11
   grids, 70 s), MARK = 0.25 at 2 140 (0.25, 8 grids, 64 s), both stopping at the tolerance.
3. **Stop** when the estimate is at most ``tolerance``, no marked bisection fits
   ``max_parameters``, every index is representative, or a solve fails. The candidates of the
   last grid are solved for its estimate even when they exceed the budget (they are the
   estimator, not the model).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..model.centrelines import centrelines
from ..model.parametrisation import Adaptive, Full, Reduced
from ..model.params import WeftParams
from ..model.problem import WeftProblem
from ..transcription.protocol import WeftNLP
from ..transcription.rows import n_parameters
from .blocks import AdaptiveBlock
from .solve import DEFAULT_START, Equilibrium, Solution, SolveReport, WeftSolver

MARK = 0.25


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

    cnlp: WeftNLP
    solver: WeftSolver
    report: SolveReport
    steps: list[AdaptiveStep] = field(default_factory=list)
    build_s: float = 0.0


@dataclass
class GridSolve:
    """The condensed model on one grid, solved: its loops, centrelines and energy."""

    red: Reduced
    cnlp: WeftNLP
    solver: WeftSolver
    report: SolveReport
    coeffs: np.ndarray
    starts: np.ndarray
    lines: np.ndarray
    energy: float
    build_s: float
    params: WeftParams


def solve_grid(pr: WeftProblem, red: Reduced, start: GridSolve | None = None,
               samples: int = 21, continuation: int | None = None,
               params: WeftParams | None = None) -> GridSolve:
    """Build and solve the condensed model on ``red`` at ``params`` (default: ``start``'s, else
    the problem's own), from ``start``'s loops lifted (its grid must be contained in ``red`` for
    the lift to be exact) or the model's default start. The factory may add the clamped courses
    and wales (dependent clamps); the result's ``red`` is the grid solved."""
    eq = Equilibrium(pr, red)
    cnlp = eq.nlp
    params = params or (start.params if start is not None else cnlp.params)
    x0 = None if start is None else cnlp.lift(start.coeffs, start.starts)
    rep = eq.solve(params, x0, continuation=continuation)
    coeffs, starts = cnlp.coefficients(rep.x), cnlp.starts(rep.x)
    spring, bend, _ = cnlp.energy(rep.x, params.vector())
    return GridSolve(cnlp.parametrisation, cnlp, eq.solver, rep, coeffs, starts,
                     centrelines(coeffs, starts, pr.L, pr.t, samples)[0], spring + bend,
                     eq.build_s, params)


def bisect(reps: tuple[int, ...], marked: set[int] | None = None) -> tuple[int, ...]:
    """``reps`` with the midpoint of every interval wider than one index (of those starting at
    a representative in ``marked``, if given) added."""
    out = set(reps)
    for lo, hi in zip(reps[:-1], reps[1:]):
        if hi - lo > 1 and (marked is None or lo in marked):
            out.add((lo + hi) // 2)
    return tuple(sorted(out))


def bisections_left(reps: tuple[int, ...]) -> int:
    """How many uniform bisections ``reps`` needs until every index is representative."""
    count = 0
    while any(hi - lo > 1 for lo, hi in zip(reps[:-1], reps[1:])):
        reps, count = bisect(reps), count + 1
    return count


def distance(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per loop (m, n): RMS distance between two sets of sampled centrelines (m, n, s, 2)."""
    return np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1), axis=-1))


@dataclass
class Indicator:
    """The hierarchical indicator of one grid's solution (module docstring, item 1)."""

    eta: np.ndarray                                  # (m, n) per loop, length units
    estimate: float                                  # RMS of eta
    delta: dict[str, np.ndarray]                     # axis "c" / "w": per loop δ_a
    candidates: dict[str, GridSolve]                 # axis: the bisected grid, solved


def indicator(pr: WeftProblem, grid: GridSolve, samples: int = 21,
              continuation: int | None = None) -> Indicator:
    """Solve the course- and wale-bisected grids of ``grid`` warm-started from it and measure
    how far each loop moves (module docstring, item 1)."""
    red = grid.red
    eta2 = np.zeros((pr.courses, pr.wales))
    delta, cands = {}, {}
    for axis in ("c", "w"):
        reps = red.courses if axis == "c" else red.wales
        left = bisections_left(reps)
        if left == 0:
            continue
        finer = (replace(red, courses=bisect(reps)) if axis == "c"
                 else replace(red, wales=bisect(reps)))
        cand = solve_grid(pr, finer, grid, samples, continuation)
        cands[axis] = cand
        delta[axis] = distance(grid.lines, cand.lines)
        eta2 += (left * delta[axis]) ** 2
    return Indicator(np.sqrt(eta2), float(np.sqrt(np.mean(eta2))), delta, cands)


def _next_grid(pr: WeftProblem, grid: GridSolve, ind: Indicator,
               budget: int) -> tuple[Reduced, GridSolve | None] | None:
    """The next grid (and its solve when a candidate's is reused), or None (module docstring,
    item 2)."""
    red, t = grid.red, pr.t
    p, q = len(red.courses), len(red.wales)
    scored = []                                     # (δ² per added parameter, axis, lo)
    for axis in ind.delta:
        reps = red.courses if axis == "c" else red.wales
        d2 = (ind.delta[axis] ** 2).sum(1 if axis == "c" else 0)    # per course (wale)
        per = q * 2 * t + 2 if axis == "c" else p * 2 * t           # parameters one index adds
        scored += [(float(d2[lo - 1:hi].sum()) / per, axis, lo)
                   for lo, hi in zip(reps[:-1], reps[1:]) if hi - lo > 1]
    if not scored:
        return None
    scored.sort(reverse=True)
    marked: dict[str, set[int]] = {"c": set(), "w": set()}
    finer = red
    for score, axis, lo in scored:
        if score < MARK * scored[0][0]:
            break
        marked[axis].add(lo)
        trial = Reduced(bisect(red.courses, marked["c"]), bisect(red.wales, marked["w"]))
        if n_parameters(pr, trial) > budget:
            marked[axis].discard(lo)
            continue
        finer = trial
    if finer == red:
        return None
    reuse = next((c for c in ind.candidates.values() if c.red == finer and c.report.success),
                 None)
    return finer, reuse


def solve_adaptive(pr: WeftProblem, cfg: Adaptive = Adaptive(), samples: int = 21,
                   continuation: int | None = None,
                   params: WeftParams | None = None) -> AdaptiveRun:
    """Refine the representatives from the corners (module docstring) at ``params`` (default:
    the problem's own); return the last grid's solve."""
    tol = cfg.tolerance if cfg.tolerance is not None else 0.1 * pr.L
    budget = cfg.max_parameters or n_parameters(pr, Full()) * 3 // 10
    grid = solve_grid(pr, Reduced().resolve(pr.courses, pr.wales), None, samples, continuation,
                      params)
    run = None
    while True:
        rep = grid.report
        ind = indicator(pr, grid, samples, continuation) if rep.success else None
        est = ind.estimate if ind is not None else float("nan")
        red = grid.red
        step = AdaptiveStep(red.courses, red.wales, grid.cnlp.n_parameters, grid.energy,
                            rep.iterations, rep.solve_s, rep.success, est, grid.lines)
        if run is None:
            run = AdaptiveRun(grid.cnlp, grid.solver, rep, [step], grid.build_s)
        else:
            rep.add_effort(run.report)
            run.cnlp, run.solver, run.report = grid.cnlp, grid.solver, rep
            run.build_s += grid.build_s
            run.steps.append(step)
        if ind is None:
            return run
        for cand in ind.candidates.values():       # the estimator's solves are this run's effort
            rep.add_effort(cand.report)
            run.build_s += cand.build_s
        nxt = None if est <= tol else _next_grid(pr, grid, ind, budget)
        if nxt is None:
            return run
        red, reuse = nxt
        grid = reuse if reuse is not None else solve_grid(pr, red, grid, samples, continuation)


class AdaptiveEquilibrium:
    """Adaptive representatives (module docstring) at any parameters: every solve refines from
    the corners afresh (a grid fitted to one load is not another's), so a warm start ``x0``
    (a vector of some other grid) is not used and a start from another model's loops is
    refused (:meth:`lift`); no sensitivities. The solution carries every step's grid in its
    ``adaptive`` block."""

    with_contact = False

    def __init__(self, problem: WeftProblem, config: Adaptive) -> None:
        self.problem, self.config = problem, config
        self.forward_solves = 0
        self.build_s = 0.0

    @property
    def params(self) -> WeftParams:
        return WeftParams.of(self.problem)

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        raise ValueError("start does not apply to adaptive representatives: they start "
                         "from the corner form")

    def solve(self, params: WeftParams | None = None, x0: np.ndarray | None = None, *,
              continuation: int | None = None, start: str = DEFAULT_START,
              x0_params: WeftParams | None = None, origin=None) -> Solution:
        """Refine from the corners at ``params`` (``x0``, ``x0_params``, ``start`` and
        ``origin`` are not used)."""
        self.forward_solves += 1
        run = solve_adaptive(self.problem, self.config, continuation=continuation, params=params)
        p = params or run.cnlp.params
        self.build_s = run.build_s
        return Solution.of(run.report, nlp=run.cnlp, params=p, build_s=run.build_s,
                           violation=run.solver.violation(run.report.x, p.vector()),
                           adaptive=AdaptiveBlock(tuple(st.as_dict() for st in run.steps),
                                                  run.steps[-1].estimate))

    def done(self) -> None:
        """Nothing to close: each grid's solver ends its own progress line."""
