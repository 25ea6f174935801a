"""The construction of the natural 3-D loop (docs/weft3d.md, "Natural 3-D shape", N1-N5).

The natural loop is the solution of one small NLP (IPOPT) per (loop, q, r, R_c), memoised:

* **Unknowns**: the loop's θ and φ coefficients, the lattice (w, c), the two interlock contacts'
  material points (σ_u, σ_l) and the four designed crossings' points in projection.
* **Objective** (N1): the projection's mean squared distance from the paper's natural loop
  plus ``SMOOTH``·L·∫φ′² ds.
* **Rows**: the loop closes on the lattice (x(L) − x(0) = (w, 0, 0)); θ, θ′, φ, φ′ periodic
  (N2); at each of plain knit's four designed crossings (A/D, C/F, Q/G, S/P) the projections
  cross and the upper yarn lies on the side of the plain-knit order (N3); each of the two
  interlock contacts (left: A/D with C/F, right: Q/G with S/P) is a pair of closest points
  (N4); and every pair of sample points of non-neighbouring pieces of yarn (other wales,
  courses up to two apart, the loop itself beyond π·r along the yarn) is at least
  g = 2R_c + ``MARGIN``·(2r − 2R_c) apart (N5), the interlock contacts included.

**Why two contacts, not four.** The upper yarn passes under the lower loop's leg (A/D) and
over its head (C/F) within about 3 mm of both yarns: in three dimensions the two crossings of
the projections are one place where the yarns come closest, the upper yarn wrapping the
lower one. A pair of closest points at each crossing of the projections (the first 3-D
model) sat on saddle points of the distance while the yarns passed through each other between
them (0.028 mm apart for the acrylic). The wrap's closest points are a true minimum.

**Start.** For a thick yarn (2r ≥ ``THIN``·c) the paper's projection does not admit N5 at the
paper's lattice (the lenses between A/D and C/F are thinner than the core); the NLP starts from
a parametric stitch of the classical form x = w/(2π)(τ + 1.5 sin 2τ), y = β(1 − cos τ),
z = −γ cos 2τ, scaled to the loop length and fitted in the loop functions by least squares.
A thin yarn starts from the paper's loop with its legs lifted; either start is tried when the
other fails.
"""
from __future__ import annotations

import functools

import casadi as ca
import numpy as np

from ..basis import continuity_rows, dphi, n_coeffs, phi
from ..crossing_points import Crossings
from ..natural_loop import NaturalLoop
from .curve3d import loop_displacements3d, positions3d, segment
from .natural3d import PAIRS, Natural3D, NaturalShapeError, WRAPS
from .proximity import Courses, check_3d, natural_lines, reference_crossings

SAMPLES = 41          # projection least-squares samples along the loop (N1)
GAP_SAMPLES = 48      # sample points per loop of the distance rows (N5)
GAUSS = 48            # nodes of the Gauss rule on [0, σ]
SMOOTH = 1e-3         # weight of ∫φ′² ds against the projection's mean squared distance
ROUNDS = 4            # solves adding the fine samples' pairs found close (N5)
MARGIN = 0.1          # g = 2R_c + MARGIN (2r − 2R_c): the natural fabric's smallest distance
# the parametric start (x = w/2π (τ + α sin 2τ), y = β(1 − cos τ), z = −γ cos 2τ), per unit
# of its own length: measured clean (all pairs at least 0.72 mm) for the acrylic
START = {"alpha": 1.5, "beta": 1.6, "gamma": 0.65, "w": 3.2, "c": 1.9}
THIN = 0.5            # 2r below THIN·c (the paper's course spacing): the paper's loop is tried first
OFFSETS = tuple((di, dj) for di in (0, 1, 2) for dj in range(-2, 3) if di > 0 or dj >= 0)


def natural_3d(natural: NaturalLoop, crossings: Crossings, modes: int, radius: float,
               core: float) -> Natural3D:
    """The natural 3-D loop of a planar natural loop (module docstring), memoised: the four
    touching crossings on the paper's lattice (``touching``) when the independent check calls
    that fabric clean, else the two wraps (``_solve``)."""
    args = (natural.coeffs.tobytes(), natural.length, natural.harmonics, modes, float(radius))
    lattice = (natural.wale_spacing, natural.course_spacing)
    try:
        shape = touching(*args, *lattice, tuple(float(crossings.s[u]) for u, _, _ in PAIRS),
                         tuple(float(crossings.s[lo]) for _, lo, _ in PAIRS))
        if _clean(shape, core):
            return shape
    except NaturalShapeError:
        pass
    return _solve(*args, float(core), *lattice)


@functools.lru_cache(maxsize=32)
def touching(coeffs: bytes, L: float, t: int, q: int, r: float, w: float, c: float,
             su0: tuple[float, ...], sl0: tuple[float, ...]) -> Natural3D:
    """The natural loop of thin yarns (T1-T3): the projection as near as it can be to the
    paper's (N1) on the paper's lattice (w, c); loops join (N2); at each of the four designed
    crossings of the projections (PAIRS) a pair of closest points 2r apart, the upper yarn on
    the plain-knit side (T1-T3, the contacts: four per loop, h₀ = 2r). For a thick yarn the
    two closest-point pairs of one side are saddle points of the distance between two crossings
    of one lens, and the yarns pass through each other between them: the check refuses it and
    ``natural_3d`` builds the wraps instead."""
    a_plan = np.frombuffer(coeffs).copy()
    nc, nq = n_coeffs(t), n_coeffs(q)
    a, b = ca.SX.sym("a", nc), ca.SX.sym("b", nq)
    su, sl = ca.SX.sym("su", 4), ca.SX.sym("sl", 4)
    seg = segment(L, t, q, GAUSS)
    s = np.linspace(0.0, L, SAMPLES)
    target = positions3d(a_plan, np.zeros(nq), s, L, t, q)
    misfit = sum(ca.sumsqr(seg(a, b, 0.0, s[k])[0][:2] - ca.DM(target[k, :2]))
                 for k in range(1, SAMPLES))
    rows, lo, hi = [], [], []
    end = seg(a, b, 0.0, L)[0]
    rows += [end[0] - w, end[1], end[2]]
    lo += [0.0] * 3
    hi += [0.0] * 3
    shift = ca.DM([0.0, c, 0.0])
    for k, (_, _, order) in enumerate(PAIRS):
        pu, tu = seg(a, b, 0.0, su[k])
        pl, tl = seg(a, b, 0.0, sl[k])
        d = pu + shift - pl
        rows += [ca.dot(d, tu), ca.dot(d, tl), ca.dot(d, d) - 4 * r * r, order * d[2]]
        lo += [0.0, 0.0, 0.0, 0.0]
        hi += [0.0, 0.0, 0.0, ca.inf]
    for deg, coef in ((q, b), (t, a)):
        E, S = continuity_rows(L, deg)
        rows += list(ca.vertsplit(ca.mtimes(ca.DM(E - S), coef)))
        lo += [0.0] * 2
        hi += [0.0] * 2
    solver = ca.nlpsol("natural3d_touching", "ipopt",
                       {"x": ca.vertcat(a, b, su, sl), "g": ca.vertcat(*rows),
                        "f": misfit / (SAMPLES - 1) + _smoothness(b, L, q)},
                       {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes",
                                                       "tol": 1e-12, "max_iter": 500}})
    big = np.full(nc + nq, np.inf)
    sol = solver(x0=np.concatenate([a_plan, _lifted_legs(L, q, r), su0, sl0]), lbg=lo, ubg=hi,
                 lbx=np.concatenate([-big, np.zeros(8)]), ubx=np.concatenate([big, np.full(8, L)]))
    if not solver.stats()["success"]:
        raise NaturalShapeError(f"no natural 3-D loop with touching crossings for radius {r:g} "
                                f"and {q} elevation modes (IPOPT: {solver.stats()['return_status']})")
    xs = np.asarray(sol["x"]).ravel()
    a3, b3, su3, sl3 = xs[:nc], xs[nc:nc + nq], xs[nc + nq:nc + nq + 4], xs[nc + nq + 4:]
    rms = _projection_rms(a3, b3, s, target[:, :2], L, t, q)
    return _shape(L, t, q, r, a3, b3, (su3, sl3), (su3, sl3), w, c, rms)


def gap(radius: float, core: float) -> float:
    """The natural fabric's smallest distance between non-neighbouring pieces (N5)."""
    return 2 * core + MARGIN * (2 * radius - 2 * core)


def _lifted_legs(L: float, q: int, r: float) -> np.ndarray:
    """φ coefficients of the paper's loop lifted for a start: legs in front, head and foot
    behind, z ≈ −α cos(4πs/L)."""
    b = np.zeros(n_coeffs(q))
    if q >= 2:
        b[1] = 4 * np.pi * (2 * r / 1.77) / L
    return b


def _smoothness(b: ca.SX | ca.MX, L: float, q: int):
    """``SMOOTH``·L·∫φ′² ds of N1 (200 nodes)."""
    nodes = np.linspace(0.0, L, 200)
    return SMOOTH * L * (ca.sumsqr(ca.mtimes(ca.DM(dphi(nodes, L, q)), b)) * (L / nodes.size))


def _projection_rms(a: np.ndarray, b: np.ndarray, s: np.ndarray, target: np.ndarray, L: float,
                    t: int, q: int) -> float:
    """RMS distance of the loop's projection at s from the paper's loop there (``target``)."""
    proj = positions3d(a, b, s, L, t, q)[:, :2]
    return float(np.sqrt(np.mean(np.sum((proj - target) ** 2, axis=1))))


def parametric_start(L: float, t: int, q: int) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(θ coefficients, φ coefficients, w, c) of the parametric stitch scaled to length L."""
    tau = np.linspace(0.0, 2 * np.pi, 4001)
    X = np.stack([START["w"] / (2 * np.pi) * (tau + START["alpha"] * np.sin(2 * tau)),
                  START["beta"] * (1 - np.cos(tau)), -START["gamma"] * np.cos(2 * tau)], 1)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(X, axis=0), axis=1))])
    scale = L / s[-1]
    X, s = X * scale, s * scale
    T = np.gradient(X, s, axis=0)
    T /= np.linalg.norm(T, axis=1)[:, None]
    theta = np.unwrap(np.arctan2(T[:, 1], T[:, 0]))
    elev = np.arcsin(np.clip(T[:, 2], -1.0, 1.0))
    a = np.linalg.lstsq(phi(s, L, t), theta, rcond=None)[0]
    b = np.linalg.lstsq(phi(s, L, q), elev, rcond=None)[0]
    return a, b, START["w"] * scale, START["c"] * scale


def _closest(shape: Natural3D, su: float, sl: float, span: float) -> tuple[float, float]:
    """The closest sampled points of the upper loop near su and the lower loop near sl."""
    L = shape.length
    u = np.clip(np.linspace(su - span, su + span, 121), 0.0, L)
    v = np.clip(np.linspace(sl - span, sl + span, 121), 0.0, L)
    pu = shape.xyz(u) + [0.0, shape.course_spacing, 0.0]
    d = np.linalg.norm(pu[:, None] - shape.xyz(v)[None], axis=2)
    i, j = np.unravel_index(np.argmin(d), d.shape)
    return float(u[i]), float(v[j])


def _shape(L, t, q, r, a, b, wraps, cross, w, c, rms=0.0) -> Natural3D:
    su, sl = wraps
    up = positions3d(a, b, su, L, t, q) + [0.0, c, 0.0]
    h0 = np.linalg.norm(up - positions3d(a, b, sl, L, t, q), axis=1)
    return Natural3D(L, t, q, r, np.asarray(a), np.asarray(b), np.asarray(su), np.asarray(sl),
                     h0, np.asarray(cross[0]), np.asarray(cross[1]),
                     np.array([o for *_, o in PAIRS], dtype=float), float(w), float(c), rms)


def _gap_pairs(X0: np.ndarray, s: np.ndarray, w: float, c: float, L: float, r: float,
               reach: float) -> tuple[np.ndarray, ...]:
    """Sample pairs (k on the loop, l on the loop at lattice offset (di, dj)) of N5 that are
    within ``reach`` in the start, other than one piece of yarn (π·r along one course)."""
    K, M, DI, DJ = [], [], [], []
    for di, dj in OFFSETS:
        d = np.linalg.norm(X0[None, :, :] + [dj * w, di * c, 0.0] - X0[:, None, :], axis=2)
        keep = d < reach
        if di == 0:
            along = np.abs(dj * L + s[None, :] - s[:, None])
            keep &= along > np.pi * r
            if dj == 0:
                keep &= np.triu(np.ones_like(keep), 1).astype(bool)
        k, m = np.nonzero(keep)
        K += [k]
        M += [m]
        DI += [np.full(k.size, di)]
        DJ += [np.full(k.size, dj)]
    return tuple(np.concatenate(v) for v in (K, M, DI, DJ))


@functools.lru_cache(maxsize=32)
def _solve(coeffs: bytes, L: float, t: int, q: int, r: float, core: float, w: float,
           c: float) -> Natural3D:
    a_plan = np.frombuffer(coeffs).copy()
    target = positions3d(a_plan, np.zeros(n_coeffs(q)), np.linspace(0.0, L, SAMPLES)[1:], L,
                         t, q)[:, :2]
    g = gap(r, core)
    starts = [parametric_start(L, t, q), (a_plan, _lifted_legs(L, q, r), w, c)]
    if 2 * r < THIN * c:             # a thin yarn: the paper's loop first
        starts.reverse()
    errors = []
    for start in starts:
        try:
            return _rounds(L, t, q, r, core, g, target, *start)
        except NaturalShapeError as err:
            errors.append(str(err))
    raise NaturalShapeError("; ".join(dict.fromkeys(errors)))


def _rounds(L: float, t: int, q: int, r: float, core: float, g: float, target: np.ndarray,
            a0: np.ndarray, b0: np.ndarray, w0: float, c0: float) -> Natural3D:
    """The construction from one start (θ, φ coefficients, lattice): N5's coarse rows, then
    the rounds adding the fine sampling's close pairs (module docstring)."""
    start = _shape(L, t, q, r, a0, b0, (np.zeros(2), np.zeros(2)), (np.zeros(4), np.zeros(4)),
                   w0, c0)
    try:
        cu0, cl0 = reference_crossings(Courses.of(natural_lines(start, 3, 241), L))
    except ValueError as err:
        raise NaturalShapeError(f"a start does not interlock ({err})") from None
    wraps0 = np.array([_closest(start, 0.5 * (cu0[i] + cu0[i + 1]), 0.5 * (cl0[i] + cl0[i + 1]),
                                0.15 * L) for i in (0, 2)]).T
    x = np.concatenate([a0, b0, *wraps0, cu0, cl0, [w0, c0]])
    coarse = (np.arange(GAP_SAMPLES) + 0.5) * L / GAP_SAMPLES
    groups = [(coarse, *_gap_pairs(positions3d(a0, b0, coarse, L, t, q), coarse, w0, c0, L, r,
                                   g + L / 4))]
    fine_n = max(GAP_SAMPLES, int(np.ceil(3 * L / g)))
    fine = (np.arange(fine_n) + 0.5) * L / fine_n
    kept: set[tuple[int, int, int, int]] = set()
    for _ in range(ROUNDS):
        x = _fit(L, t, q, r, g, target, groups, x)
        shape = _unpack(L, t, q, r, x, target)
        found = _gap_pairs(shape.xyz(fine), fine, shape.wale_spacing, shape.course_spacing, L, r,
                           g + 3 * L / fine_n)
        new = set(zip(*(v.tolist() for v in found))) - kept
        if not new and _clean(shape, core):
            return shape
        kept |= new
        groups = groups[:1] + [(fine, *(np.array(v) for v in zip(*sorted(kept))))]
    _verify(shape, core)
    return shape


def _fit(L: float, t: int, q: int, r: float, g: float, target: np.ndarray,
         groups: list[tuple[np.ndarray, ...]], x0: np.ndarray) -> np.ndarray:
    """One solve of the construction's NLP (module docstring) from x0, with the distance rows
    (N5) of the sample-pair ``groups``."""
    nc, nq = n_coeffs(t), n_coeffs(q)
    xs = ca.MX.sym("x", nc + nq + 14)
    a, b = xs[:nc], xs[nc:nc + nq]
    su, sl, xu, xl = (xs[nc + nq + o:nc + nq + o + n] for o, n in ((0, 2), (2, 2), (4, 4), (8, 4)))
    w, c = xs[-2], xs[-1]
    seg = segment(L, t, q, GAUSS)
    D = loop_displacements3d(L, t, q, np.linspace(0.0, L, SAMPLES)[1:], 8)(a, b)
    misfit = ca.sumsqr(D[:2, :].T - ca.DM(target)) / (SAMPLES - 1)
    rows, lo, hi = [], [], []

    def add(expr, lower, upper):
        rows.append(expr)
        lo.extend([lower] * expr.numel())
        hi.extend([upper] * expr.numel())
    end = seg(a, b, 0.0, L)[0]
    add(end - ca.vertcat(w, 0, 0), 0.0, 0.0)                                        # closure
    for deg, coef in ((q, b), (t, a)):                                              # N2
        E, S = continuity_rows(L, deg)
        add(ca.mtimes(ca.DM(E - S), coef), 0.0, 0.0)
    shift = ca.vertcat(0, c, 0)
    for k, (_, _, order) in enumerate(PAIRS):                                       # N3
        d = seg(a, b, 0.0, xu[k])[0] + shift - seg(a, b, 0.0, xl[k])[0]
        add(d[:2], 0.0, 0.0)
        add(order * d[2], 0.5 * g, ca.inf)
    for k in range(len(WRAPS)):                                                     # N4
        pu, tu = seg(a, b, 0.0, su[k])
        pl, tl = seg(a, b, 0.0, sl[k])
        d = pu + shift - pl
        add(ca.vertcat(ca.dot(d, tu), ca.dot(d, tl)), 0.0, 0.0)
        add(ca.dot(d, d), g * g, ca.inf)
    for sg, K, M, DI, DJ in groups:                                                 # N5
        G = loop_displacements3d(L, t, q, sg, 8)(a, b)
        off = ca.vertcat(ca.DM(DJ).T * w, ca.DM(DI).T * c, ca.DM.zeros(1, K.size))
        diff = ca.mtimes(G, ca.DM(_selector(M, sg.size) - _selector(K, sg.size))) + off
        add(ca.sum1(diff ** 2).T, g * g, ca.inf)
    solver = ca.nlpsol("natural3d", "ipopt",
                       {"x": xs, "f": misfit + _smoothness(b, L, q), "g": ca.vertcat(*rows)},
                       {"print_time": False, "ipopt": {
                           "print_level": 0, "sb": "yes", "tol": 1e-9, "max_iter": 1000}})
    free = np.full(nc + nq, np.inf)
    w0, c0 = x0[-2:]
    sol = solver(x0=x0, lbg=lo, ubg=hi,
                 lbx=np.concatenate([-free, np.zeros(12), [0.5 * w0, 0.5 * c0]]),
                 ubx=np.concatenate([free, np.full(12, L), [2.0 * w0, 2.0 * c0]]))
    stats = solver.stats()
    if not stats["success"]:
        raise NaturalShapeError(f"no natural 3-D loop keeps non-neighbouring yarn {g:g} apart "
                                f"for radius {r:g} and {q} elevation modes "
                                f"(IPOPT: {stats['return_status']})")
    return np.asarray(sol["x"]).ravel()


def _selector(idx: np.ndarray, n: int):
    """The sparse n × len(idx) matrix whose column j picks sample idx[j]."""
    from scipy.sparse import csc_matrix   # lazily: the CLI starts without SciPy
    m = csc_matrix((np.ones(idx.size), (idx, np.arange(idx.size))), shape=(n, idx.size))
    return ca.DM(ca.Sparsity(n, idx.size, m.indptr.tolist(), m.indices.tolist()), m.data.tolist())


def _unpack(L: float, t: int, q: int, r: float, x: np.ndarray, target: np.ndarray
            ) -> Natural3D:
    nc, nq = n_coeffs(t), n_coeffs(q)
    a, b, o = x[:nc], x[nc:nc + nq], nc + nq
    rms = _projection_rms(a, b, np.linspace(0.0, L, SAMPLES)[1:], target, L, t, q)
    return _shape(L, t, q, r, a, b, (x[o:o + 2], x[o + 2:o + 4]), (x[o + 4:o + 8], x[o + 8:o + 12]),
                  x[-2], x[-1], rms)


def _clean(shape: Natural3D, core: float) -> bool:
    return natural_check(shape, core).ok


def natural_check(shape: Natural3D, core: float, reference: Natural3D | None = None):
    """The independent all-pairs check (``proximity.check_3d``) of four courses of four
    loops of ``shape`` on its lattice, sampled as the check samples (4 per radius, at least 241
    per loop), the designed crossings read on ``reference``'s (default: ``shape``'s own)."""
    S = max(241, int(np.ceil(4 * shape.length / shape.radius)))
    lines = shape.xyz(np.linspace(0.0, shape.length, S))[None, None] + \
        shape.starts(4, 4)[:, :, None, :]
    return check_3d(lines, natural_lines(reference or shape, 4, S), shape.length, shape.radius,
                    core)


def _verify(shape: Natural3D, core: float) -> None:
    """Refuse a natural fabric the independent check does not call clean."""
    rep = natural_check(shape, core)
    if not rep.ok:
        raise NaturalShapeError(f"the natural 3-D fabric is not clean: {rep.verdict()}")
