"""The 3-D weft model's loop as a periodic cell: one loop repeated on its lattice (w, c), a
fabric with no edges (docs/real_fabric.md, "A periodic cell").

The cell's unknowns are x = (a, b, σ_u (n), σ_l (n), w, c): the loop's θ and φ coefficients,
the n persistent contacts' material points on the loop and on the loop one course up (the
natural shape's: two wraps for a yarn with a core, four touching crossings without one,
``natural_fit``), and the lattice.
Its rows: the loop closes on the lattice (x(L) − x(0) = (w, 0, 0)); θ, θ′, φ, φ′ periodic
(N2); each wrap's pair of points is a pair of closest points (S6); and the pull fixes the
spacing along it, w (courses) or c (wales); the other spacing is free (a uniaxial pull: no
lateral force). Its energy per cell (p = (pulled spacing, R_f, k)):

    U = R_f · B(a, b)                     (S4, bent from the natural loop, or with
                                           ``straight`` from a straight yarn)
        + Σ over the n contacts E(h′, sin α)         (S5-S7, C3: the model's persistent
                                                      contacts with the loop one course up)
        + Σ over the other pairs w_s² v(d′)           (R1, C3)

Bent from the natural loop the contacts pressed at rest see the law thinned (C3), so that the
natural loop is stress-free; bent from a straight yarn the loop is prestressed anyway and every
contact sees the yarn's own law (a = 1), as stitch-by-stitch's simulation does (its relaxed
cell and course sweep are reproduced: docs/real_fabric.md, "The source's own cell").
Both contact sums are linear in the law's rigidity k (compression.py), which is a parameter:
the NLP at k is the NLP built at k, number for number. (Solved instead at R_f·k₀/k with
the built k₀ and its forces times k/k₀, the same equilibrium in exact arithmetic, IPOPT took
another path from the natural loop: from it the acrylic's cell at k = 0.0192 N/mm³, 5 %
strain, came out at U 0.00097 against 0.00083 N·mm, a second local minimum; from the other's
answer, the same to 1e-9. The cell's equilibria are not unique.)

The other pairs are the model's own neighbour list (``repulsion.natural_neighbours``) read
from one loop of a 3 × 5 fabric to its images within two courses and two wales, naturally
closer than ``reach``·2r. The force through one cell is the pull row's multiplier,
F = dU/d(spacing) (the envelope theorem); per width it is F / c₀ (courses) or F / w₀ (wales).
The check of a state is the model's own all-pairs check of 4 × 4 loops of the periodic
fabric, the designed crossings read on the natural fabric (``natural_fit.natural_check``).
A state's contacts are read back by ``contact_state`` (the wraps' normal forces) and
``pair_state`` (the other pairs' energies and pushes); ``solve_cell(..., held=True)`` holds the
spacing across the pull (plane strain) instead of leaving it free.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import casadi as ca
import numpy as np

from ....ipopt import ipopt_options, succeeded
from ..basis import continuity_rows, n_coeffs
from ..compression import SoftShell
from .crossing_contact import crossing_terms, read_crossings
from .curve3d import bending3d, loop_displacements3d, segment
from .friction import Lagged
from .natural3d import Natural3D
from .natural_fit import natural_check
from .proximity import ProximityReport
from .repulsion import natural_neighbours, sample_s

DIRECTIONS = ("courses", "wales")
GAUSS = 16                      # Gauss nodes of a wrap's segment to σ
SAMPLES = 80                    # other-contact samples per loop (48, 64, 80: course F(10 %)
                                # 0.329, 0.334, 0.335 N; docs/real_fabric.md)
REACH = 2.5                     # other pairs listed: naturally closer than REACH · 2r
MAX_ITER = 500
TOL = 1e-10
MIN_SPACING = 0.3               # a spacing's lower bound, times its natural value


@dataclass
class PeriodicCell:
    """The cell's NLP along ``direction`` (module docstring): ``solver`` IPOPT with
    p = (pulled spacing, R_f, k), ``energy`` U(x, p); ``shape`` the reference lattice the
    strains are read from (the natural loop's, or a relaxed cell's), ``natural`` the natural
    fabric the check reads the designed crossings on."""

    shape: Natural3D
    natural: Natural3D
    core: float                  # R_c
    direction: str
    solver: ca.Function
    energy: ca.Function
    rows: int
    pairs: int
    rigidity: float              # the law's k the cell was built with (the default k)
    law: SoftShell
    closest: ca.Function         # x -> the contacts' points and tangents (p_u, t_u, p_l, t_l)
    pair_vectors: ca.Function    # x -> each other pair's vector between its samples (3 × P)
    pair_scales: np.ndarray      # each other pair's thinning a (C3; 1 for a straight yarn's)
    wrap_scales: np.ndarray      # each wrap's thinning a (C3; 1 for a straight yarn's)
    samples: int                 # other-contact samples per loop

    @property
    def spacing0(self) -> float:
        """The reference spacing along the pull."""
        return self.shape.wale_spacing if self.direction == "courses" else self.shape.course_spacing

    @property
    def across0(self) -> float:
        """The reference spacing across the pull (the width one cell carries)."""
        return self.shape.course_spacing if self.direction == "courses" else self.shape.wale_spacing

    @property
    def across_index(self) -> int:
        """Where x holds the spacing across the pull (x ends with w, c)."""
        return -1 if self.direction == "courses" else -2

    def across(self, x: np.ndarray) -> float:
        """The spacing across the pull at state x."""
        return float(x[self.across_index])

    def along(self, x: np.ndarray) -> float:
        """The spacing along the pull at state x."""
        return float(x[-2] if self.direction == "courses" else x[-1])


@dataclass(frozen=True)
class CellSolution:
    """One solve of the cell: state x, energy U (N·mm), force through one cell F (N)."""

    x: np.ndarray
    U: float
    F: float
    success: bool
    status: str
    iterations: int


def cell_pairs(shape: Natural3D, law: SoftShell, samples: int = SAMPLES,
               reach: float = REACH) -> tuple[np.ndarray, ...]:
    """The other contacts' pairs of the cell (``repulsion.natural_neighbours``: one piece of
    yarn and the wraps' windows left out, each pair's thinning scale, C3) read from one loop of
    a 3 × 5 fabric, which holds every lattice offset of the list, to its images: sample
    coordinates s, sample k on the loop, m on its image at (dj·w, di·c), di, dj and the scale.
    The model lists pairs naturally closer than 1.25·2r and its rounds add those that come
    close; the cell has no rounds, so its list reaches ``reach``·2r (the law is zero beyond
    touch: a listed pair that stays apart costs only its evaluation)."""
    wales, loop = 5, 2                   # loop (course 1, wale 3); kb − ka = di·wales + dj
    nb = natural_neighbours(shape, law, 3, wales, samples, reach)
    sel = nb.ka == loop
    DI, DJ = np.divmod(nb.kb[sel] - loop + 2, wales)
    return sample_s(shape.length, samples), nb.qa[sel], nb.qb[sel], DI, DJ - 2, nb.scale[sel]


def build_cell(shape: Natural3D, law: SoftShell, direction: str, samples: int = SAMPLES,
               straight: bool = False, reach: float = REACH, max_iter: int = MAX_ITER,
               max_time: float | None = None, thinned: bool | None = None) -> PeriodicCell:
    """The cell's NLP (module docstring) pulled along ``direction``; ``max_iter`` and
    ``max_time`` (s) bound each solve. ``thinned``: the contacts pressed at rest see the law
    thinned (C3); by default only when bent from the natural loop (``wrap_thinning``)."""
    if direction not in DIRECTIONS:
        raise ValueError(f"direction must be one of {DIRECTIONS}, not {direction!r}")
    nc, nq = n_coeffs(shape.harmonics), n_coeffs(shape.modes)
    n = len(shape.s_upper)
    xs = ca.MX.sym("x", nc + nq + 2 * n + 2)
    p = ca.MX.sym("p", 3)                       # (pulled spacing, R_f, k)
    w, c = xs[-2], xs[-1]
    thin = (not straight) if thinned is None else thinned
    ex = cell_expressions(shape, law, xs[:-2], (w, c, 0.0), p[1], p[2], samples, straight,
                          reach, thin)
    energy, rows = ex.energy, list(ex.rows)
    rows.append((w if direction == "courses" else c) - p[0])                    # the pull
    g = ca.vertcat(*rows)
    solver = ca.nlpsol("periodic_cell", "ipopt", {"x": xs, "p": p, "f": energy, "g": g},
                       cell_solver_options(TOL, max_iter, max_time))
    return PeriodicCell(shape, shape, law.core_radius, direction, solver,
                        ca.Function("U", [xs, p], [energy]), g.numel(), ex.pairs,
                        law.rigidity, law, ca.Function("closest", [xs], [ex.closest]),
                        ca.Function("pair_vectors", [xs], [ex.pair_vectors]), ex.pair_scales,
                        ex.wrap_scales, samples)


def cell_solver_options(tol: float, max_iter: int, max_time: float | None) -> dict:
    """IPOPT's options for a cell's NLP (or a specimen of cells): ``max_iter`` and
    ``max_time`` (s) bound each solve; NaN warnings silenced (a step into a core)."""
    opts = ipopt_options(tol, max_iter, **({} if max_time is None else
                                           {"max_wall_time": float(max_time)}))
    opts["show_eval_warnings"] = False
    return opts


@dataclass(frozen=True)
class CellExpressions:
    """The cell's energy and rows at a lattice (``cell_expressions``): ``energy`` R_f·B +
    (k/k₀)·contact, ``rows`` the closure, N2 and the wraps' closest-point rows, ``closest`` the
    wraps' points and tangents (12 × n), ``pair_vectors`` the other pairs' vectors (3 × P)."""

    energy: Any
    rows: tuple[Any, ...]
    closest: Any
    pair_vectors: Any
    pair_scales: np.ndarray
    wrap_scales: np.ndarray

    @property
    def pairs(self) -> int:
        return int(self.pair_scales.size)


def cell_expressions(shape: Natural3D, law: SoftShell, y: Any, lattice: tuple[Any, Any, Any],
                     R_f: Any, k: Any, samples: int = SAMPLES, straight: bool = False,
                     reach: float = REACH, thin: bool = True) -> CellExpressions:
    """The cell's energy and rows (module docstring) in its loop's unknowns y = (a, b, σ_u,
    σ_l) on the lattice (w, c, s): the course period (w, 0, 0) and the course above shifted by
    (s, c, 0), s the lattice's shear (0 in the uniaxial cell; the clamped specimen of cells,
    ``cell_fabric``, shears it). An image at lattice offset (dj, di) sits at
    (dj·w + di·s, di·c, 0)."""
    w, c, s = lattice
    L, t, q = shape.length, shape.harmonics, shape.modes
    nc, nq = n_coeffs(t), n_coeffs(q)
    n = len(shape.s_upper)
    contact = 0.0
    a, b = y[:nc], y[nc:nc + nq]
    su, sl = y[nc + nq:nc + nq + n], y[nc + nq + n:nc + nq + 2 * n]
    a0 = np.zeros(nc) if straight else shape.coeffs
    b0 = np.zeros(nq) if straight else shape.elevation
    energy = bending3d(L, t, q, 8)(a, b, ca.DM(a0), ca.DM(b0), R_f)
    seg, terms = segment(L, t, q, GAUSS), crossing_terms(law)
    shift = ca.vertcat(s, c, 0)
    rows = [seg(a, b, 0.0, L)[0] - ca.vertcat(w, 0, 0)]                         # closure
    for deg, coef in ((q, b), (t, a)):                                          # N2
        E, S = continuity_rows(L, deg)
        rows.append(ca.mtimes(ca.DM(E - S), coef))
    signs, scales = shape.crossing_signs(), wrap_thinning(shape, law, thin)
    closest = []
    for j in range(n):                                                          # S5-S7
        pu, tu = seg(a, b, 0.0, su[j])
        pl, tl = seg(a, b, 0.0, sl[j])
        e, r, *_ = terms(pu + shift, tu, pl, tl, signs[j], scales[j])
        contact += e
        rows.append(r)
        closest.append(ca.vertcat(pu + shift, tu, pl, tl))
    sv, K, M, DI, DJ, scale = cell_pairs(shape, law, samples, reach)            # R1
    if not thin:
        scale = np.ones_like(scale)
    G = loop_displacements3d(L, t, q, sv, 8)(a, b)
    along = ca.DM(DJ).T * w
    if not (isinstance(s, float) and s == 0.0):
        along = along + ca.DM(DI).T * s
    off = ca.vertcat(along, ca.DM(DI).T * c, ca.DM.zeros(1, K.size))
    diff = G[:, M.tolist()] - G[:, K.tolist()] + off
    d = ca.sqrt(ca.sum1(diff ** 2)).T
    contact += (L / samples) ** 2 * ca.sum1(law.casadi_energy(law.seen(d, ca.DM(scale))))
    energy += k / law.rigidity * contact                          # linear in k
    return CellExpressions(energy, tuple(rows), ca.horzcat(*closest), diff,
                           np.asarray(scale, dtype=float), scales)


def wrap_thinning(shape: Natural3D, law: SoftShell, thinned: bool) -> np.ndarray:
    """Each wrap's thinning a (C3): ``thinned``, the natural loop's, so that it is stress-free
    at rest (the default bent from the natural loop), or 1, the yarn's own law (the default
    for a cell bent from a straight yarn, which is prestressed anyway: as stitch-by-stitch's
    simulation, whose relaxed cell and course sweep this cell then reproduces,
    docs/real_fabric.md, "The source's own cell")."""
    return law.thinning(shape.h0) if thinned else np.ones(len(shape.h0))


def natural_state(shape: Natural3D) -> np.ndarray:
    """The cell's x at the natural loop."""
    return np.concatenate([shape.coeffs, shape.elevation, shape.s_upper, shape.s_lower,
                           [shape.wale_spacing, shape.course_spacing]])


def contact_state(cell: PeriodicCell, x: np.ndarray, rigidity: float | None = None) -> Lagged:
    """The contacts at state x as friction would lag them (``friction.Lagged``, F1, F3): each
    one's normal force a·F(h′, α) (C2, C3) at rigidity k (default: the built law's), its
    material coordinates and the cosine between its tangents. The cell has no friction
    (calibration refuses it); this is what its estimate reads (``scripts/periodic_cell.py
    --friction-estimate``)."""
    k = cell.rigidity if rigidity is None else rigidity
    state = read_crossings(cell.law, np.asarray(cell.closest(x)), cell.shape.crossing_signs(),
                           cell.wrap_scales)
    n = len(cell.shape.s_upper)
    sig = x[-2 - 2 * n:-2]
    return Lagged(np.abs(state["force"]) * k / cell.rigidity, sig[:n].copy(), sig[n:].copy(),
                  state["cosine"])


def pair_state(cell: PeriodicCell, x: np.ndarray, rigidity: float | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The other pairs at state x (R1, C3): each pair's vector between its two samples (3 × P),
    its energy (L/S)²·v(d′)·k/k₀ and the push between the two, minus that energy's derivative
    along the distance, (L/S)²·a·f(d′)·k/k₀ (``SoftShell.force``), at rigidity k (default the
    built law's). What ``scripts/periodic_cell.py --friction-estimate`` reads."""
    k = cell.rigidity if rigidity is None else rigidity
    r = np.asarray(cell.pair_vectors(x))
    d = np.linalg.norm(r, axis=0)
    weight = (cell.shape.length / cell.samples) ** 2 * k / cell.rigidity
    seen = cell.law.seen(d, cell.pair_scales)
    return r, weight * cell.law.energy(seen), weight * cell.pair_scales * cell.law.force(seen)


def solve_cell(cell: PeriodicCell, spacing: float, R_f: float, x0: np.ndarray,
               free: bool = False, rigidity: float | None = None,
               held: bool = False) -> CellSolution:
    """The cell at the pulled ``spacing`` (``free``: both spacings free, the pull's row
    dropped by loose bounds) from x0, with bending modulus R_f and contact rigidity
    ``rigidity`` (default: the built law's); F = dU/d(spacing), the pull row's multiplier.
    ``held``: the spacing across the pull held at its reference value (plane strain, the
    limit of clamps that keep the specimen's width) instead of free (uniaxial stress)."""
    k = cell.rigidity if rigidity is None else rigidity
    lbx, ubx = np.full(x0.size, -np.inf), np.full(x0.size, np.inf)
    sigmas = slice(-2 - 2 * len(cell.shape.s_upper), -2)       # the contacts' σ_u, σ_l
    lbx[sigmas], ubx[sigmas] = 0.0, cell.shape.length
    lbx[-2:] = MIN_SPACING * np.array([cell.natural.wale_spacing, cell.natural.course_spacing])
    if held:
        lbx[cell.across_index] = ubx[cell.across_index] = cell.across0
    lbg, ubg = np.zeros(cell.rows), np.zeros(cell.rows)
    if free:
        lbg[-1], ubg[-1] = -np.inf, np.inf
    sol = cell.solver(x0=x0, p=[spacing, R_f, k], lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    st = cell.solver.stats()
    return CellSolution(np.asarray(sol["x"]).ravel(), float(sol["f"]),
                        -float(sol["lam_g"][-1]), succeeded(st["return_status"]),
                        st["return_status"], int(st["iter_count"]))


def cell_shape(cell: PeriodicCell, x: np.ndarray) -> Natural3D:
    """The loop and lattice of state x as a shape (the check draws its fabric)."""
    sh = cell.shape
    nc, nq = n_coeffs(sh.harmonics), n_coeffs(sh.modes)
    return replace(sh, coeffs=x[:nc], elevation=x[nc:nc + nq], wale_spacing=float(x[-2]),
                   course_spacing=float(x[-1]))


def check_cell(cell: PeriodicCell, x: np.ndarray) -> ProximityReport:
    """The independent all-pairs check of 4 × 4 loops of the periodic fabric at x, the designed
    crossings read on the natural fabric: no pair of pieces inside the hard core, no crossing
    flipped."""
    return natural_check(cell_shape(cell, x), cell.core, reference=cell.natural)


def relaxed(cell: PeriodicCell, x: np.ndarray) -> None:
    """Make state x's lattice the cell's reference (a straight yarn's relaxed cell)."""
    cell.shape = replace(cell.shape, wale_spacing=float(x[-2]), course_spacing=float(x[-1]))
