"""The equilibrium NLP of eq. (13): minimise U_spring + U_bend − W_loads subject to continuity
(18)-(19), the chaining of eq. (1) and the clamps.

Decision variables, in this order (see :class:`Layout`):
- ``coeffs``: every loop's coefficients (2t+2 × N, loop k = (i−1)·n + (j−1)), or in the reduced
  model the representative parameters z with coeffs = T·z (``reduction``, eqs. 22-27);
- ``starts``: every loop's start point (2 × N); the first of each course is (x_i^0, y_i^0);
- lifted spring vectors: BE and RH of every upper loop (courses 2..m), the vectors from the upper
  loop's B (R) to the lower loop's E (H) that eqs. (6)-(7) stretch;
- lifted points: one per clamped or loaded material point.
Equality constraints tie each start, spring vector and lifted point to loop starts plus per-loop
integrals of eq. (1). Every nonlinear term is a per-loop integral of one loop's coefficients, so
the Lagrangian Hessian is block diagonal plus the constant spring part. Lifting the spring
vectors rather than the four points B, E, R, H keeps that and shrinks the KKT system from about
30 to 22 rows per loop (measured: the factorizations dominate large solves); not lifting them at
all couples vertically neighbouring loops in the Hessian and took 437 instead of 28 iterations
on a 50 × 50 pull. Clamp targets, clamp angles,
stiffnesses and loads are NLP parameters: one build serves many solves.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ..model.basis import continuity_rows, n_coeffs, phi
from ..model.energy import bending_energy, spring_pair_energy
from ..model.kinematics import loop_displacements
from ...layout import Layout
from ..model.params import WeftParams, param_layout
from ..model.parametrisation import Full, Parametrisation, Reduced
from ..model.problem import WeftProblem
from .reduction import reduction_map

SPRING_POINTS = ("B", "R", "E", "H")
SPRINGS = (("SL", "B", "E"), ("SR", "R", "H"))   # block, upper point, lower point


@dataclass
class SpecialPoint:
    """A lifted clamped or loaded material point: loop index k and s."""

    k: int
    s: float


@dataclass(frozen=True)
class ClampRows:
    """The constraint rows of one clamp: its held coordinates (``dims``) and its angle."""

    position: slice | None
    dims: tuple[int, ...]
    angle: slice | None


class NLPSizes:
    """What every weft NLP (lifted ``WeftNLP``, condensed ``CondensedNLP``) derives the same way
    from its layouts ``x``, ``g`` and its ``params``."""

    x: Layout
    g: Layout
    params: WeftParams

    @property
    def p0(self) -> np.ndarray:
        """The problem's own parameter vector."""
        return self.params.vector()

    @property
    def n_variables(self) -> int:
        return self.x.size

    @property
    def n_constraints(self) -> int:
        return self.g.size


@dataclass
class WeftNLP(NLPSizes):
    """An assembled NLP with everything needed to solve it and read its solution.

    ``clamp_rows[q]`` and ``rigid_rows[q]`` locate clamp q's and rigid clamp q's constraint rows
    (0-based positions in the problem's lists), so multipliers are read by slice, not by name.
    """

    problem: WeftProblem
    parametrisation: Parametrisation
    nlp: dict[str, ca.MX]
    x: Layout
    p: Layout
    g: Layout
    x0: np.ndarray
    params: WeftParams
    specials: list[SpecialPoint]
    clamp_points: list[int]
    load_points: list[int]
    rigid_points: list[list[int]]
    clamp_rows: list[ClampRows]
    rigid_rows: list[slice]
    energy: ca.Function
    coeff_map: np.ndarray | None
    n_parameters: int
    displacements: ca.MX | None = None     # D: per-loop integrals (2 × N·P), see _constraints
    nlpsol_options: dict = field(default_factory=dict)   # extra nlpsol options (none here)

    @property
    def eval_points(self) -> list[float]:
        """The s-values of each loop's columns of ``displacements``."""
        return eval_points(self.problem, self.specials)

    @property
    def model(self) -> str:
        """``full`` or ``reduced``: the name results and files use."""
        return self.parametrisation.name


    def coefficients(self, xval: np.ndarray) -> np.ndarray:
        """Loop coefficients (m, n, 2t+2) of a solution vector."""
        pr = self.problem
        a = self.x.get(xval, "coeffs")
        if self.coeff_map is not None:
            a = (self.coeff_map @ a.ravel(order="F")).reshape(n_coeffs(pr.t), -1, order="F")
        return a.T.reshape(pr.courses, pr.wales, n_coeffs(pr.t))

    def starts(self, xval: np.ndarray) -> np.ndarray:
        """Loop start points (m, n, 2) of a solution vector."""
        pr = self.problem
        return self.x.get(xval, "starts").T.reshape(pr.courses, pr.wales, 2)

    def special_positions(self, xval: np.ndarray) -> np.ndarray:
        """Positions (2 × specials) of the clamped and loaded material points."""
        return self.x.get(xval, "PC") if self.specials else np.zeros((2, 0))

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """A full decision vector from loop coefficients (m, n, 2t+2) and starts (m, n, 2)."""
        pr = self.problem
        a = coeffs.reshape(pr.n_loops, -1).T
        xval = np.zeros(self.x.size)
        if self.coeff_map is not None:
            z, *_ = np.linalg.lstsq(self.coeff_map, a.ravel(order="F"), rcond=None)
            self.x.put(xval, "coeffs", z)
        else:
            self.x.put(xval, "coeffs", a)
        x_st = starts.reshape(pr.n_loops, 2).T
        self.x.put(xval, "starts", x_st)
        pts = _point_positions(pr, a, x_st, self.specials)
        for name, value in pts.items():
            self.x.put(xval, name, value)
        return xval


def _loop_index(pr: WeftProblem, loop: tuple[int, int]) -> int:
    return (loop[0] - 1) * pr.wales + (loop[1] - 1)


def eval_points(pr: WeftProblem, specials: list[SpecialPoint]) -> list[float]:
    """The s-values each loop's Function reports: L, the spring points, then special points."""
    pts = [pr.L]
    if pr.crossings is not None and pr.courses > 1:
        pts += [pr.crossings.s[k] for k in SPRING_POINTS]
    for sp in specials:
        if sp.s not in pts:
            pts.append(sp.s)
    return pts


def special_points(pr: WeftProblem) -> tuple[list[SpecialPoint], list[int], list[int], list[list[int]]]:
    """Distinct clamped/loaded material points, and each clamp's, load's and rigid clamp's
    point indices among them."""
    specials: list[SpecialPoint] = []

    def index(loop: tuple[int, int], s: float) -> int:
        k = _loop_index(pr, loop)
        for q, sp in enumerate(specials):
            if sp.k == k and sp.s == s:
                return q
        specials.append(SpecialPoint(k, s))
        return len(specials) - 1

    clamps = [index(c.loop, c.s) for c in pr.clamps]
    loads = [index(ld.loop, ld.s) for ld in pr.loads]
    rigid = [[index(loop, s) for loop, _, s in rc.points] for rc in pr.rigid_clamps]
    return specials, clamps, loads, rigid


def _point_positions(pr: WeftProblem, a: np.ndarray, starts: np.ndarray,
                     specials: list[SpecialPoint]) -> dict[str, np.ndarray]:
    """Numeric values of the lifted points for coefficients a (nc × N) and starts (2 × N)."""
    disp = loop_displacements(pr.L, pr.t, np.array(eval_points(pr, specials)),
                              pr.quadrature_nodes).map(pr.n_loops)
    d_all = np.asarray(disp(a))
    n_pts = d_all.shape[1] // pr.n_loops
    col = {s: q for q, s in enumerate(eval_points(pr, specials))}
    out: dict[str, np.ndarray] = {}
    n, N = pr.wales, pr.n_loops
    if _spring_blocks(pr):
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


def _spring_blocks(pr: WeftProblem) -> list[str]:
    """Names of the lifted spring-vector blocks (none for a single course)."""
    return [name for name, _, _ in SPRINGS] if pr.courses > 1 and pr.crossings is not None else []


def build_nlp(pr: WeftProblem, parametrisation: Parametrisation = Full()) -> WeftNLP:
    """Assemble the NLP of a problem in a parametrisation (``Full()`` or ``Reduced(...)``: the
    same model, two parametrisations)."""
    m, n, nc = pr.courses, pr.wales, n_coeffs(pr.t)
    parametrisation = parametrisation.resolve(m, n)
    specials, clamp_pts, load_pts, rigid_pts = special_points(pr)
    coeff_map = reduction_map(pr, parametrisation) if isinstance(parametrisation, Reduced) else None
    xl, xsym, xb, A = _variables(pr, coeff_map, specials)
    pl = param_layout(pr)
    psym = ca.MX.sym("p", pl.size)
    pb = {name: ca.reshape(psym[pl.slice(name)], *shape) for name, (_, _, shape) in pl.blocks.items()}
    gl, g, clamp_rows, rigid_rows, D = _constraints(pr, A, xb, pb, specials, clamp_pts, rigid_pts,
                                                    continuity=coeff_map is None)
    spring, bend, work = _energy_terms(pr, A, xb, pb, specials, load_pts)
    nlp = {"x": xsym, "p": psym, "f": spring + bend - work, "g": g}
    energy = ca.Function("energy", [xsym, psym], [spring, bend, work],
                         ["x", "p"], ["spring", "bending", "load_work"])
    result = WeftNLP(pr, parametrisation, nlp, xl, pl, gl, np.zeros(xl.size), WeftParams.of(pr),
                     specials, clamp_pts, load_pts, rigid_pts, clamp_rows, rigid_rows, energy,
                     coeff_map, n_parameters(pr, parametrisation), D)
    result.x0 = result.lift(np.broadcast_to(pr.natural.coeffs, (m, n, nc)).copy(),
                            pr.natural_starts())
    return result


def _variables(pr: WeftProblem, coeff_map: np.ndarray | None, specials: list[SpecialPoint],
               ) -> tuple[Layout, ca.MX, dict[str, ca.MX], ca.MX]:
    """Decision variables (see the module docstring) and the loop coefficients A (2t+2 × N),
    which in the reduced model are T·z."""
    N, nc = pr.n_loops, n_coeffs(pr.t)
    xl = Layout()
    xl.add("coeffs", *((nc, N) if coeff_map is None else (coeff_map.shape[1], 1)))
    xl.add("starts", 2, N)
    for name in _spring_blocks(pr):
        xl.add(name, 2, N - pr.wales)
    if specials:
        xl.add("PC", 2, len(specials))
    xsym = ca.MX.sym("x", xl.size)
    xb = {name: ca.reshape(xsym[xl.slice(name)], *shape) for name, (_, _, shape) in xl.blocks.items()}
    A = xb["coeffs"] if coeff_map is None else ca.reshape(
        ca.mtimes(_sparse_dm(coeff_map), xb["coeffs"]), nc, N)
    return xl, xsym, xb, A


def _constraints(pr: WeftProblem, A: ca.MX, xb: dict[str, ca.MX], pb: dict[str, ca.MX],
                 specials: list[SpecialPoint], clamp_pts: list[int], rigid_pts: list[list[int]],
                 continuity: bool) -> tuple[Layout, ca.MX, list[ClampRows], list[slice], ca.MX]:
    """All equality constraints g = 0: chaining (eq. 1), lifted spring vectors and points,
    continuity (18)-(19) unless the parametrisation has it built in, clamps; with the rows of
    each clamp and rigid clamp, and the per-loop integrals D they use (g is affine in the
    variables and D)."""
    n, N, X = pr.wales, pr.n_loops, xb["starts"]
    evals = eval_points(pr, specials)
    col, P = {s: q for q, s in enumerate(evals)}, len(evals)
    D = loop_displacements(pr.L, pr.t, np.array(evals), pr.quadrature_nodes).map(N, "serial")(A)

    def at(s: float, loops: np.ndarray) -> ca.MX:
        """Positions of material point s on the given loops: start + per-loop integral."""
        return X[:, loops.tolist()] + D[:, (loops * P + col[s]).tolist()]

    g, gl = [], Layout()

    def add_g(name: str, expr: ca.MX) -> slice | None:
        if not expr.numel():
            return None
        g.append(ca.vec(expr))
        return gl.add(name, expr.numel(), 1)

    left = np.array([k for k in range(N) if k % n != n - 1], dtype=int)
    add_g("chain", X[:, (left + 1).tolist()] - at(pr.L, left))
    if _spring_blocks(pr):
        up, low = np.arange(n, N), np.arange(0, N - n)
        for name, upper, lower in SPRINGS:
            add_g(f"lift_{name}", xb[name] - at(pr.crossings.s[lower], low)
                  + at(pr.crossings.s[upper], up))
    if specials:
        add_g("lift_special", xb["PC"] - ca.horzcat(*[at(sp.s, np.array([sp.k])) for sp in specials]))
    if continuity and n > 1:
        E, S = continuity_rows(pr.L, pr.t)
        add_g("continuity", ca.mtimes(ca.DM(E), A[:, left.tolist()])
              - ca.mtimes(ca.DM(S), A[:, (left + 1).tolist()]))
    clamp_rows = _clamp_constraints(pr, A, xb, pb, clamp_pts, add_g)
    rigid_rows = _rigid_constraints(pr, xb, pb, rigid_pts, add_g)
    return gl, ca.vertcat(*g), clamp_rows, rigid_rows, D


def _energy_terms(pr: WeftProblem, A: ca.MX, xb: dict[str, ca.MX], pb: dict[str, ca.MX],
                  specials: list[SpecialPoint], load_pts: list[int]) -> tuple[ca.MX, ca.MX, ca.MX]:
    """U_spring (eqs. 6-10) over the lifted spring vectors, U_bend (eqs. 11-12) over all loops,
    and the loads' work."""
    bend = ca.sum2(bending_energy(pr.L, pr.t).map(pr.n_loops)(A, ca.DM(pr.natural.coeffs), pb["R_f"]))
    spring = ca.MX(0)
    if _spring_blocks(pr):
        k = ca.vertcat(pb["k_a"], pb["k_b"])
        pair = spring_pair_energy().map(pr.n_loops - pr.wales)
        c = pr.crossings
        spring = (ca.sum2(pair(xb["SL"], ca.DM(c.rest_left), ca.DM(c.frame_left), k))
                  + ca.sum2(pair(xb["SR"], ca.DM(c.rest_right), ca.DM(c.frame_right), k)))
    return spring, bend, _load_work(pr, A, xb, pb, specials, load_pts)


def _sparse_dm(mat: np.ndarray) -> ca.DM:
    """A sparse CasADi matrix holding the nonzeros of ``mat``."""
    cols, rows = np.nonzero(mat.T)            # column-major order, as CasADi stores nonzeros
    sp = ca.Sparsity.triplet(mat.shape[0], mat.shape[1], rows.tolist(), cols.tolist())
    return ca.DM(sp, mat[rows, cols].tolist())


def _clamp_constraints(pr: WeftProblem, A: ca.MX, xb: dict[str, ca.MX], pb: dict[str, ca.MX],
                       clamp_pts: list[int], add_g) -> list[ClampRows]:
    """Position rows P[dim] − target[dim] and angle rows θ(s) − angle, one block per clamp."""
    n_angle, rows = 0, []
    for q, (c, sp) in enumerate(zip(pr.clamps, clamp_pts)):
        dims = [d for d in range(2) if c.fix[d]]
        pos = add_g(f"clamp{q}_pos", xb["PC"][dims, sp] - pb["targets"][dims, q]) if dims else None
        angle = None
        if c.angle is not None:
            row = ca.DM(phi(c.s, pr.L, pr.t))
            angle = add_g(f"clamp{q}_angle", ca.mtimes(row, A[:, _loop_index(pr, c.loop)])
                          - pb["angles"][n_angle])
            n_angle += 1
        rows.append(ClampRows(pos, tuple(dims), angle))
    return rows


def rigid_natural_points(pr: WeftProblem) -> list[np.ndarray]:
    """Natural positions (k × 2) of each rigid clamp's points."""
    return [np.array([pr.natural_position(loop, s) for loop, _, s in rc.points])
            for rc in pr.rigid_clamps]


def _rigid_constraints(pr: WeftProblem, xb: dict[str, ca.MX], pb: dict[str, ca.MX],
                       rigid_pts: list[list[int]], add_g) -> list[slice]:
    """Rows P − (c + R(φ)(P0 − c) + t) for every point of every rigid clamp."""
    rows = []
    for q, (rc, idx, p0) in enumerate(zip(pr.rigid_clamps, rigid_pts, rigid_natural_points(pr))):
        tx, ty, phi_ = pb["rigid"][0, q], pb["rigid"][1, q], pb["rigid"][2, q]
        rot = ca.vertcat(ca.horzcat(ca.cos(phi_), -ca.sin(phi_)), ca.horzcat(ca.sin(phi_), ca.cos(phi_)))
        c = ca.DM(rc.centre)
        target = c + ca.mtimes(rot, ca.DM((p0 - rc.centre).T)) + ca.vertcat(tx, ty)
        rows.append(add_g(f"rigid{q}", xb["PC"][:, idx] - target))
    return rows


def _load_work(pr: WeftProblem, A: ca.MX, xb: dict[str, ca.MX], pb: dict[str, ca.MX],
               specials: list[SpecialPoint], load_pts: list[int]) -> ca.MX:
    """Work of point forces and moments from the natural state: f·(P − P0) + M·(θ(s) − θ0(s))."""
    work = ca.MX(0)
    for q, (ld, sp) in enumerate(zip(pr.loads, load_pts)):
        p0 = ca.DM(pr.natural_position(ld.loop, ld.s))
        work += ca.dot(pb["forces"][:, q], xb["PC"][:, sp] - p0)
        row = ca.DM(phi(ld.s, pr.L, pr.t))
        dtheta = ca.mtimes(row, A[:, _loop_index(pr, ld.loop)] - ca.DM(pr.natural.coeffs))
        work += pb["moments"][q] * dtheta
    return work


def n_parameters(pr: WeftProblem, parametrisation: Parametrisation) -> int:
    """Parameter count as the paper counts it (docs/weft_model.md, "Parameter counts").

    Full: m·n·(2t+2) + 2m. Reduced over p × q representatives: p·q·2t + 2p + 2m.
    """
    nc = n_coeffs(pr.t)
    if not isinstance(parametrisation, Reduced):
        return pr.courses * pr.wales * nc + 2 * pr.courses
    red = parametrisation.resolve(pr.courses, pr.wales)
    p, q = len(red.courses), len(red.wales)
    return p * q * 2 * pr.t + 2 * p + 2 * pr.courses
