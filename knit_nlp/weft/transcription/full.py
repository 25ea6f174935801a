"""The full weft NLP, eq. (13): minimise U_spring + U_bend − W_loads subject to continuity
(18)-(19), the chaining of eq. (1) and the clamps.

Decision variables, in this order (see :class:`Layout`):
- ``coeffs``: every loop's coefficients (2t+2 × N, loop k = (i−1)·n + (j−1));
- ``starts``: every loop's start point (2 × N); the first of each course is (x_i^0, y_i^0);
- lifted spring vectors: BE and RH of every upper loop (courses 2..m), the vectors from the upper
  loop's B (R) to the lower loop's E (H) that eqs. (6)-(7) stretch;
- lifted points: one per clamped or loaded material point.
Equality constraints tie each start, spring vector and lifted point to loop starts plus
per-loop integrals of eq. (1); the clamps' rows are those of ``rows``. Every nonlinear term is a per-loop integral of one loop's coefficients, so
the Lagrangian Hessian is block diagonal plus the constant spring part. Lifting the spring
vectors rather than the four points B, E, R, H keeps that and shrinks the KKT system from about
30 to 22 rows per loop (measured: the factorizations dominate large solves); not lifting them at
all couples vertically neighbouring loops in the Hessian and took 437 instead of 28 iterations
on a 50 × 50 pull. Clamp targets, clamp angles,
stiffnesses and loads are NLP parameters: one build serves many solves.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from ...layout import Layout
from ..model.basis import continuity_rows, n_coeffs, phi
from ..model.energy import bending_energy, spring_pair_energy
from ..model.kinematics import loop_displacements
from ..model.parametrisation import Full
from ..model.params import WeftParams, param_layout
from ..model.problem import WeftProblem
from .protocol import Assembled
from .rows import (SPRINGS, ClampRows, ClampTable, SpecialPoint, add_clamp_rows, eval_points,
                   has_springs, held_dims, loop_index, n_parameters, rigid_natural_points,
                   rigid_targets, special_points)


@dataclass
class FullNLP(Assembled):
    """The full NLP (module docstring) with everything needed to solve it and read its solution
    (the members of :class:`~knit_nlp.weft.transcription.protocol.WeftNLP`).

    ``displacements`` is D, the per-loop integrals (2 × N·P) the constraints are affine in;
    ``energy_terms`` the Function (x, p) -> (spring, bending, load_work).
    """

    energy_terms: ca.Function
    displacements: ca.MX
    x0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nlpsol_options: dict[str, Any] = field(default_factory=dict)   # the factory's derivatives
    parametrisation: Full = Full()
    model: str = "full"

    @property
    def eval_points(self) -> list[float]:
        """The s-values of each loop's columns of ``displacements``."""
        return eval_points(self.problem, self.clamp_table.specials)

    def energy(self, x: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
        spring, bending, work = self.energy_terms(x, p)
        return float(spring), float(bending), float(work)

    def coefficients(self, x: np.ndarray) -> np.ndarray:
        pr = self.problem
        return self.x.get(x, "coeffs").T.reshape(pr.courses, pr.wales, n_coeffs(pr.t))

    def starts(self, x: np.ndarray) -> np.ndarray:
        pr = self.problem
        return self.x.get(x, "starts").T.reshape(pr.courses, pr.wales, 2)

    def special_positions(self, x: np.ndarray) -> np.ndarray:
        return self.x.get(x, "PC") if self.clamp_table.specials else np.zeros((2, 0))

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """The decision vector of these loops (exact: every loop is free), with the lifted
        spring vectors and points computed from them."""
        pr = self.problem
        a = coeffs.reshape(pr.n_loops, -1).T
        x_st = starts.reshape(pr.n_loops, 2).T
        xval = np.zeros(self.x.size)
        self.x.put(xval, "coeffs", a)
        self.x.put(xval, "starts", x_st)
        for name, value in _point_positions(pr, a, x_st, self.clamp_table.specials).items():
            self.x.put(xval, name, value)
        return xval

    def representatives(self) -> None:
        return None


def _point_positions(pr: WeftProblem, a: np.ndarray, starts: np.ndarray,
                     specials: list[SpecialPoint]) -> dict[str, np.ndarray]:
    """Numeric values of the lifted points for coefficients a (nc × N) and starts (2 × N)."""
    evals = eval_points(pr, specials)
    disp = loop_displacements(pr.L, pr.t, np.array(evals), pr.quadrature_nodes).map(pr.n_loops)
    d_all = np.asarray(disp(a))
    n_pts = d_all.shape[1] // pr.n_loops
    col = {s: q for q, s in enumerate(evals)}
    out: dict[str, np.ndarray] = {}
    n, N = pr.wales, pr.n_loops
    if has_springs(pr):
        up, low = np.arange(n, N), np.arange(0, N - n)
        for name, upper, lower in SPRINGS:
            cu, cl = col[pr.crossings.s[upper]], col[pr.crossings.s[lower]]
            out[name] = (starts[:, low] + d_all[:, low * n_pts + cl]
                         - starts[:, up] - d_all[:, up * n_pts + cu])
    if specials:
        ks = np.array([sp.k for sp in specials])
        cs = np.array([col[sp.s] for sp in specials])
        out["PC"] = starts[:, ks] + d_all[:, ks * n_pts + cs]
    return out


def build_nlp(pr: WeftProblem) -> FullNLP:
    """Assemble the full NLP of a problem (``factory.transcribe`` adds its closed-form
    derivatives)."""
    m, n, nc = pr.courses, pr.wales, n_coeffs(pr.t)
    specials, clamp_pts, load_pts, rigid_pts = special_points(pr)
    xl, xsym, xb = _variables(pr, specials)
    pl = param_layout(pr)
    psym = ca.MX.sym("p", pl.size)
    pb = {name: ca.reshape(psym[pl.slice(name)], *shape) for name, (_, _, shape) in pl.blocks.items()}
    rows = _Constraints()
    D = _constraints(pr, xb, pb, specials, rows)
    clamp_rows, rigid_rows = clamp_constraints(pr, xb, pb, clamp_pts, rigid_pts, rows)
    spring, bend, work = _energy_terms(pr, xb, pb, specials, load_pts)
    g = rows.expression()
    nlp = {"x": xsym, "p": psym, "f": spring + bend - work, "g": g}
    energy = ca.Function("energy", [xsym, psym], [spring, bend, work],
                         ["x", "p"], ["spring", "bending", "load_work"])
    table = ClampTable(specials, clamp_pts, load_pts, rigid_pts, clamp_rows, rigid_rows)
    result = FullNLP(pr, nlp, xl, pl, rows.layout, rows.lower(), rows.upper(), WeftParams.of(pr),
                     table, n_parameters(pr, Full()), energy_terms=energy, displacements=D)
    result.x0 = result.lift(np.broadcast_to(pr.natural.coeffs, (m, n, nc)).copy(),
                            pr.natural_starts())
    return result


def _variables(pr: WeftProblem, specials: list[SpecialPoint],
               ) -> tuple[Layout, ca.MX, dict[str, ca.MX]]:
    """Decision variables (module docstring), by block. A further block (e.g. contact
    variables) is one more ``xl.add`` here: the blocks are read by name."""
    N, nc = pr.n_loops, n_coeffs(pr.t)
    xl = Layout()
    xl.add("coeffs", nc, N)
    xl.add("starts", 2, N)
    if has_springs(pr):
        for name, _, _ in SPRINGS:
            xl.add(name, 2, N - pr.wales)
    if specials:
        xl.add("PC", 2, len(specials))
    xsym = ca.MX.sym("x", xl.size)
    xb = {name: ca.reshape(xsym[xl.slice(name)], *shape) for name, (_, _, shape) in xl.blocks.items()}
    return xl, xsym, xb


class _Constraints:
    """Constraint blocks in layout order, each with its bounds lower ≤ g ≤ upper (equalities:
    both 0). A block of inequalities (e.g. contact gaps g ≥ 0) is ``add(name, expr, 0, inf)``."""

    def __init__(self) -> None:
        self.layout = Layout()
        self.blocks: dict[str, tuple[ca.MX, float, float]] = {}

    def add(self, name: str, expr: ca.MX, lower: float = 0.0, upper: float = 0.0) -> slice:
        self.blocks[name] = (ca.vec(expr), lower, upper)
        return self.layout.add(name, expr.numel(), 1)

    def put(self, name: str, expr: ca.MX) -> None:
        """The expression of a block already in the layout (``rows.add_clamp_rows``)."""
        self.blocks[name] = (ca.vec(expr), 0.0, 0.0)

    def expression(self) -> ca.MX:
        return ca.vertcat(*[self.blocks[name][0] for name in self.layout.blocks])

    def _bound(self, k: int) -> np.ndarray:
        return np.concatenate([np.full(stop - start, self.blocks[name][k])
                               for name, (start, stop, _) in self.layout.blocks.items()]
                              or [np.zeros(0)])

    def lower(self) -> np.ndarray:
        return self._bound(1)

    def upper(self) -> np.ndarray:
        return self._bound(2)


Constraints = _Constraints       # the 3-D NLP's rows are kept the same way (transcription.spatial)


def _constraints(pr: WeftProblem, xb: dict[str, ca.MX], pb: dict[str, ca.MX],
                 specials: list[SpecialPoint], rows: _Constraints) -> ca.MX:
    """The equality rows g = 0 of chaining (eq. 1), the lifted spring vectors and points and
    continuity (18)-(19); returns the per-loop integrals D they use (g is affine in the
    variables and D)."""
    n, N, X, A = pr.wales, pr.n_loops, xb["starts"], xb["coeffs"]
    evals = eval_points(pr, specials)
    col, P = {s: q for q, s in enumerate(evals)}, len(evals)
    D = loop_displacements(pr.L, pr.t, np.array(evals), pr.quadrature_nodes).map(N, "serial")(A)

    def at(s: float, loops: np.ndarray) -> ca.MX:
        """Positions of material point s on the given loops: start + per-loop integral."""
        return X[:, loops.tolist()] + D[:, (loops * P + col[s]).tolist()]

    left = np.array([k for k in range(N) if k % n != n - 1], dtype=int)
    if left.size:
        rows.add("chain", X[:, (left + 1).tolist()] - at(pr.L, left))
    if has_springs(pr):
        up, low = np.arange(n, N), np.arange(0, N - n)
        for name, upper, lower in SPRINGS:
            rows.add(f"lift_{name}", xb[name] - at(pr.crossings.s[lower], low)
                     + at(pr.crossings.s[upper], up))
    if specials:
        rows.add("lift_special", xb["PC"] - ca.horzcat(*[at(sp.s, np.array([sp.k]))
                                                         for sp in specials]))
    if n > 1:
        E, S = continuity_rows(pr.L, pr.t)
        rows.add("continuity", ca.mtimes(ca.DM(E), A[:, left.tolist()])
                 - ca.mtimes(ca.DM(S), A[:, (left + 1).tolist()]))
    return D


def clamp_constraints(pr: WeftProblem, xb: dict[str, ca.MX], pb: dict[str, ca.MX],
                      clamp_pts: list[int], rigid_pts: list[list[int]],
                      rows: _Constraints) -> tuple[list[ClampRows], list[slice]]:
    """The clamp rows of ``rows.add_clamp_rows``: held coordinates P[dims] − target[dims],
    angles θ(s) − angle, rigid-clamp points P − (c + R(φ)(P0 − c) + t), on the lifted points'
    x and y (the first two rows of ``PC``: the 3-D NLP's too, ``spatial``)."""
    clamp_rows, rigid_rows = add_clamp_rows(rows.layout, pr)
    n_angle = 0
    for q, (c, sp) in enumerate(zip(pr.clamps, clamp_pts)):
        dims = list(held_dims(c.fix))
        if dims:
            rows.put(f"clamp{q}_pos", xb["PC"][dims, sp] - pb["targets"][dims, q])
        if c.angle is not None:
            angle = ca.mtimes(ca.DM(phi(c.s, pr.L, pr.t)), xb["coeffs"][:, loop_index(pr, c.loop)])
            rows.put(f"clamp{q}_angle", angle - pb["angles"][n_angle])
            n_angle += 1
    for q, (rc, idx, p0) in enumerate(zip(pr.rigid_clamps, rigid_pts, rigid_natural_points(pr))):
        motion = pb["rigid"][:, q]
        rows.put(f"rigid{q}", xb["PC"][:2, idx] - rigid_targets(rc, p0, motion[0], motion[1],
                                                                motion[2]))
    return clamp_rows, rigid_rows


def _energy_terms(pr: WeftProblem, xb: dict[str, ca.MX], pb: dict[str, ca.MX],
                  specials: list[SpecialPoint], load_pts: list[int]) -> tuple[ca.MX, ca.MX, ca.MX]:
    """U_spring (eqs. 6-10) over the lifted spring vectors, U_bend (eqs. 11-12) over all loops,
    and the loads' work."""
    A = xb["coeffs"]
    bend = ca.sum2(bending_energy(pr.L, pr.t).map(pr.n_loops)(A, ca.DM(pr.natural.coeffs), pb["R_f"]))
    spring = ca.MX(0)
    if has_springs(pr):
        k = ca.vertcat(pb["k_a"], pb["k_b"])
        pair = spring_pair_energy().map(pr.n_loops - pr.wales)
        c = pr.crossings
        spring = (ca.sum2(pair(xb["SL"], ca.DM(c.rest_left), ca.DM(c.frame_left), k))
                  + ca.sum2(pair(xb["SR"], ca.DM(c.rest_right), ca.DM(c.frame_right), k)))
    return spring, bend, _load_work(pr, xb, pb, load_pts)


def _load_work(pr: WeftProblem, xb: dict[str, ca.MX], pb: dict[str, ca.MX],
               load_pts: list[int]) -> ca.MX:
    """Work of point forces and moments from the natural state: f·(P − P0) + M·(θ(s) − θ0(s))."""
    work = ca.MX(0)
    for q, (ld, sp) in enumerate(zip(pr.loads, load_pts)):
        p0 = ca.DM(pr.natural_position(ld.loop, ld.s))
        work += ca.dot(pb["forces"][:, q], xb["PC"][:, sp] - p0)
        row = ca.DM(phi(ld.s, pr.L, pr.t))
        dtheta = ca.mtimes(row, xb["coeffs"][:, loop_index(pr, ld.loop)] - ca.DM(pr.natural.coeffs))
        work += pb["moments"][q] * dtheta
    return work
