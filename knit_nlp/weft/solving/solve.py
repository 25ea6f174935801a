"""Solving a weft NLP with IPOPT: direct, by continuation, from perturbed and multilevel starts.

- Direct: one IPOPT solve from the natural configuration (or a given start).
- Continuation: clamp targets, clamp angles and loads are stepped from their natural values to
  the problem's in equal steps, each solve warm-started from the last; a failed step is halved
  (up to ``max_halvings`` times). Used when the direct solve fails, or always when asked.
- Degenerate starts: where the natural yarn is straight, a compressive clamp leaves IPOPT at a
  point where the end position does not depend, to first order, on the shape (the Jacobian
  loses rank). The solve then starts from each of a few smooth perturbations of the natural
  shape (θ ∝ cos, sin of πS/ℓ and 2πS/ℓ along each course of length ℓ) and keeps the successful
  solution of lowest energy, which is the lowest buckling mode.
- Multilevel starts (the default start, ``start_point``): the same pull solved on coarser
  fabrics first for the full model (``multilevel_start``), the corner grid first for a finer
  reduced grid (``corner_start``); these solve, so they live here with the solver.
The NLP is built once; every solve reuses the same ``casadi.nlpsol`` object.

:class:`Equilibrium` is a problem's forward equilibrium in a fixed transcription: the NLP and
its :class:`WeftSolver` built once, ``solve(params, x0) -> Solution`` by the strategy above, the
sensitivities (``sensitivity.KKT``) on first use. Its variants (yarn contact, adaptive
representatives) and the one choice between them: ``variants.equilibrium``. Only this module
and ``contact/equilibrium.py`` build IPOPT instances (the contact NLP's are :meth:`WeftSolver.sibling`
of the paper's).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, fields
from typing import Any

import casadi as ca
import numpy as np

from ...errors import ProblemError
from ...ipopt import ipopt_options, succeeded
from ...outcome import OUT_OF_TIME
from ...progress import QUIET_FOR, IterationLine
from ..model.parametrisation import Full, Parametrisation, Reduced
from ..model.spatial.friction import FrictionPath
from ..model.params import WeftParams
from ..model.problem import WeftProblem
from ..transcription.factory import transcribe
from ..transcription.protocol import WeftNLP
from .blocks import AdaptiveBlock, ContactBlock
from .sensitivity import KKT, ContactState, Stability
from .starts import (STARTS, coarse_chain, largest_move, needs_perturbation, perturbed_starts,
                     prolong, prolong_multipliers, rigid_start)

DEFAULT_START = "multilevel"    # measured: docs/measurements.md
# a cold solve of the coarsest fabric in at most this many iterations marks a pull the natural
# start handles well (measured: course pulls take 5 iterations at every size from 8 x 8 to
# 100 x 100, where the coarse solves cost more than they save; diagonal pulls 9 on 8 x 8 and
# 13-39 on larger fabrics)
EASY_ITERATIONS = 6
# IPOPT options by transcription (``WeftNLP.model``), measured (docs/measurements.md, "IPOPT
# options for the full weft model (measured)": no other option won). Full model: its first
# Newton systems from a multilevel start have the wrong inertia (33-63 negative curvature
# directions, 100 x 100 diagonal pull) until the Hessian is regularised by delta_w = 1, which
# IPOPT reaches from its default first trial 1e-4 in three factorisations (1e-4, 1e-2, 1);
# starting the trials at 1 reaches the same delta_w, hence the same iterates, in one: 14 -> 12
# factorisations of the KKT system.
MODEL_IPOPT: dict[str, dict] = {"full": {"first_hessian_perturbation": 1.0}, "reduced": {}}
# the 3-D model (docs/weft3d.md) by default in load steps: a direct solve from the natural
# state of a 6 x 6 acrylic diagonal pull took 2113 iterations to fail, 4 steps 109 to succeed;
# with the repulsion's samples condensed, 3 steps took 47, 33 and 36 iterations on the 6 x 6,
# 10 x 10 and 30 x 30 pulls of scripts/bench_weft3d.py (corners moved 3, 2 and 3 mm: --pull
# 0.5, 0.2, 0.1) against 4 steps' 55, 41 and 50, to the same minima (energies within 1e-10,
# positions 6e-9 mm); 2 steps ended in another (6 x 6)
MODEL_CONTINUATION: dict[str, int] = {"full3d": 3}
# ... and more where a held point would move further in a step than this many natural lattice
# spacings (the smaller of the two): the 30 x 30 bench pull at its default (a corner moved
# (15, 15) mm; the documented 30 x 30 figures are its 3 mm pull) in 3 steps moved the corner
# 7.1 mm in the first, which IPOPT did not survive (70 iterations towards objective 1e15 N mm,
# the violation stuck at 2.9 mm; the same at c9a5219); in 10 steps (2.1 mm) every step
# converged, 28 iterations each (the 900 s budget ran out in the ninth). 1.2 spacings (2.4 mm
# for the acrylic) keeps the 10 x 10 bench pull's 3 steps of 2.36 mm
MODEL_STEP_MOVE: dict[str, float] = {"full3d": 1.2}
# models whose load steps start from the secant predictor (``WeftSolver.continuation``,
# ``predict``). None by default: on the 3-D diagonal pulls it saved 13-22 % of the iterations
# (6 x 6: 105 -> 91, 10 x 10: 169 -> 131) but ended in a neighbouring minimum (energy 4e-7 and
# 5e-8 relative apart, loops within 1e-3 mm, crossing coordinates up to 0.16 mm), which a
# tighter tol does not close (docs/weft3d.md, "Cost"); ``scripts/bench_weft3d.py --predictor``
MODEL_PREDICTOR: set[str] = set()
WARM = {"warm_start_init_point": "yes"}     # start from given multipliers (``once(..., lam_g0=...)``)


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
    detail: str = ""          # a sentence that says more than the status (the result's message)
    # lagged friction (3-D, [yarn] friction > 0): the load path's state after this solve
    friction: FrictionPath | None = None

    def add_effort(self, other: "SolveReport") -> None:
        """Count another solve's iterations, time and IPOPT profile into this report."""
        self.iterations += other.iterations
        self.solve_s += other.solve_s
        self.stats = {k: self.stats.get(k, 0.0) + other.stats.get(k, 0.0)
                      for k in set(self.stats) | set(other.stats)}


@dataclass
class Clock:
    """The wall-clock deadline (``time.perf_counter`` seconds) that solvers sharing it stop at:
    the paper's solves and the contact solves of one forward solve share one budget
    ``[solver] max_time`` (:meth:`WeftSolver.sibling`). ``held``: the budget is running for an
    answer whose further solves (the 3-D model's rounds and finer samples, ``rounds3d``) must
    spend it, so starting the clock again leaves the deadline where it is."""

    deadline: float = np.inf
    held: bool = False


class OnClock:
    """A solver on a shared :class:`Clock`: its ``deadline`` is the clock's (moving it moves
    every solver's that shares the clock)."""

    clock: Clock

    @property
    def deadline(self) -> float:
        """When the solves stop (the shared :class:`Clock`)."""
        return self.clock.deadline

    @deadline.setter
    def deadline(self, when: float) -> None:
        self.clock.deadline = when


class WeftSolver(OnClock):
    """One IPOPT instance for one assembled NLP, reusable across parameter values and starts.

    With lagged friction (``SpatialNLP.friction``, docs/weft3d.md "Friction") it carries the
    load path's state ``path`` (``FrictionPath``): the lagged block of the NLP's parameters,
    appended to the ``WeftParams`` vector of every solve (:meth:`parameters`), set from the
    natural state when a path starts (:meth:`begin_path`) and from each accepted step's answer
    when the next step starts (:meth:`continuation`); a halved step keeps it."""

    path: FrictionPath | None = None

    def __init__(self, wnlp: WeftNLP, tol: float | None = None, max_iter: int | None = None,
                 print_level: int = 0, verbose: bool | None = False,
                 ipopt: dict | None = None, clock: Clock | None = None) -> None:
        opts = wnlp.problem.solver
        self.wnlp, self.verbose = wnlp, verbose
        t0 = time.perf_counter()
        # measured on the 100 x 100 pull: MUMPS's scaling passes cost a third of IPOPT's own
        # time and the KKT systems here are well scaled without them
        # (the model's and the caller's options may override these)
        extra = {"max_wall_time": opts.max_time, "mumps_scaling": 0,
                 "mumps_permuting_scaling": 0, **MODEL_IPOPT.get(wnlp.model, {}), **(ipopt or {})}
        base = (extra.pop("tol", tol or opts.tol), extra.pop("max_iter", max_iter or opts.max_iter),
                extra.pop("print_level", print_level))     # these three may be overridden too
        options = {**ipopt_options(*base, **extra), **wnlp.nlpsol_options}
        # verbose: every iterate; False: a progress line once a solve outlasts QUIET_FOR;
        # None: never (a study's workers, whose runner keeps its own progress line). Always
        # there: it ends a solve at the shared deadline (IterationLine.deadline)
        quiet = float("inf") if verbose is None else 0.0 if verbose else QUIET_FOR
        self.progress = IterationLine(wnlp.n_variables, wnlp.n_constraints, quiet_for=quiet,
                                      budget=opts.max_time)
        options["iteration_callback"] = self.progress
        self.solver = ca.nlpsol("weft", "ipopt", wnlp.nlp, options)
        self.setup_s = time.perf_counter() - t0
        self.clock = Clock() if clock is None else clock
        if clock is None:
            self.start_clock()
        self._g = ca.Function("g", [wnlp.nlp["x"], wnlp.nlp["p"]], [wnlp.nlp["g"]])

    # -- lagged friction: the load path's state (model/spatial/friction.py) ------------------
    def begin_path(self, x: np.ndarray | None = None) -> None:
        """Start a load path whose first step lags from x (None: the natural state)."""
        if getattr(self.wnlp, "friction", None) is not None:
            self.path = FrictionPath(self.wnlp.lagged_at(self.wnlp.x0 if x is None else x))

    def parameters(self, p: np.ndarray) -> np.ndarray:
        """The NLP's parameter vector: ``p`` (``WeftParams.vector``) and, with friction, the
        path's lagged block (a solve outside a path is one step from the natural state)."""
        if getattr(self.wnlp, "friction", None) is None:
            return p
        if self.path is None:
            self.begin_path()
        return np.concatenate([np.asarray(p, dtype=float).ravel(), self.path.lagged.block()])

    def accept_step(self, x: np.ndarray) -> None:
        """Count an accepted step that reached x into the path (its dissipation, F4)."""
        if self.path is not None:
            self.path = self.path.accepted(self.wnlp.step_dissipation(x, self.path.lagged))

    def _lag_from(self, x: np.ndarray) -> None:
        """The next step's lagged values: the accepted answer x's (the one method that moves
        them within a path)."""
        if self.path is not None:
            self.path = self.path.next_step(self.wnlp.lagged_at(x))

    def sibling(self, wnlp: WeftNLP, ipopt: dict | None = None) -> "WeftSolver":
        """An IPOPT instance for another NLP of the same problem (yarn contact's, with more
        variables and rows) that shares this one's clock and progress setting: its solves stop
        at the same deadline."""
        return WeftSolver(wnlp, verbose=self.verbose, ipopt=ipopt, clock=self.clock)

    def start_clock(self) -> None:
        """Start the wall-clock budget ``[solver] max_time`` shared by the solves that follow
        (:meth:`once` ends a solve at this deadline through the iteration callback), and by
        every solver sharing this one's clock; a held clock (:class:`Clock`) keeps its
        deadline."""
        if not self.clock.held:
            self.deadline = time.perf_counter() + self.wnlp.problem.solver.max_time
        self.progress.start()

    def once(self, p: np.ndarray, x0: np.ndarray, *, lbg: np.ndarray | None = None,
             ubg: np.ndarray | None = None, lam_g0: np.ndarray | None = None) -> SolveReport:
        """A single IPOPT solve from x0 (none once the time budget is spent). The rows' bounds
        are the NLP's own unless given (yarn contact moves its gap rows' bounds between
        solves); ``lam_g0`` starts the multipliers."""
        t0 = time.perf_counter()
        if t0 >= self.deadline:
            return SolveReport(False, OUT_OF_TIME, x0, np.zeros(self.wnlp.n_constraints),
                               np.nan, 0, 0.0)
        warm = {} if lam_g0 is None else {"lam_g0": lam_g0}
        self.progress.deadline = self.deadline        # callers may move the deadline
        lbg = np.asarray(self.wnlp.lbg if lbg is None else lbg, dtype=float).ravel()
        ubg = np.asarray(self.wnlp.ubg if ubg is None else ubg, dtype=float).ravel()
        self.progress.bounds = (lbg, ubg)
        sol = self.solver(x0=x0, p=self.parameters(p), lbg=lbg, ubg=ubg, **warm)
        stats = self.solver.stats()
        status = str(stats["return_status"])
        if status == "User_Requested_Stop" and time.perf_counter() >= self.deadline:
            status = OUT_OF_TIME                    # stopped at the deadline (IterationLine)
        return SolveReport(succeeded(status), status, np.asarray(sol["x"]).ravel(),
                           np.asarray(sol["lam_g"]).ravel(), float(sol["f"]),
                           int(stats["iter_count"]), time.perf_counter() - t0,
                           stats={k: float(v) for k, v in stats.items() if k.startswith("t_wall")})

    def violation(self, x: np.ndarray, p: np.ndarray) -> float:
        """Largest constraint violation at x: how far g(x, p) lies outside [lbg, ubg]."""
        return self.wnlp.violation(np.asarray(self._g(x, self.parameters(p))).ravel())

    def continuation(self, p: np.ndarray, x0: np.ndarray, steps: int,
                     max_halvings: int = 6, p_from: np.ndarray | None = None,
                     predict: bool = False) -> SolveReport:
        """Step the parameters from their natural values (or ``p_from``, x0's) to ``p``,
        warm-starting each solve: from the last step's solution, or with ``predict`` from its
        secant extrapolation (:func:`secant`) once two states of the path are known. With
        friction the steps are a load path (class docstring): the first lags from the natural
        state (from x0 with ``p_from``: a solved state), each next one from the last accepted
        answer; only the ``WeftParams`` part of the parameters is interpolated."""
        p_nat = WeftParams.natural(self.wnlp.problem).vector() if p_from is None else p_from
        x, tau, dtau = x0, 0.0, 1.0 / steps
        total = SolveReport(False, "", x0, np.zeros(self.wnlp.n_constraints), np.nan, 0, 0.0)
        halvings, before = 0, None                    # before: (τ, x) of the step before x
        self.begin_path(None if p_from is None else x0)
        lag_from = None                               # an accepted answer the next step lags from
        while tau < 1.0 - 1e-12:
            if time.perf_counter() >= self.deadline:
                total.status = OUT_OF_TIME
                return total
            nxt = min(1.0, tau + dtau)
            self.progress.at(tau)                     # the progress line's share and estimate
            start = x if before is None or not predict else secant(before, (tau, x), nxt)
            if lag_from is not None:
                self._lag_from(lag_from)
                lag_from = None
            rep = self.once(p_nat + nxt * (p - p_nat), start)
            total.add_effort(rep)
            if rep.success:
                before, x, tau = (tau, x), rep.x, nxt
                self.accept_step(rep.x)
                lag_from = rep.x
                total.friction = self.path
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


def secant(before: tuple[float, np.ndarray], last: tuple[float, np.ndarray],
           tau: float) -> np.ndarray:
    """The state at load factor ``tau`` extrapolated along the chord of the last two states
    (τ₀, x₀), (τ₁, x₁) of a loading path: x₁ + (x₁ − x₀)(τ − τ₁)/(τ₁ − τ₀)."""
    (t0, x0), (t1, x1) = before, last
    return x1 + (x1 - x0) * ((tau - t1) / (t1 - t0))


@dataclass
class Solution(SolveReport):
    """A forward solve of one problem (:meth:`Equilibrium.solve`): IPOPT's report on the NLP
    ``nlp`` (x, multipliers, status, effort, attempts, loading path), the parameters solved
    at, the largest violation of the rows' bounds at x, the time the equilibrium took to
    build, and what its variant adds: ``contact`` (the contact solve behind x, None without
    one) and the result JSON's typed blocks (``contact_block``, ``adaptive``: ``blocks``)."""

    nlp: WeftNLP | None = None
    params: WeftParams | None = None
    violation: float = 0.0
    build_s: float = 0.0
    contact: "ContactState | None" = None
    contact_block: ContactBlock | None = None
    adaptive: AdaptiveBlock | None = None

    @classmethod
    def of(cls, report: SolveReport, **more: Any) -> "Solution":
        """A report as a solution with the fields ``more`` adds."""
        return cls(**{f.name: getattr(report, f.name) for f in fields(SolveReport)}, **more)


class Equilibrium:
    """A weft problem's forward equilibrium in a fixed transcription (``transcribe``): the NLP
    and its IPOPT instance built once, re-solved at many parameter values (studies, sweeps,
    continuation, control, fit, calibrate); its sensitivities and stability check
    (``sensitivity.KKT``) are built on first use. ``variants.equilibrium`` chooses the variant
    (this, yarn contact, adaptive representatives)."""

    def __init__(self, problem: WeftProblem, parametrisation: Parametrisation | None = None,
                 *, verbose: bool | None = False) -> None:
        if problem.yarn is not None and not (self.with_contact or problem.yarn.spatial):
            # its solves and sensitivities would ignore the yarn's thickness (the 3-D model's
            # crossings are in its own NLP)
            raise ValueError(f"{problem.source}: this Equilibrium ignores [yarn] radius; build "
                             "it with variants.equilibrium(problem)")
        t0 = time.perf_counter()
        self.problem = problem
        self.nlp = transcribe(problem, parametrisation)
        self.solver = WeftSolver(self.nlp, verbose=verbose)
        self._build_s = time.perf_counter() - t0
        self._kkt: KKT | None = None
        self.forward_solves = 0

    with_contact = False        # whether solves and the KKT system hold yarn contact

    def rebuild(self, nlp: WeftNLP) -> None:
        """Solve ``nlp`` from now on (the 3-D model's rounds of other contacts, rounds3d.py):
        its IPOPT instance built here on the same wall-clock budget ([solver] max_time), the
        KKT system afresh; the load path's friction state carried over (a round that solves
        the last step again keeps that step's lagged values)."""
        t0 = time.perf_counter()
        self.nlp, self._kkt, path = nlp, None, self.solver.path
        self.solver = WeftSolver(nlp, verbose=self.solver.verbose, clock=self.solver.clock)
        self.solver.path = path
        self._build_s += time.perf_counter() - t0

    @property
    def wnlp(self) -> WeftNLP:
        """The NLP (the inverse problems' name for :attr:`nlp`)."""
        return self.nlp

    @property
    def params(self) -> WeftParams:
        """The problem's own parameter values; change them with ``with_(...)``."""
        return self.nlp.params

    @property
    def build_s(self) -> float:
        """Seconds spent building: the NLP, its IPOPT instance, the KKT Functions once used."""
        return self._build_s

    def as_params(self, params: WeftParams | np.ndarray | None) -> WeftParams:
        """Parameters given as values, a vector of the NLP's layout ``p``, or None (the
        problem's own)."""
        if params is None:
            return self.params
        if isinstance(params, WeftParams):
            return params
        return WeftParams.from_vector(self.problem, np.asarray(params, dtype=float))

    def solve(self, params: WeftParams | np.ndarray | None = None, x0: np.ndarray | None = None,
              *, continuation: int | None = None, start: str = DEFAULT_START,
              x0_params: WeftParams | np.ndarray | None = None,
              origin: tuple[np.ndarray, np.ndarray] | None = None) -> Solution:
        """Solve at ``params`` from ``x0`` (else from ``start``): direct, then continuation
        from the natural parameters (:func:`solve_nlp`). ``x0_params`` (x0's parameters, if
        known) and ``origin`` (a solved state and its parameters: one load step from there)
        are for yarn contact's load steps only."""
        params = self.as_params(params)
        self.forward_solves += 1
        rep = solve_nlp(self.nlp, self.solver, params=params, x0=x0,
                        continuation=continuation, start=start)
        return self.solution(rep, params)

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """The decision vector of another solved model's loops (``WeftNLP.lift``)."""
        return self.nlp.lift(coeffs, starts)

    def done(self) -> None:
        """End the progress line of the solves (a newline where one was written)."""
        self.solver.progress.done()

    def solution(self, report: SolveReport, params: WeftParams | np.ndarray) -> Solution:
        """A report of this NLP at ``params`` as a :class:`Solution` (its violation, and what
        the variant keeps for its x)."""
        params = self.as_params(params)
        sol = Solution.of(report, nlp=self.nlp, params=params, build_s=self.build_s,
                          violation=self.solver.violation(report.x, params.vector()))
        if sol.friction is None:            # a step solved again (rounds3d): its path's state
            sol.friction = self.solver.path
        return sol

    # -- sensitivities: an optional capability, built on first use ----------------------
    @property
    def kkt_system(self) -> KKT:
        """The KKT system at this equilibrium's solutions (``sensitivity.KKT``)."""
        if self._kkt is None:
            t0 = time.perf_counter()
            self._kkt = KKT(self.nlp, self.solver.solver, self.contact_state)
            self._build_s += time.perf_counter() - t0
        return self._kkt

    def contact_state(self, x: np.ndarray) -> ContactState | None:
        """The contact solve behind base solution x (none without contact)."""
        return None

    def sensitivity(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray, dp: np.ndarray,
                    sliding: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """dx/dθ and dλ/dθ for parameter directions dp (``KKT.sensitivity``)."""
        return self.kkt_system.sensitivity(x, lam, p, dp, sliding)

    def system(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray) -> tuple[ca.DM, ca.DM, int]:
        """The KKT matrix, ∂F/∂p and the size of its Hessian block (``KKT.system``)."""
        return self.kkt_system.system(x, lam, p)

    def linear_system(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray,
                      contact: bool = True):
        """The sensitivities' linear system as SciPy matrices (``KKT.linear_system``)."""
        return self.kkt_system.linear_system(x, lam, p, contact)

    def stability(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray,
                  method: str = "sparse") -> Stability:
        """Smallest eigenvalue of the reduced Hessian (``KKT.stability``)."""
        return self.kkt_system.stability(x, lam, p, method)


# IPOPT iterations of one solve inside a 3-D inverse step (``SpatialSteps``): the
# accepted steps of the 2 x 2 and 6 x 6 controls took 10-60
TRIAL_ITER = 150
# halvings of a failed 3-D step before the control shrinks its trust region instead: with 6,
# failed trials of a 6 x 6 acrylic control took 4-6 minutes each (over 1 000 iterations)
TRIAL_HALVINGS = 2


class SpatialSteps(Equilibrium):
    """The 3-D model's equilibrium (its full transcription, ``transcription.spatial``; chosen
    by ``variants.equilibrium``) whose solves with an ``origin`` (a solved state and its
    parameters: the control iteration's trial steps) are one load step from there: IPOPT
    from the predicted state x0 at the new parameters, and where that fails, the parameters
    stepped from the origin's (halved as needed, ``WeftSolver.continuation``). Without an
    origin, a solve is the 3-D model's own (load steps from the natural state). Measured on a
    2 x 2 control: with the default solve from x0 (four load steps from the natural
    parameters, each warm-started from the new actuation's prediction) the first trial steps
    failed and the trust radius fell to 3e-5 mm before it grew again (42 outer iterations).
    A step's IPOPT solves stop at ``TRIAL_ITER`` iterations (a failed step shrinks the control's
    trust region): on a 6 x 6 acrylic control one trial of 3 mm pressed a crossing
    towards its core (objective 2.5e9) for over 1 100 iterations and 13 minutes."""

    _trial: WeftSolver | None = None        # the IPOPT instance of the steps, built on first use

    def solve(self, params: WeftParams | np.ndarray | None = None, x0: np.ndarray | None = None,
              *, continuation: int | None = None, start: str = DEFAULT_START,
              x0_params: WeftParams | np.ndarray | None = None,
              origin: tuple[np.ndarray, np.ndarray] | None = None) -> Solution:
        if origin is None or x0 is None:
            return super().solve(params, x0, continuation=continuation, start=start)
        refuse_friction(self.problem, "the inverse problems' trial steps")
        params = self.as_params(params)
        p = params.vector()
        self.forward_solves += 1
        if self._trial is None:
            self._trial = WeftSolver(self.nlp, max_iter=TRIAL_ITER, verbose=self.solver.verbose,
                                     clock=self.solver.clock)
        self.solver.start_clock()
        rep = self._trial.once(p, x0)
        rep.attempts = [f"direct from the prediction: {rep.status} ({rep.iterations} it)"]
        if not rep.success:
            step = self._trial.continuation(p, origin[0], 1, max_halvings=TRIAL_HALVINGS,
                                            p_from=np.asarray(origin[1]))
            step.add_effort(rep)
            step.attempts = rep.attempts + [f"load step from the last state: {step.status}"]
            rep = step
        return self.solution(rep, params)


def refuse_friction(problem: WeftProblem, what: str) -> None:
    """Refuse lagged friction (``[yarn] friction`` > 0) in ``what``, whose load path is not a
    forward continuation (exit 2)."""
    yarn = problem.yarn
    if yarn is not None and yarn.spatial and yarn.friction > 0:
        raise ProblemError(problem.source, "yarn", "friction",
                           f"{what}: lagged friction needs a forward load path (its answer "
                           "depends on the steps), which these solves do not follow; remove "
                           "friction or set it to 0")


def model_steps(wnlp: WeftNLP, p: np.ndarray) -> int | None:
    """The model's own load steps to parameters p (None: it solves directly): the 3-D model's
    MODEL_CONTINUATION, or more where a held point would move further in a step than
    MODEL_STEP_MOVE natural lattice spacings."""
    steps = MODEL_CONTINUATION.get(wnlp.model)
    if steps is None or wnlp.model not in MODEL_STEP_MOVE:
        return steps
    shape = wnlp.shape                       # the natural 3-D shape's lattice
    spacing = MODEL_STEP_MOVE[wnlp.model] * min(shape.wale_spacing, shape.course_spacing)
    move = largest_move(wnlp.problem, WeftParams.natural(wnlp.problem).vector(), p)
    return max(steps, int(np.ceil(move / spacing - 1e-9)))


def solve_nlp(wnlp: WeftNLP, solver: WeftSolver | None = None,
              params: WeftParams | None = None, x0: np.ndarray | None = None,
              continuation: int | None = None, start: str = DEFAULT_START) -> SolveReport:
    """Solve robustly at ``params`` (the problem's own by default): direct, then continuation;
    from perturbed starts where degenerate. Without x0 the solve starts from ``start``
    (:func:`start_point`: ``multilevel``, ``rigid`` or ``natural``); a multilevel start's
    coarse solves count into ``solve_s`` and ``attempts``."""
    solver = solver or WeftSolver(wnlp)
    solver.start_clock()
    p = (params or wnlp.params).vector()
    continuation = continuation or wnlp.problem.solver.continuation or model_steps(wnlp, p)
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
        solver.begin_path()                  # friction: one load step from the natural state
        rep = solver.once(p, x0)
        if rep.success:
            solver.accept_step(rep.x)
            rep.friction = solver.path
        attempts.append(f"direct: {rep.status} ({rep.iterations} it)")
        tried.append(rep)
    for steps in ([] if tried and tried[-1].success else [continuation] if continuation else [4, 16]):
        rep = solver.continuation(p, x0, steps, predict=solver.wnlp.model in MODEL_PREDICTOR)
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


def start_point(wnlp: WeftNLP, p: np.ndarray, start: str,
                log: list[str] | None = None) -> np.ndarray:
    """The decision vector a solve starts from: ``natural``, ``rigid`` (``starts.rigid_start``)
    or ``multilevel``: the coarser problem of the transcription's kind first
    (:data:`MULTILEVEL`: coarser fabrics for the full model, the corner grid for a finer reduced
    grid), the natural state where there is none."""
    if start not in STARTS:
        raise ValueError(f"start must be one of {', '.join(STARTS)}; got {start!r}")
    if start == "natural":
        return wnlp.x0
    if start == "rigid":
        return rigid_start(wnlp, p)
    coarser = MULTILEVEL.get(wnlp.model)       # none for the 3-D model (yet)
    x = None if coarser is None else coarser(wnlp, p, log)
    return wnlp.x0 if x is None else x


def corner_start(cnlp: WeftNLP, p: np.ndarray, log: list[str] | None = None
                 ) -> np.ndarray | None:
    """For the condensed reduced model over a grid finer than the corners: solve the corner form
    (``transcribe(problem, Reduced())``, the coarsest grid, contained in every grid) at the same
    parameters from its natural state and lift its loops into this grid. None for the corner
    form itself or a failed corner solve. Measured
    (diagonal pulls, corner then grid against the grid from its natural state): 16 × 16 over
    8 × 8, 9 + 13 against 45 iterations; 30 × 30 over 15 × 15, 8 + 15 against 103, where the
    natural start ends in another minimum (energy 114.47 against 55.29); 24 × 24 over 12 × 12,
    87.98 against 36.33; 100 × 100 over 6 × 6, 11 + 6 against 11, the same minimum."""
    pr = cnlp.problem
    corner = transcribe(pr, Reduced())
    if corner.parametrisation == cnlp.parametrisation:
        return None
    rep = solve_nlp(corner, WeftSolver(corner), params=WeftParams.from_vector(pr, p),
                start="natural")
    if log is not None:
        log.append(f"corner start: {rep.status} ({rep.iterations} it, {rep.solve_s:.2f} s)")
    if not rep.success:
        return None
    return cnlp.lift(corner.coefficients(rep.x), corner.starts(rep.x))


def multilevel_start(wnlp: WeftNLP, p: np.ndarray, log: list[str] | None = None
                     ) -> np.ndarray | None:
    """Solve the pull on the coarsest fabric of :func:`coarse_chain` from its natural state; if
    that took more than EASY_ITERATIONS (the pull is hard for a cold start), prolong the
    solution level by level up to this fabric. Each coarser level after the first starts from
    the prolonged loops *and multipliers* (``starts.prolong_multipliers``; a failed warm solve
    is repeated as usual, IPOPT estimating them); this fabric's solve starts from the loops
    only: with the prolonged multipliers the 100 x 100 diagonal pull's first Newton step was
    4 x longer and ended in another minimum (557.13 against 547.20), with IPOPT's least-squares
    estimate and its regularised first steps in the usual one (docs/measurements.md).
    None (start natural) where no coarser problem is defined, the probe was easy or a coarse
    solve failed. Every coarse solve is appended to ``log``, coarsest first."""
    chain = coarse_chain(wnlp.problem, WeftParams.from_vector(wnlp.problem, p))
    x, lam, prev = None, None, None
    for level, cp in enumerate(reversed(chain)):
        nlp = transcribe(cp, Full())
        if prev is None:
            rep = solve_nlp(nlp, WeftSolver(nlp), start="natural")
        else:
            x0 = prolong(prev, x, nlp)
            rep = WeftSolver(nlp, ipopt=WARM).once(nlp.p0, x0, lam_g0=prolong_multipliers(prev, lam, nlp))
            if not rep.success:
                rep = _combined(solve_nlp(nlp, WeftSolver(nlp), x0=x0), [rep], [])
        if log is not None:
            log.append(f"multilevel {cp.courses}x{cp.wales}: {rep.status} ({rep.iterations} it, "
                       f"{rep.solve_s:.2f} s)")
        if not rep.success or (level == 0 and rep.iterations <= EASY_ITERATIONS):
            return None
        x, lam, prev = rep.x, rep.lam_g, nlp
    return None if prev is None else prolong(prev, x, wnlp)


# the coarser problem a multilevel start solves first, by the transcription's ``model``
MULTILEVEL = {"full": multilevel_start, "reduced": corner_start}
