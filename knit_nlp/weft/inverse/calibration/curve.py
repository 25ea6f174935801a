"""A model test curve: the pulled clamp moved in warm-started steps, force and strains recorded.

One forward NLP is built per specimen (``forward.equilibrium_for``: with
``[yarn] radius`` every solve is a contact solve and the KKT system holds the active contacts)
and re-solved at every step from the previous step's solution. Steps aim at even force
increments (the secant stiffness of the last step sets the next), so the curve is resolved
alike wherever its slope; a failed solve halves the step. The curve ends at the first node
past the goal force (and past a smallest strain, if asked: beyond the goal force the steps aim
at even strain increments up to it, and stop where the force passes ``JAMMED`` times the goal),
or where the model's force stops rising (after a fall the step is tried again shorter, at most
``BRANCH_RETRIES`` times a curve: a long step can land on another equilibrium), or at
``MAX_STRAIN``. ``CurveModel`` steps; a
clamped specimen (``SpecimenModel``) or a periodic cell (``cell.CellModel``) solves and reads.

Strain at a force is read by monotone cubic (PCHIP) interpolation of the nodes. Sensitivities
of those strains to the material values come either from the implicit-function theorem at each
node (``implicit``: one KKT factorization per node, :meth:`Equilibrium.sensitivity`): at fixed
force, dε/dθ = −(∂F/∂θ)/(∂F/∂u)/L0 and the lateral strain's likewise; or from curves re-solved at
perturbed values on the same clamp positions, warm-started from the base nodes
(``finite_differences``). ``scripts/bench_calibration.py`` measures both.

The 3-D model (``[yarn] geometry = "3d"``) has neither yet: its sensitivities are differences
of whole curves (``curve_differences``, ``calibrate.TestModel.derivatives``). Its curve steps
are single IPOPT solves warm-started from the last node (``SpecimenModel._solve``), and its
lateral points are read on the space curves' projection (``points.point_function``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import casadi as ca
import numpy as np
from scipy.interpolate import PchipInterpolator
from scipy.sparse.linalg import splu

from ..forward import CURVE_KEEP, equilibrium_for
from ..points import point_function, point_jacobian
from ...model.params import WeftParams
from ...model.spatial.state import spatial_samples
from ...output.check import own_check, spatial_own_check
from ....progress import no_path
from .specimen import PULLED, Specimen

SENSITIVITIES = ("implicit", "finite_differences", "curve_differences")
NODES = 12                  # force increments aimed at between zero and the goal (measured:
                            # strains at the metric forces within 2.3e-4 of 96 increments)
FIRST_STRAIN = 0.01         # the first step, before any stiffness is known
MIN_STRAIN_STEP = 1e-4
MAX_STRAIN_STEP = 0.1
MAX_STRAIN = 3.0            # a jersey loop (ω = 2) pulled straight along the course: L/w − 1 = 3.5
MAX_HALVINGS = 6
# A curve that runs on past its goal force (to the strain the checks read) stops where its force
# passes JAMMED times the goal: the loops are jammed against their yarns' cores. (The periodic
# cell's wale pull at k = 0.048 N/mm³ passed 353 N per cell at 27.6 % strain, the goal 0.9,
# then crept on in successful micro-steps at 1e4-1e8 N between failed 9 s ones: 5 minutes for
# one curve, measured.)
JAMMED = 100.0
# A step after which the force has fallen is tried again from the last node at a quarter of its
# length (and no later step is longer), at most BRANCH_RETRIES times per curve, before the curve
# is said to stop rising: a long step can land on another equilibrium (the periodic cell's are
# not unique: bent from a straight yarn its wale pull at k = 0.00465 N/mm³ fell from 17.8 N at
# 20.6 % strain after a 1.6 % step, where 1.25 % steps go on rising, clean, to 30 %; measured,
# docs/real_fabric.md).
BRANCH_RETRIES = 3
KKT_RESIDUAL = 1e-8        # relative residual above which a KKT solve is refused
# Finite differences: central, with a relative step of 1e-3. The step must move the KKT
# residual well above IPOPT's tolerance (1e-8), or the warm-started solve returns the base point
# unchanged: at 1e-5 the 2 x 3 course pull's dF/dk_b came out 15 times too small (measured).
FD_STEP = 1e-3


@dataclass
class Curve:
    """Nodes of a model test curve at material values ``material`` (model force units)."""

    u: np.ndarray                      # pulled clamp's travel
    force: np.ndarray                  # its reaction along the pull, on the model specimen
    lateral: np.ndarray                # distance between the free edges' points
    xs: list[np.ndarray] = field(repr=False, default_factory=list)
    lams: list[np.ndarray] = field(repr=False, default_factory=list)
    material: dict[str, float] = field(default_factory=dict)
    complete: bool = True              # reached the goal force
    reason: str = ""                   # why not
    solves: int = 0
    iterations: int = 0


class CurveModel:
    """A test's curves by warm-started steps of the pulled clamp (module docstring). A model
    gives ``specimen`` (gauge, lateral width), ``params(material, u)``, ``_solve(p, x0, curve,
    p0)`` (a solve with ``success``, ``status``, ``x``, ``iterations``), ``read(rep)`` (the
    force along the pull and the lateral distance of a solve), ``multipliers(rep)`` and
    ``check(x)`` (the own check's block of a node's answer)."""

    specimen: Any
    max_strain_step = MAX_STRAIN_STEP
    takes_rigidity = False          # its NLP takes the contact rigidity as a parameter

    def params(self, material: dict[str, float], u: float) -> Any:
        raise NotImplementedError

    def _solve(self, p: Any, x0: np.ndarray | None, curve: Curve, p0: Any = None) -> Any:
        raise NotImplementedError

    def read(self, rep: Any) -> tuple[float, float]:
        raise NotImplementedError

    def multipliers(self, rep: Any) -> np.ndarray:
        raise NotImplementedError

    def check(self, x: np.ndarray) -> dict[str, Any]:
        raise NotImplementedError

    def _record(self, c: Curve, us: list, fs: list, lats: list, u: float, rep: Any) -> None:
        f, lat = self.read(rep)
        us.append(float(u))
        fs.append(f)
        lats.append(lat)
        c.xs.append(rep.x)
        c.lams.append(self.multipliers(rep))

    def _unloaded(self, material: dict[str, float], c: Curve) -> tuple[list, list, list] | None:
        """A curve's first node, the unloaded specimen, recorded in ``c`` with no force by
        definition: the travel, force and lateral lists that start there; None (and ``c``
        incomplete, saying why) where its solve failed."""
        rep = self._solve(self.params(material, 0.0), None, c)
        if not rep.success:
            c.complete, c.reason = False, f"the unloaded specimen did not solve ({rep.status})"
            return None
        us, fs, lats = [], [], []
        self._record(c, us, fs, lats, 0.0, rep)
        fs[0] = 0.0
        return us, fs, lats

    def curve(self, material: dict[str, float], goal: float,
              strain_limit: float = MAX_STRAIN, min_strain: float = 0.0) -> Curve:
        """Pull until the force passes ``goal`` (model force units) and the axial strain
        ``min_strain``, or until the axial strain ``strain_limit``."""
        L0 = self.specimen.gauge
        c = Curve(np.zeros(0), np.zeros(0), np.zeros(0), material=dict(material))
        if (started := self._unloaded(material, c)) is None:
            return c
        us, fs, lats = started
        step, retries, cap = FIRST_STRAIN * L0, BRANCH_RETRIES, np.inf
        while fs[-1] < goal or us[-1] < min_strain * L0:
            remaining = strain_limit * L0 - us[-1]
            if remaining < MIN_STRAIN_STEP * L0 or len(us) > 10 * NODES:
                c.complete, c.reason = False, (f"stopped at axial strain {us[-1] / L0:.3g} "
                                               "(the strain limit) short of the goal force")
                break
            if remaining - step < MIN_STRAIN_STEP * L0:     # no sliver of a last step
                step = remaining
            p_last = self.params(material, us[-1])
            for _ in range(MAX_HALVINGS + 1):
                u = us[-1] + step
                rep = self._solve(self.params(material, u), c.xs[-1], c, p_last)
                if rep.success:
                    break
                step /= 2
            else:
                c.complete, c.reason = False, (f"no equilibrium past strain {us[-1] / L0:.3g} "
                                               f"({rep.status})")
                break
            f = self.read(rep)[0]
            if not f > fs[-1] and retries > 0 and step / 4 >= MIN_STRAIN_STEP * L0:
                retries, step = retries - 1, step / 4       # another branch? (BRANCH_RETRIES)
                cap = step                                  # no longer steps from here on
                continue
            if not f > fs[-1]:
                c.complete, c.reason = False, (f"the model's force stops rising at axial "
                                               f"strain {u / L0:.3g}")
                break
            stiffness = (f - fs[-1]) / step
            self._record(c, us, fs, lats, u, rep)
            if f > JAMMED * goal:
                c.reason = (f"the model jams: {f / goal:.3g} times the goal force at axial "
                            f"strain {u / L0:.3g}")
                break
            aim = goal / NODES / stiffness if f < goal else min_strain * L0 / NODES
            step = float(np.clip(aim, MIN_STRAIN_STEP * L0,
                                 min(self.max_strain_step * L0, 3 * step, cap)))
        if fs[-1] >= goal:          # stopped on the way to min_strain: the goal was reached
            c.complete = True
            c.reason = c.reason if fs[-1] > JAMMED * goal else ""     # (the jam is said)
        c.u, c.force, c.lateral = np.array(us), np.array(fs), np.array(lats)
        return c

    def pull_to(self, material: dict[str, float], strains: np.ndarray,
                report: Callable[[float, Any], None] | None = None) -> Curve:
        """The curve at given axial strains (negative: pushed together), in order, each solve
        warm-started from the last; a failed step is halved (``MAX_HALVINGS``) through
        intermediate strains, which are not recorded. Stops at the first strain it cannot reach
        (``reason``). ``report(strain, solution)`` is called at every recorded node."""
        L0 = self.specimen.gauge
        c = Curve(np.zeros(0), np.zeros(0), np.zeros(0), material=dict(material))
        if (started := self._unloaded(material, c)) is None:
            return c
        us, fs, lats = started
        for target in np.asarray(strains, dtype=float) * L0:
            u, x, step, halvings = us[-1], c.xs[-1], target - us[-1], 0
            while u != target and halvings <= MAX_HALVINGS:
                nxt = target if abs(target - u) <= abs(step) else u + step
                rep = self._solve(self.params(material, nxt), x, c, self.params(material, u))
                if rep.success:
                    u, x = nxt, rep.x
                else:
                    halvings, step = halvings + 1, step / 2
            if u != target:
                c.complete, c.reason = False, (f"no equilibrium past strain {u / L0:.3g} "
                                               f"({rep.status})")
                break
            self._record(c, us, fs, lats, target, rep)
            if report is not None:
                report(target / L0, rep)
        c.u, c.force, c.lateral = np.array(us), np.array(fs), np.array(lats)
        return c



class SpecimenModel(CurveModel):
    """A specimen's forward NLP, built once, and its curves."""

    def __init__(self, specimen: Specimen) -> None:
        self.specimen = specimen
        yarn = specimen.problem.yarn
        self.spatial = yarn is not None and yarn.spatial
        self.eq = equilibrium_for(specimen.problem, CURVE_KEEP, load_path=True)
        low, high = specimen.lateral_points
        points = point_function(self.eq.wnlp, [*low, *high])
        self._points = point_jacobian(points)
        self._n_low = len(low)
        self.base = WeftParams.of(specimen.problem)
        pulled = self.eq.wnlp.clamp_table.rigid_rows[PULLED - 1]
        rows = np.arange(pulled.start, pulled.stop)
        self._rows = rows.reshape(-1, 2)[:, specimen.axis]     # the pull's component per point
        self.build_s = self.eq.build_s

    def params(self, material: dict[str, float], u: float) -> np.ndarray:
        return self.base.with_(material=material,
                               rigid={PULLED: self.specimen.translation(u)}).vector()

    def force(self, lam: np.ndarray) -> np.ndarray:
        """The pulled clamp's force on the fabric along the pull (results.RigidClampReaction:
        −λ of its rows), for λ of shape (m,) or (m, k)."""
        return -np.sum(lam[self._rows], axis=0)

    def lateral(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """Distance between the free edges' points and its gradient in x."""
        P, J = self._points(x)
        other = 1 - self.specimen.axis
        P, J = np.asarray(P), np.asarray(ca.DM(J))
        k = self._n_low
        w = np.r_[-np.full(k, 1.0 / k), np.full(P.shape[1] - k, 1.0 / (P.shape[1] - k))]
        rows = 2 * np.arange(P.shape[1]) + other            # vec(P) is column-major
        return float(P[other] @ w), w @ J[rows]

    def read(self, rep: Any) -> tuple[float, float]:
        return float(self.force(rep.lam_g)), self.lateral(rep.x)[0]

    def multipliers(self, rep: Any) -> np.ndarray:
        return rep.lam_g

    def check(self, x: np.ndarray) -> dict[str, Any]:
        """The own check's block of answer x (``output.check.own_check``; in 3-D
        ``spatial_own_check``: all pairs of yarn pieces)."""
        pr, wnlp = self.specimen.problem, self.eq.wnlp
        if self.spatial:
            return spatial_own_check(pr, wnlp.centrelines3d(x, spatial_samples(pr)))
        return own_check(pr, wnlp.coefficients(x), wnlp.starts(x))[1]

    def _solve(self, p: np.ndarray, x0: np.ndarray | None, curve: Curve,
               p0: np.ndarray | None = None):
        """The equilibrium at p from x0; with ``p0`` (x0's parameters, x0 solved there) a
        solve with contact is one load step from that state instead of rounds from the
        paper's solution (measured on c4k's course pull: the same curve to 5 digits, 311
        IPOPT iterations instead of 410, 28 s instead of 43 s; the paper's model ignores it)."""
        if self.spatial and x0 is not None:
            rep = self._step3d(p, x0)
        else:
            rep = self.eq.solve(p, x0, origin=None if p0 is None else (x0, p0))
        curve.solves += 1
        curve.iterations += rep.iterations
        return rep

    def _step3d(self, p: np.ndarray, x0: np.ndarray):
        """A 3-D curve step: one IPOPT solve from the last node's state ``x0`` (the default
        3-D solve steps the load from the natural state in 4 solves whatever ``x0``; on a
        5 x 3 wale pull that ran over 4000 iterations at 7.5 % strain where single warm steps
        took 4-6 each, measured). A failed step is halved by the caller; ``[solver] max_iter``
        bounds each. With lagged friction (``[yarn] friction``, docs/weft3d.md "Friction") the
        curve is the load path: every step lags from ``x0``, the last accepted state (a halved
        step from it too), so a curve depends on its steps as a pull does on its load steps."""
        solver = self.eq.solver
        solver.start_clock()
        no_path()              # one solve: not a share of the unloaded solve's load steps
        solver.begin_path(x0)  # lagged friction (if any): from the last node, halved or not
        return self.eq.solution(solver.once(p, x0), p)

    def on_grid(self, material: dict[str, float], base: Curve) -> Curve:
        """The curve at other material values on ``base``'s clamp positions, each solve
        warm-started from ``base``'s solution there (finite differences)."""
        c = Curve(base.u.copy(), np.zeros_like(base.u), np.zeros_like(base.u),
                  material=dict(material))
        for k, u in enumerate(base.u):
            rep = self._solve(self.params(material, u), base.xs[k], c,
                              self.params(base.material, u))
            if not rep.success:
                c.complete, c.reason = False, f"a perturbed solve failed ({rep.status})"
                return c
            c.force[k] = float(self.force(rep.lam_g))
            c.lateral[k] = self.lateral(rep.x)[0]
        return c

    def kkt_sensitivity(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray,
                        dp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """dx/dθ, dλ/dθ = −K⁻¹ ∂F/∂p · dp on the equilibrium's KKT system
        (``Equilibrium.linear_system``: with contact the active contacts' rows and sliding
        points), solved by SuperLU with the residual checked. (CasADi's MUMPS, which
        ``Equilibrium.sensitivity`` uses, returned the right-hand side unchanged, without an
        error, on the course pull at k_a = 4003, k_b = 0.009, R_f = 0.045 N/mm, N mm²; SuperLU's
        residual there is 1e-14.) NaN where the system is singular."""
        mat, Fp, nz = self.eq.linear_system(x, lam, p)
        rhs = -(Fp @ dp)
        try:
            dz = splu(mat).solve(rhs)
        except RuntimeError:                    # exactly singular
            dz = np.full(rhs.shape, np.nan)
        bad = np.linalg.norm(mat @ dz - rhs, axis=0) > KKT_RESIDUAL * (1 + np.linalg.norm(rhs, axis=0))
        dz[:, bad] = np.nan
        return dz[:self.eq.wnlp.n_variables], dz[nz:]

    def node_sensitivities(self, c: Curve, names: list[str]) -> tuple[np.ndarray, np.ndarray,
                                                                      np.ndarray, np.ndarray]:
        """At every node: ∂F/∂u, ∂F/∂θ (nodes × k), ∂lat/∂u, ∂lat/∂θ, θ the material values
        ``names`` (implicit-function theorem on each node's KKT system)."""
        base = self.params(c.material, 0.0)
        dirs = [self.params(c.material, 1.0) - base]
        for name in names:
            dirs.append(self.params({**c.material, name: c.material[name] + 1.0}, 0.0) - base)
        dp = np.stack(dirs, axis=1)
        Fu, Ft, Lu, Lt = [], [], [], []
        for u, x, lam in zip(c.u, c.xs, c.lams):
            dx, dlam = self.kkt_sensitivity(x, lam, self.params(c.material, u), dp)
            dF = self.force(dlam)
            dL = self.lateral(x)[1] @ dx
            Fu.append(dF[0])
            Ft.append(dF[1:])
            Lu.append(dL[0])
            Lt.append(dL[1:])
        return np.array(Fu), np.array(Ft).reshape(len(c.u), -1), np.array(Lu), np.array(
            Lt).reshape(len(c.u), -1)


def strains_at(c: Curve, specimen: Specimen, forces: np.ndarray,
               extrapolate: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Axial and lateral strain at model forces ``forces``: NaN past the curve's last node, or
    with ``extrapolate`` continued along the last node's tangent (so that a fit far from the
    answer, whose curve stops short, still sees how far it is)."""
    forces = np.asarray(forces, dtype=float)
    if len(c.u) < 2 or not np.all(np.diff(c.force) > 0):   # (a re-solved curve may not rise)
        nan = np.full(forces.shape, np.nan)
        return nan, nan.copy()
    top = c.force[-1]
    inside = np.clip(forces, 0.0, top)
    u_of, lat_of = PchipInterpolator(c.force, c.u), PchipInterpolator(c.force, c.lateral)
    u, lat = u_of(inside), lat_of(inside)
    beyond = forces - inside
    if extrapolate:
        u = u + beyond * u_of.derivative()(top)
        lat = lat + beyond * lat_of.derivative()(top)
    else:
        u, lat = np.where(beyond > 0, np.nan, u), np.where(beyond > 0, np.nan, lat)
    return u / specimen.gauge, lat / specimen.lateral_width - 1.0


def strain_slopes(c: Curve, specimen: Specimen, forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d(axial strain)/dF and d(lateral strain)/dF along the curve at ``forces`` (the last
    node's past it, as ``strains_at`` extrapolates)."""
    forces = np.clip(np.asarray(forces, dtype=float), 0, c.force[-1])
    du = PchipInterpolator(c.force, c.u).derivative()(forces)
    dl = PchipInterpolator(c.force, c.lateral).derivative()(forces)
    return du / specimen.gauge, dl / specimen.lateral_width


def implicit_derivatives(model: SpecimenModel, c: Curve, names: list[str],
                         forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d(axial, lateral strain at fixed model forces)/dθ (len(forces) × k), implicit function."""
    Fu, Ft, Lu, Lt = model.node_sensitivities(c, names)
    sp = model.specimen
    ok = Fu > 0
    du = np.where(ok[:, None], -Ft / np.where(ok, Fu, 1.0)[:, None], 0.0)   # du/dθ at fixed F
    dax = du / sp.gauge
    dlat = (Lt + Lu[:, None] * du) / sp.lateral_width
    interp = lambda nodes: np.stack([np.interp(forces, c.force, nodes[:, k])  # noqa: E731
                                     for k in range(nodes.shape[1])], axis=1)
    return interp(dax), interp(dlat)


def fd_derivatives(model: SpecimenModel, c: Curve, names: list[str],
                   forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The same by central differences of curves re-solved on ``c``'s clamp positions."""
    sp = model.specimen
    dax, dlat = [], []
    for name in names:
        h = FD_STEP * c.material[name]
        pairs = [strains_at(model.on_grid({**c.material, name: c.material[name] + sign * h}, c),
                            sp, forces) for sign in (1.0, -1.0)]
        dax.append((pairs[0][0] - pairs[1][0]) / (2 * h))
        dlat.append((pairs[0][1] - pairs[1][1]) / (2 * h))
    shape = (len(forces), len(names))
    return (np.stack(dax, axis=1) if dax else np.zeros(shape),
            np.stack(dlat, axis=1) if dlat else np.zeros(shape))
