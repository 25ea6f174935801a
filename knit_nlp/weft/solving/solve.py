"""Solving the weft NLP with IPOPT: direct, by continuation, and from perturbed starts.

- Direct: one IPOPT solve from the natural configuration (or a given start).
- Continuation: clamp targets, clamp angles and loads are stepped from their natural values to
  the problem's in equal steps, each solve warm-started from the last; a failed step is halved
  (up to ``max_halvings`` times). Used when the direct solve fails, or always when asked.
- Degenerate starts: where the natural yarn is straight, a compressive clamp leaves IPOPT at a
  point where the end position does not depend, to first order, on the shape (the Jacobian
  loses rank). The solve then starts from each of a few smooth perturbations of the natural
  shape (θ ∝ cos, sin of πS/ℓ and 2πS/ℓ along each course of length ℓ) and keeps the successful
  solution of lowest energy, which is the lowest buckling mode.
The NLP is built once; every solve reuses the same ``casadi.nlpsol`` object.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ...ipopt import ipopt_options, succeeded
from ...progress import IterationLine
from ..transcription.derivatives import closed_form_derivatives
from .guesses import needs_perturbation, perturbed_starts
from ..transcription.full import WeftNLP
from ..model.params import WeftParams
from .starts import start_point

DEFAULT_START = "multilevel"    # measured: see README, "Measured performance"

OUT_OF_TIME = "Maximum_WallTime_Exceeded"      # IPOPT's own name, also used between solves


@dataclass
class SolveReport:
    """Outcome of a solve: the solution vector, multipliers, IPOPT's status, effort and timing."""

    success: bool
    status: str
    x: np.ndarray
    lam_g: np.ndarray
    objective: float
    iterations: int
    solve_s: float
    continuation_steps: int = 0
    attempts: list[str] = field(default_factory=list)
    stats: dict[str, float] = field(default_factory=dict)
    # continuation: (load factor, x, lam_g) of every step reached, the loading path
    path: list[tuple[float, np.ndarray, np.ndarray]] = field(default_factory=list)

    def add_effort(self, other: "SolveReport") -> None:
        """Count another solve's iterations, time and IPOPT profile into this report."""
        self.iterations += other.iterations
        self.solve_s += other.solve_s
        self.stats = {k: self.stats.get(k, 0.0) + other.stats.get(k, 0.0)
                      for k in set(self.stats) | set(other.stats)}


class WeftSolver:
    """One IPOPT instance for one assembled NLP, reusable across parameter values and starts."""

    def __init__(self, wnlp: WeftNLP, tol: float | None = None, max_iter: int | None = None,
                 print_level: int = 0, verbose: bool = False, derivatives: str = "closed_form",
                 ipopt: dict | None = None) -> None:
        opts = wnlp.problem.solver
        self.wnlp = wnlp
        t0 = time.perf_counter()
        # measured on the 100 x 100 pull: MUMPS's scaling passes cost a third of IPOPT's own
        # time and the KKT systems here are well scaled without them
        options = {**ipopt_options(tol or opts.tol, max_iter or opts.max_iter, print_level,
                                   max_wall_time=opts.max_time, mumps_scaling=0,
                                   mumps_permuting_scaling=0, **(ipopt or {})),
                   **wnlp.nlpsol_options}
        self.progress = IterationLine(wnlp.n_variables, wnlp.n_constraints) if verbose else None
        if self.progress is not None:
            options["iteration_callback"] = self.progress
        self.solver = ca.nlpsol("weft", "ipopt", wnlp.nlp,
                                {**options, **derivative_options(wnlp, derivatives)})
        self.setup_s = time.perf_counter() - t0
        self.start_clock()
        self._g = ca.Function("g", [wnlp.nlp["x"], wnlp.nlp["p"]], [wnlp.nlp["g"]])

    def start_clock(self) -> None:
        """Start the wall-clock budget ``[solver] max_time`` shared by the solves that follow
        (each IPOPT call also stops itself at ``max_wall_time`` = max_time)."""
        self.deadline = time.perf_counter() + self.wnlp.problem.solver.max_time

    def once(self, p: np.ndarray, x0: np.ndarray) -> SolveReport:
        """A single IPOPT solve from x0 (none once the time budget is spent)."""
        t0 = time.perf_counter()
        if t0 >= self.deadline:
            return SolveReport(False, OUT_OF_TIME, x0, np.zeros(self.wnlp.n_constraints),
                               np.nan, 0, 0.0)
        sol = self.solver(x0=x0, p=p, lbg=0.0, ubg=0.0)
        stats = self.solver.stats()
        status = str(stats["return_status"])
        return SolveReport(succeeded(status), status, np.asarray(sol["x"]).ravel(),
                           np.asarray(sol["lam_g"]).ravel(), float(sol["f"]),
                           int(stats["iter_count"]), time.perf_counter() - t0,
                           stats={k: float(v) for k, v in stats.items() if k.startswith("t_wall")})

    def violation(self, x: np.ndarray, p: np.ndarray) -> float:
        """Largest absolute constraint residual |g| at x."""
        g = np.asarray(self._g(x, p)).ravel()
        return float(np.max(np.abs(g))) if g.size else 0.0

    def continuation(self, p: np.ndarray, x0: np.ndarray, steps: int,
                     max_halvings: int = 6) -> SolveReport:
        """Step the parameters from their natural values to ``p``, warm-starting each solve."""
        p_nat = WeftParams.natural(self.wnlp.problem).vector()
        x, tau, dtau = x0, 0.0, 1.0 / steps
        total = SolveReport(False, "", x0, np.zeros(self.wnlp.n_constraints), np.nan, 0, 0.0)
        halvings = 0
        while tau < 1.0 - 1e-12:
            if time.perf_counter() >= self.deadline:
                total.status = OUT_OF_TIME
                return total
            nxt = min(1.0, tau + dtau)
            rep = self.once(p_nat + nxt * (p - p_nat), x)
            total.add_effort(rep)
            if rep.success:
                x, tau = rep.x, nxt
                total.continuation_steps += 1
                total.path.append((tau, rep.x, rep.lam_g))
                total.x, total.lam_g, total.objective, total.status = rep.x, rep.lam_g, rep.objective, rep.status
                continue
            halvings += 1
            if halvings > max_halvings:
                total.status, total.x, total.lam_g = rep.status, rep.x, rep.lam_g
                return total
            dtau /= 2
        total.success = True
        return total


def derivative_options(wnlp: WeftNLP, derivatives: str) -> dict:
    """nlpsol options for the derivatives: ``closed_form`` (derivatives.py; full model only,
    measured faster, see README) or ``casadi`` (CasADi's AD of the NLP expressions)."""
    if derivatives not in ("closed_form", "casadi"):
        raise ValueError(f"unknown derivatives {derivatives!r}")
    if derivatives == "casadi" or wnlp.model != "full":
        return {}
    return closed_form_derivatives(wnlp)


def solve(wnlp: WeftNLP, solver: WeftSolver | None = None, params: WeftParams | None = None,
          x0: np.ndarray | None = None, continuation: int | None = None,
          start: str = DEFAULT_START) -> SolveReport:
    """Solve robustly at ``params`` (the problem's own by default): direct, then continuation;
    from perturbed starts where degenerate. Without x0 the solve starts from ``start``
    (start.py: ``multilevel``, ``rigid`` or ``natural``); a multilevel start's coarse solves
    count into ``solve_s`` and ``attempts``."""
    solver = solver or WeftSolver(wnlp)
    solver.start_clock()
    p = (params or wnlp.params).vector()
    continuation = continuation or wnlp.problem.solver.continuation
    if needs_perturbation(wnlp, p) and x0 is None:
        return _best_of_perturbed(wnlp, solver, p, continuation)
    if x0 is not None:
        return _direct_then_continuation(solver, p, x0, continuation)
    t0, levels = time.perf_counter(), []
    x0 = start_point(wnlp, p, start, levels)
    start_s = time.perf_counter() - t0
    rep = _direct_then_continuation(solver, p, x0, continuation)
    rep.solve_s += start_s          # the coarse solves are part of solving this problem
    rep.attempts = levels + rep.attempts
    return rep


def _direct_then_continuation(solver: WeftSolver, p: np.ndarray, x0: np.ndarray,
                              continuation: int | None) -> SolveReport:
    attempts, tried = [], []
    if continuation is None:
        rep = solver.once(p, x0)
        attempts.append(f"direct: {rep.status} ({rep.iterations} it)")
        tried.append(rep)
    for steps in ([] if tried and tried[-1].success else [continuation] if continuation else [4, 16]):
        rep = solver.continuation(p, x0, steps)
        attempts.append(f"continuation x{steps}: {rep.status} ({rep.iterations} it, "
                        f"{rep.continuation_steps} steps)")
        tried.append(rep)
        if rep.success:
            break
    return _combined(tried[-1], tried[:-1], attempts)


def _combined(final: SolveReport, others: list[SolveReport], attempts: list[str]) -> SolveReport:
    """``final`` carrying the effort of every other solve tried and the list of attempts."""
    for other in others:
        final.add_effort(other)
    final.attempts = attempts
    return final


def _best_of_perturbed(wnlp: WeftNLP, solver: WeftSolver, p: np.ndarray,
                       continuation: int | None) -> SolveReport:
    best, attempts, tried = None, [], []
    for name, x0 in perturbed_starts(wnlp):
        rep = _direct_then_continuation(solver, p, x0, continuation)
        attempts += [f"perturbed {name}: {a}" for a in rep.attempts]
        tried.append(rep)
        if rep.success and (best is None or rep.objective < best.objective - 1e-12):
            best = rep
    final = best or tried[-1]
    return _combined(final, [r for r in tried if r is not final], attempts)
