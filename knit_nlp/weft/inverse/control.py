"""Deformation control (docs/inverse.md, "Deformation control"): move the actuated clamps so that
material points reach goals and openings stay open, with the fabric in stable equilibrium.

Formulation (chosen by measurement, docs/inverse.md): an outer trust-region Gauss–Newton (SQP)
iteration over the few actuated unknowns u. At each outer step the equilibrium x(u) is the
forward NLP's solution (the same built IPOPT instance, warm-started from the implicit-function
prediction x + (dx/du)·d), and dx/du comes from one factorization of the forward KKT matrix
(see ``equilibrium``). The residual is r(u) = (√w·(P(x(u)) − goal), √travel_weight·(u − u₀)) so
the objective Σw|misfit|² + travel_weight·Σ|travel|² is |r|²; each step solves the convex QP

    min_d |r + J d|²  s.t.  bounds on u + d,  |d|∞ ≤ Δ,  o + Jₒ d ≥ at_least  (openings, linearised)

(CasADi's ``qrqp``) and is accepted on the decrease of |r|² + ρ·Σ opening shortfall.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from ...jsonio import write_json
from ...outcome import Energy, Outcome, describe
from ...progress import QUIET_FOR, Clock
from ..model.problem import WeftProblem
from ..output.plausibility import summary_line as implausible
from ..output.results import WeftResult
from ..solving.solve import SolveReport
from ..solving.sensitivity import Stability
from .forward import equilibrium_for
from ..model.centrelines import natural_centrelines
from .plot import plot_control
from .points import point_function, point_jacobian
from .spec import Actuated, ControlProblem

CONVERGED = "Converged"


CONTACT_FORWARD = 0.01    # forward check with yarn contact: 1/100 of the radius (forward_tolerance)

@dataclass
class ControlOptions:
    """Outer-iteration limits and tolerances."""

    max_iter: int = 60
    step_tol: float = 1e-10          # stop when the accepted step is this small (relative to 1 + |u|)
    objective_tol: float = 1e-14     # stop when the predicted decrease is below this (absolute)
    opening_tol: float = 1e-7        # allowed shortfall of an opening at the answer
    forward_tol: float = 1e-5        # largest centreline distance for the forward check to pass
    initial_radius: float = 10.0     # trust region in model units (and radians for rotations);
    #                                  place_stitch: 5 outer steps instead of 7 with 2.0
    # the 3-D model's first trust region, in yarn radii: its crossings have no stiffness at
    # touch, so a first trial of 10 mm on a 6 x 6 acrylic fabric pressed a crossing towards
    # its core (objective 1e8-5e9) for minutes before the step was cut
    initial_radius_3d: float = 1.0
    # times a converged iteration whose equilibrium is not the forward solve's from the natural
    # state goes on from the forward solve's (a 2 x 2 acrylic control in 3-D ended 0.008 mm
    # from it, on a second minimum 1e-9 N·mm higher in energy)
    branch_restarts: int = 3


@dataclass
class State:
    """An equilibrium at actuated unknowns u."""

    u: np.ndarray
    x: np.ndarray
    lam: np.ndarray
    r: np.ndarray
    gap: np.ndarray                  # opening distance minus at_least (>= 0 feasible)
    report: SolveReport

    def merit(self, rho: float) -> float:
        return float(self.r @ self.r + rho * np.sum(np.maximum(0.0, -self.gap)))


@dataclass(repr=False)
class ControlResult(Outcome):
    """What the control command found, as a result (the contract of :mod:`knit_nlp.outcome`:
    ``status`` is the optimiser's status or the reason it failed, ``nit`` its outer
    iterations, ``energy`` the equilibrium's at the answer) with everything its JSON
    (``to_json``, the contract's ``<problem>.control.json``) and picture (``save``) need."""

    ctl: "Controller"
    success: bool
    status: str
    state: State
    start: State
    p: np.ndarray
    iterations: int
    stability: Stability
    forward_success: bool
    forward_distance: float
    forward_x: np.ndarray
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def problem(self) -> WeftProblem:
        return self.ctl.cp.problem

    @cached_property
    def equilibrium(self) -> WeftResult:
        """The forward model's result at the answer (its clamps, loops, energy and own check,
        ``WeftResult.checked``), made once: the JSON, the summary and the picture read it."""
        return WeftResult.of(self.ctl.eq.solution(self.state.report, self.p))

    @property
    def energy(self) -> Energy:
        return self.equilibrium.energy

    @property
    def message(self) -> str:
        """The status spelled out, and which actuated unknowns ended on a bound."""
        bound = at_bounds(self)
        if not bound:
            return describe(self.status)
        return (f"{describe(self.status)}; stopped on a bound: {', '.join(bound)} "
                "(widen its bounds to let it move further)")

    def to_json(self) -> dict[str, Any]:
        """The contract's ``<problem>.control.json`` (plus ``message`` and ``energy``)."""
        return control_json(self)

    def save(self, out_dir: Path | str) -> list[Path]:
        """``DIR/<problem>.control.json`` and the picture ``.control.png`` (the equilibrium at
        the answer with its grips and forces, the start shape, goals, the actuated clamps'
        travel)."""
        out, name, result = Path(out_dir), self.problem.name, self.to_json()
        js = write_json(out / f"{name}.control.json", result)
        wnlp = self.ctl.eq.wnlp
        goals = np.array([g["goal"] for g in result["goals"]]).reshape(-1, 2)
        reached = np.array([g["achieved"] for g in result["goals"]]).reshape(-1, 2)
        travel = [(self.start.u[k:k + 2], self.state.u[k:k + 2]) for k in _clamp_offsets(self.ctl.cp)]
        openings = [(pair, "opening " + "–".join(f"{q['point']} {tuple(q['loop'])}"
                                                  for q in o["points"])
                     + f" at least {o['at_least']:.4g}: achieved {o['achieved']:.4g}")
                    for pair, o in zip(self.ctl.opening_points(self.state.x), result["openings"])]
        png = plot_control(out / f"{name}.control.png", self.equilibrium,
                           natural_centrelines(wnlp.problem), wnlp.centrelines(self.start.x),
                           wnlp.centrelines(self.state.x), goals, reached, travel, openings,
                           f"{name}: {result['status']}, objective {result['objective']:.3g}, "
                           f"{'stable' if result['stable'] else 'NOT STABLE'}"
                           + ("" if self.problem.yarn is None else
                              f"; {'3-D model' if self.problem.yarn.spatial else 'yarn contact'}"
                              f", r = {self.problem.yarn.radius:g} "
                              f"{self.problem.units.length}"), result["check"])
        return [js, png]


# per kind of actuated clamp: its file table and the names of its unknowns
KINDS = {"clamp": ("clamp", ("target x", "target y")),
         "rigid": ("rigid_clamp", ("translation x", "translation y", "rotation"))}


def _label(a: Actuated) -> str:
    """How a file names an actuated clamp's table: ``clamp[2]``, ``rigid_clamp[1]``."""
    return f"{KINDS[a.kind][0]}[{a.table}]"


def at_bounds(ans: ControlResult, rtol: float = 1e-8) -> list[str]:
    """Each actuated unknown that ends on one of its bounds, as ``clamp[2] target x = 16
    (upper bound)``."""
    out, k = [], 0
    for a in ans.ctl.cp.actuated:
        for d, name in enumerate(KINDS[a.kind][1]):
            u = float(ans.state.u[k + d])
            for side, b in (("lower", a.lower[d]), ("upper", a.upper[d])):
                if np.isfinite(b) and abs(u - b) <= rtol * (1.0 + abs(b)):
                    out.append(f"{_label(a)} {name} = {u:.6g} ({side} bound)")
        k += a.size
    return out


def control_summary(ans: ControlResult, paths: list[Path]) -> str:
    """What ``knit-nlp control`` prints: readable lines (no Python dicts), the bound an
    actuated unknown stopped on included."""
    r = ans.to_json()
    lines = [f"{ans.problem.name}: {r['status']} in {r['iterations']} outer iterations, "
             f"{r['forward_solves']} forward solves, {r['timings']['total_s']:.2f} s"]
    for a, v in zip(ans.ctl.cp.actuated, r["actuated"]):
        where = (f"target {_xy(v['target'])}" if a.kind == "clamp" else
                 f"translation {_xy(v['translation'])}, rotation {v['rotation']:.6g} rad")
        lines.append(f"  actuated {_label(a)}: {where}")
    lines += [f"  on a bound: {b}: widen its bounds to let it move further" for b in at_bounds(ans)]
    for g in r["goals"]:
        lines.append(f"  goal {_xy(g['loop'])} {g['point']}: goal {_xy(g['goal'])}, "
                     f"achieved {_xy(g['achieved'])}, misfit {g['misfit']:.3g}")
    for o in r["openings"]:
        lines.append(f"  opening at least {o['at_least']:.4g}: achieved {o['achieved']:.4g}")
    lines.append(f"  stable: {r['stable']} (min reduced Hessian eigenvalue "
                 f"{r['min_reduced_hessian_eigenvalue']:.3g}); forward check: "
                 f"{r['forward_check']['success']} (max distance "
                 f"{r['forward_check']['max_distance']:.2e})")
    lines.append("  check: " + r["check"]["verdict"])   # the equilibrium's own check
    lines += implausible(ans.equilibrium)       # springs beyond L, folds, loops inside out
    lines.append(f"  wrote {', '.join(map(str, paths))}")
    return "\n".join(lines)


def _xy(v: list[float]) -> str:
    """``(16, 14.3232)``: numbers to 6 significant digits."""
    return "(" + ", ".join(f"{c:.6g}" for c in v) + ")"


def _clamp_offsets(cp: ControlProblem) -> list[int]:
    """Offsets in u of each actuated point clamp's target (rigid clamps are not drawn)."""
    out, k = [], 0
    for a in cp.actuated:
        if a.kind == "clamp":
            out.append(k)
        k += a.size
    return out


class Controller:
    """The outer problem over the actuated unknowns of one control problem (one forward build)."""

    def __init__(self, cp: ControlProblem, options: ControlOptions | None = None) -> None:
        self.cp, self.opts = cp, options or ControlOptions()
        # with [yarn] radius the forward model and its KKT system hold the active contacts
        self.eq = equilibrium_for(cp.problem)
        pl = self.eq.wnlp.p
        idx = []
        for a in cp.actuated:
            block, rows = ("targets", 2) if a.kind == "clamp" else ("rigid", 3)
            idx += [pl.slice(block).start + rows * a.index + d for d in range(rows)]
        self.idx = np.array(idx, dtype=int)
        self.E = np.zeros((pl.size, len(idx)))
        self.E[self.idx, np.arange(len(idx))] = 1.0
        self.u0 = self.eq.wnlp.p0[self.idx].copy()
        self.lower = np.concatenate([a.lower for a in cp.actuated])
        self.upper = np.concatenate([a.upper for a in cp.actuated])
        self._goals = point_jacobian(point_function(self.eq.wnlp, [(g.loop, g.s) for g in cp.goals]))
        self._open = point_jacobian(point_function(
            self.eq.wnlp, [(lp, s) for o in cp.openings for lp, _, s in o.points]))
        w = []
        for g in cp.goals:
            w += [np.sqrt(g.weight) if f else 0.0 for f in g.fix]
        self._w = np.array(w)
        self._rows = self._w > 0
        self._qp = self._build_qp()
        self.restarts = 0                # iterations resumed from the forward solve's branch
        self._forward: tuple[np.ndarray, SolveReport] | None = None

    # -- residuals and their Jacobians ------------------------------------------------------
    def params(self, u: np.ndarray) -> np.ndarray:
        p = self.eq.wnlp.p0.copy()
        p[self.idx] = u
        return p

    def goal_positions(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(self._goals(x)[0]).reshape(2, -1, order="F")

    def opening_points(self, x: np.ndarray) -> np.ndarray:
        """Each opening's two points at x, (openings, 2, 2) (the picture draws them)."""
        if not self.cp.openings:
            return np.zeros((0, 2, 2))
        return np.asarray(self._open(x)[0]).reshape(2, -1, order="F").T.reshape(-1, 2, 2)

    def opening_distances(self, x: np.ndarray) -> np.ndarray:
        P = np.asarray(self._open(x)[0]).reshape(2, -1, order="F")
        return np.linalg.norm(P[:, 0::2] - P[:, 1::2], axis=0)

    def _residual(self, u: np.ndarray, x: np.ndarray) -> np.ndarray:
        P = np.asarray(self._goals(x)[0]).ravel(order="F")
        tgt = np.concatenate([g.target for g in self.cp.goals]) if self.cp.goals else np.zeros(0)
        goal = (self._w * (P - tgt))[self._rows]
        return np.concatenate([goal, np.sqrt(self.cp.travel_weight) * (u - self.u0)])

    def _state(self, u: np.ndarray, rep: SolveReport) -> State:
        at = np.array([o.at_least for o in self.cp.openings])
        return State(u, rep.x, rep.lam_g, self._residual(u, rep.x),
                     self.opening_distances(rep.x) - at, rep)

    def jacobians(self, s: State) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """dx/du, the residual Jacobian dr/du and the opening-gap Jacobian d(gap)/du."""
        dx, _ = self.eq.sensitivity(s.x, s.lam, self.params(s.u), self.E)
        _, JP = self._goals(s.x)
        Jr = (self._w[:, None] * np.asarray(JP @ ca.DM(dx)))[self._rows]
        Jr = np.vstack([Jr, np.sqrt(self.cp.travel_weight) * np.eye(len(s.u))])
        Po, JO = self._open(s.x)
        Po = np.asarray(Po).reshape(2, -1, order="F")
        dPo = np.asarray(JO @ ca.DM(dx)).reshape(2, -1, len(s.u), order="F")
        diff = Po[:, 0::2] - Po[:, 1::2]
        unit = diff / np.maximum(np.linalg.norm(diff, axis=0), 1e-300)
        Jg = np.einsum("dk,dku->ku", unit, dPo[:, 0::2] - dPo[:, 1::2])
        return dx, Jr, Jg

    # -- the outer iteration ----------------------------------------------------------------
    def _build_qp(self) -> ca.Function:
        """The step QP over (d, t): t ≥ 0 are elastic slacks of the linearised openings, so the
        QP is always feasible (ℓ1 elastic mode) and t = 0 whenever the openings can be met."""
        nu, no = len(self.idx), len(self.cp.openings)
        return ca.conic("step", "qrqp", {"h": ca.Sparsity.dense(nu + no, nu + no),
                                         "a": ca.Sparsity.dense(no, nu + no)},
                        {"print_iter": False, "print_header": False, "print_info": False,
                         "error_on_fail": False})

    def _step(self, s: State, Jr: np.ndarray, Jg: np.ndarray, radius: float, rho: float
              ) -> tuple[np.ndarray, np.ndarray]:
        """The QP step d and the multipliers of the linearised openings."""
        nu, no = len(s.u), len(s.gap)
        H = np.zeros((nu + no, nu + no))
        H[:nu, :nu] = 2.0 * Jr.T @ Jr + 1e-12 * np.eye(nu) * max(1.0, np.trace(Jr.T @ Jr))
        g = np.r_[2.0 * Jr.T @ s.r, np.full(no, rho)]
        lbx = np.r_[np.maximum(self.lower - s.u, -radius), np.zeros(no)]
        ubx = np.r_[np.minimum(self.upper - s.u, radius), np.full(no, np.inf)]
        sol = self._qp(h=H, g=g, a=np.hstack([Jg, np.eye(no)]), lba=-s.gap, uba=np.inf,
                       lbx=lbx, ubx=ubx)
        if not self._qp.stats()["success"]:
            raise RuntimeError(f"step QP failed: {self._qp.stats()['return_status']}")
        return np.asarray(sol["x"]).ravel()[:nu], np.asarray(sol["lam_a"]).ravel()

    def equilibrium(self, u: np.ndarray, x0: np.ndarray | None = None,
                    origin: State | None = None):
        """The forward solve at unknowns u (the built IPOPT instance; warm start x0; with
        contact, a load step from the state ``origin``)."""
        return self.eq.solve(self.params(u), x0=x0, origin=None if origin is None else
                             (origin.x, self.params(origin.u)))

    def _progress(self, it: int, s: State, radius: float, clock: Clock) -> None:
        """One stderr line per outer iteration once the control has run QUIET_FOR seconds (a
        control that cannot reach its goal or opening is not silent while it tries)."""
        took = clock.due()
        if took is None:
            return
        short = float(np.max(-s.gap, initial=0.0))
        sys.stderr.write(f"  control: outer iteration {it}, goal misfit {float(np.sqrt(s.r @ s.r)):.3g}"
                         + (f", opening short by {short:.3g}" if short > 0 else "")
                         + f", trust radius {radius:.3g}, {took:.0f} s\n")
        sys.stderr.flush()

    def run(self, u_start: np.ndarray | None = None) -> ControlResult:
        t0 = time.perf_counter()
        clock = Clock(QUIET_FOR, every=0.0)      # a line per outer iteration after QUIET_FOR
        u = self.u0.copy() if u_start is None else np.asarray(u_start, dtype=float)
        rep = self.equilibrium(u)
        start = self._state(u, rep)
        if not rep.success:
            return self._finish(start, start, False, f"start equilibrium not found: {rep.status}", 0, t0)
        rho = 10.0 * (1.0 + float(start.r @ start.r))
        s, status, it, radius = self._iterate(start, self.first_radius(), rho, 0, clock)
        for _ in range(self.opts.branch_restarts):
            if status != CONVERGED:
                break
            fwd = self.forward(s.u)
            if not fwd.success or self.distance(s.x, fwd.x) <= self.forward_tolerance():
                break
            # the path the iteration took ended on another equilibrium than the forward solve
            # from the natural state reaches at these targets: go on from that one
            self.restarts += 1
            s, status, it, radius = self._iterate(self._state(s.u, fwd), radius, rho, it, clock)
        ok = status == CONVERGED and bool(np.all(s.gap >= -self.opts.opening_tol))
        if status == CONVERGED and not ok:
            status = "Converged_Opening_Infeasible"
        return self._finish(start, s, ok, status, it, t0)

    def _iterate(self, s: State, radius: float, rho: float, it: int, clock: Clock
                 ) -> tuple[State, str, int, float]:
        """Trust-region Gauss–Newton/SQP steps from state s (module docstring) until converged,
        failed or out of iterations; returns the last state, status, iteration count and trust
        radius."""
        status, first = "Maximum_Iterations", it + 1
        for it in range(first, self.opts.max_iter + 1):
            dx, Jr, Jg = self.jacobians(s)
            try:
                d, lam_o = self._step(s, Jr, Jg, radius, rho)
            except RuntimeError as err:
                return s, str(err), it, radius
            rho = max(rho, 2.0 * float(np.abs(lam_o).max(initial=0.0)))
            model = s.r + Jr @ d
            pred = s.merit(rho) - float(model @ model + rho * np.sum(np.maximum(0.0, -(s.gap + Jg @ d))))
            if pred <= self.opts.objective_tol or np.abs(d).max() <= self.opts.step_tol * (1 + np.abs(s.u).max()):
                return s, CONVERGED, it, radius
            trial = self.equilibrium(s.u + d, x0=s.x + dx @ d, origin=s)
            if not trial.success:
                radius = 0.25 * np.abs(d).max()
                continue
            new = self._state(s.u + d, trial)
            ratio = (s.merit(rho) - new.merit(rho)) / pred
            if ratio > 1e-4:
                s = new
                if ratio > 0.75:
                    radius = max(radius, 2.0 * np.abs(d).max())
            else:
                radius = 0.25 * np.abs(d).max()
            self._progress(it, s, radius, clock)
        return s, status, max(it, first - 1), radius

    def forward(self, u: np.ndarray) -> SolveReport:
        """The forward solve from the natural state at unknowns u (as ``knit-nlp solve``),
        once per u (the branch test and the forward check share it)."""
        if self._forward is None or not np.array_equal(self._forward[0], u):
            self._forward = (u.copy(), self.eq.solve(self.params(u)))
        return self._forward[1]

    def distance(self, x: np.ndarray, y: np.ndarray) -> float:
        """The largest distance between two states' centrelines (21 samples per loop; in
        space for the 3-D model, whose states may differ out of the plane only)."""
        lines = getattr(self.eq.wnlp, "centrelines3d", self.eq.wnlp.centrelines)
        return float(np.linalg.norm(lines(x, 21) - lines(y, 21), axis=-1).max())

    def first_radius(self) -> float:
        """The first trust region: ``initial_radius``, in the 3-D model at most
        ``initial_radius_3d`` yarn radii."""
        yarn = self.cp.problem.yarn
        if yarn is not None and yarn.spatial:
            return min(self.opts.initial_radius, self.opts.initial_radius_3d * yarn.radius)
        return self.opts.initial_radius

    def forward_tolerance(self) -> float:
        """The forward check's largest centreline distance: ``forward_tol``; with yarn contact
        at least CONTACT_FORWARD × radius, since contact rounds settle their contact points
        only to a fraction of a sample (docs/contact.md), while another equilibrium branch
        differs by the yarn's thickness."""
        yarn = self.cp.problem.yarn
        return max(self.opts.forward_tol, 0.0 if yarn is None else CONTACT_FORWARD * yarn.radius)

    def _finish(self, start: State, s: State, ok: bool, status: str, it: int, t0: float) -> ControlResult:
        t1 = time.perf_counter()
        p = self.params(s.u)
        stab = self.eq.stability(s.x, s.lam, p)
        t2 = time.perf_counter()
        fwd = self.forward(s.u)
        dist = self.distance(s.x, fwd.x)
        fwd_ok = bool(fwd.success and dist <= self.forward_tolerance())
        t3 = time.perf_counter()
        if ok and not stab.stable:
            status = "Saddle: the equilibrium is not stable"
        elif ok and not fwd_ok:
            status = "Forward check failed: the forward solve does not reach the state"
        success = ok and stab.stable and fwd_ok
        timings = {"build_s": self.eq.build_s, "optimise_s": t1 - t0, "stability_s": t2 - t1,
                   "forward_check_s": t3 - t2, "total_s": self.eq.build_s + t3 - t0}
        return ControlResult(self, success, status, s, start, p, it, stab, fwd_ok,
                             dist, fwd.x, timings)


def control(cp: ControlProblem, u_start: np.ndarray | None = None,
            options: ControlOptions | None = None) -> ControlResult:
    """Solve a control problem (Python API behind ``knit-nlp control``)."""
    return Controller(cp, options).run(u_start)


def control_json(ans: ControlResult) -> dict[str, Any]:
    """The contract's ``<problem>.control.json`` (plus ``message`` and ``energy``)."""
    ctl = ans.ctl
    cp, ctl_u, eq = ctl.cp, ans.state.u, ctl.eq
    actuated, k = [], 0
    for a in cp.actuated:
        v = ctl_u[k:k + a.size]
        k += a.size
        actuated.append({"clamp": a.table, "target": v.tolist()} if a.kind == "clamp" else
                        {"rigid_clamp": a.table, "translation": v[:2].tolist(), "rotation": float(v[2])})
    achieved = ctl.goal_positions(ans.state.x)
    goals = []
    for q, g in enumerate(cp.goals):
        miss = (achieved[:, q] - g.target)[list(g.fix)]
        goals.append({"loop": list(g.loop), "point": g.point, "goal": g.target.tolist(),
                      "fix": [c for c, f in zip("xy", g.fix) if f],
                      "achieved": achieved[:, q].tolist(), "misfit": float(np.linalg.norm(miss))})
    openings = [{"points": [{"loop": list(lp), "point": lab} for lp, lab, _ in o.points],
                 "at_least": o.at_least, "achieved": o.at_least + float(gp)}
                for o, gp in zip(cp.openings, ans.state.gap)]
    r, equilibrium = ans.state.r, ans.equilibrium
    return {"problem": cp.problem.name, "success": ans.success, "status": ans.status,
            "message": ans.message, "energy": equilibrium.energy.to_json(),
            "objective": float(r @ r), "iterations": ans.iterations, "timings": ans.timings,
            "forward_solves": eq.forward_solves,
            "actuated": actuated, "goals": goals, "openings": openings,
            "stable": ans.stability.stable,
            "min_reduced_hessian_eigenvalue": ans.stability.min_eigenvalue,
            "stability_method": ans.stability.method,
            "forward_check": {"success": ans.forward_success, "max_distance": ans.forward_distance,
                              "restarts_from_the_forward_solve": ctl.restarts},
            "travel_weight": cp.travel_weight,
            "check": equilibrium.checked,             # the answer's own check (output.check)
            "equilibrium": equilibrium.to_json()}
