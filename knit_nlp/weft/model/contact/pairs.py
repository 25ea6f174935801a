"""Contact pairs of an uncrossed fabric state: where two yarn pieces come close, found
without looking at all pairs.

Each course is one yarn, parametrised by its arc length S = (j − 1)·L + s, and sampled every
``h`` (about the radius). A k-d tree over the samples (scipy's cKDTree) gives, for each sample
u, the samples of every course within ``reach`` of it; those of one course form runs (strands
of that yarn near u). On each strand the sample nearest to u and its two polyline segments give
u's foot F on that strand; a foot is kept when the segment u–F crosses no other strand of that
course near u (F is then the nearest point of that yarn to u from u's side). The discrete local
minima of the distance over both yarns' samples are polished by Newton on (S_A, S_B) on the
continuous centrelines: the connecting segment then meets both yarns at right angles, a true
local minimum of the distance between the two centrelines. Near a crossing there is none (the
distance falls to zero at the crossing), nor inside the lens between two crossings (a saddle),
so designed interlocks need no zone here.

The state must be uncrossed (crossings.py checks it): the side of a pair is then where A lies
now, σ = sign((P_A − P_B)·N_B), N_B = (−sin θ_B, cos θ_B) the left normal of B at the foot, and
it stays so (the gap row σ·(P_A − P_B)·N_B ≥ required keeps it). A pair is dropped on the same
piece of yarn; its required gap is min(2r, natural gap) (natural.py, "Thick yarn"), 0 in a
designed box: a natural one, or one around a designed crossing that slid (zones.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from .curves import Curves, basis_at
from .near import TooLarge, estimate, neighbours, tree_of
from .natural import NaturalFabric
from .ranges import expand
from .zones import Zones

NEWTON_STEPS = 25
CROSSING = 1e-9           # relative to L: a polished minimum this close is a crossing
EDGE_STEPS = 40           # bisection steps to a designed box's edge (2^-40 of a sample)
CHUNK = 1 << 15           # samples whose neighbours strand_feet gathers at once, at most ...
ROWS = 1 << 19            # ... and the rows (sample pairs, nodes) a step holds at once
POLISHED = 1 << 16        # points polish moves at once
INTERVAL_NODES = 3        # Gauss nodes per sample interval of course_samples, ...
LOOP_NODES = 128          # ... and at least this many per loop


SAMPLES = 200             # samples per loop of the crossing count, solver's and check's
MAX_SAMPLES = 5000        # ... at most (check --samples)
FEWEST = 16               # the pair search samples each loop at least this often, ...
PER_RADIUS = 1            # ... about this many times per radius in the solver ...
MOST_PAIR_SAMPLES = 1000  # ... and never more often than this, whatever the grid
CHECK_PER_RADIUS = 4      # ... and in check (a finer look than the solver's)


def pair_samples(L: float, radius: float, per_radius: float = PER_RADIUS,
                 most: int = SAMPLES) -> int:
    """Samples per loop of the pair search: ``per_radius`` per radius (the discrete minima
    then lie within a fraction of r of the true ones, which polish finds), at least
    ``FEWEST`` and at most ``most``: the search only proposes candidates, and below L / 200
    a finer grid finds nothing more but costs its square (r = 1e-3 asked for 10,000 samples
    per loop, 4.3 GB on a 4 x 4 fabric; r = 1e-9 for 298 GiB). The solver's grid
    (``solving/contact/rounds.py``) and check's (:func:`check_samples`) both come from here."""
    return int(min(most, max(FEWEST, math.ceil(per_radius * L / radius))))


def check_samples(L: float, radius: float, samples: int = SAMPLES) -> int:
    """Samples per loop of check's gap search at ``samples`` per loop asked: no finer than
    ``CHECK_PER_RADIUS`` per radius (at r = 1.0 the 10 x 10 check at 200 per loop took 150 s:
    80 samples per strand across 4r, each a row of the search). Not coarser: at 2 per radius
    (134 per loop at r = 0.15) the check of a 20 x 20 contact pull missed gaps of 0.75 x 2r
    that 200 per loop finds (the solver's 67 per loop misses them too)."""
    return pair_samples(L, radius, CHECK_PER_RADIUS, samples)


GAP_TOL = 1e-3            # a gap below its requirement·(1 − GAP_TOL) is short: check's verdict
CHECK_REACH = 0.5         # check's gap search: pairs within this many r of their requirement


def checked_pairs(fab: NaturalFabric, curves: Curves, courses: int, wales: int,
                  zones: Zones | None, samples: int = SAMPLES, limit: float | None = None
                  ) -> tuple["Pairs", "Grid"]:
    """The gap search of ``check`` (output/check.py) on a state: pairs within ``CHECK_REACH``·r
    of their requirement, searched at :func:`check_samples` per loop, and that grid. The
    contact rounds judge their answer by the same search (solving/contact/rounds.py, "the
    checker has the last word"), so solver and check share the search, its sampling and
    :func:`short`, as they share the rule (``NaturalFabric``) and the zones."""
    grid = Grid(courses, wales, fab.L, check_samples(fab.L, fab.radius, samples))
    return find_pairs(fab, curves, grid, CHECK_REACH * fab.radius, zones, limit), grid


def short(pairs: "Pairs") -> np.ndarray:
    """Which pairs miss their required gap by more than ``GAP_TOL`` (relative): check's
    violations."""
    return pairs.gap < pairs.required * (1 - GAP_TOL)


@dataclass(frozen=True)
class Grid:
    """The fabric's size and the course-arc sampling (every course sampled at the same S)."""

    courses: int
    wales: int
    L: float
    per_loop: int                 # sample intervals per loop

    @property
    def h(self) -> float:
        return self.L / self.per_loop

    @property
    def S(self) -> np.ndarray:
        """Sample positions along a course, 0..n·L."""
        return np.linspace(0.0, self.wales * self.L, self.wales * self.per_loop + 1)

    def sampled_at(self, per_loop: int) -> "Grid":
        """The same fabric sampled ``per_loop`` times per loop."""
        return self if per_loop == self.per_loop else Grid(self.courses, self.wales, self.L,
                                                           per_loop)

    def loop_of(self, course: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Loop index k and material s of course arc S (the end of a loop is the next loop's
        start; the course's last point is s = L of its last loop)."""
        j = np.clip(np.floor(np.asarray(S) / self.L).astype(int), 0, self.wales - 1)
        return np.asarray(course) * self.wales + j, np.asarray(S) - j * self.L


@dataclass
class Pairs:
    """Contact pairs (one entry each): loops, material points, side, required and current
    signed gap."""

    kA: np.ndarray
    sA: np.ndarray
    kB: np.ndarray
    sB: np.ndarray
    sigma: np.ndarray
    required: np.ndarray
    gap: np.ndarray

    def __len__(self) -> int:
        return len(self.kA)

    @classmethod
    def empty(cls) -> "Pairs":
        z = np.zeros(0)
        return cls(z.astype(int), z, z.astype(int), z, z, z, z)

    def select(self, keep: np.ndarray) -> "Pairs":
        return Pairs(*(getattr(self, f.name)[keep] for f in fields(self)))

    def concat(self, other: "Pairs") -> "Pairs":
        return Pairs.joined([self, other])

    @classmethod
    def joined(cls, parts: list["Pairs"]) -> "Pairs":
        """The pairs of all ``parts``, in order."""
        if not parts:
            return cls.empty()
        return cls(*(np.concatenate([getattr(p, f.name) for p in parts])
                     for f in fields(cls)))


def course_samples(curves: Curves, grid: Grid) -> np.ndarray:
    """Positions (m, samples per course, 2) at ``grid.S``: eq. (1) integrated from each loop's
    start over the sample intervals by Gauss-Legendre, ``INTERVAL_NODES`` nodes per interval
    and at least ``LOOP_NODES`` per loop. Every loop is sampled at the same material points, so
    the tangent angles at all nodes of all loops are one matrix product (coefficients times the
    basis at the shared nodes), in blocks of at most ``ROWS`` nodes: the cell rule of
    :meth:`Curves.points` point by point took 16 s and 1 GB at 100 x 100 with 200 samples per
    loop. The polyline only proposes candidates (pairs are polished on :meth:`Curves.points`,
    crossings are located on it); it differs from the cell rule by about that rule's own error
    (measured 7e-12 at 200 and 16 samples per loop, 4e-10 at 67, L = 10; tested). The last
    state's samples are kept: the pair search and the crossing count ask for the same ones."""
    key = (id(curves), grid)
    if _SAMPLED.get("key") == key and _SAMPLED.get("curves") is curves:
        return _SAMPLED["pts"]
    m, n, p = grid.courses, grid.wales, grid.per_loop
    G = max(INTERVAL_NODES, -(-LOOP_NODES // p))
    x, w = np.polynomial.legendre.leggauss(G)
    s = np.linspace(0.0, grid.L, p + 1)
    h = s[1:] - s[:-1]
    nodes = s[:-1, None] + h[:, None] * (x + 1.0) / 2.0                 # (p, G)
    basis = basis_at(nodes, grid.L, curves.t).reshape(-1, curves.coeffs.shape[1])
    body = np.empty((m * n, p, 2))       # each loop's samples but its end: loop k's rows
    ends = np.empty((m * n, 2))
    rows = max(1, ROWS // (p * G))       # loops per block: bounded temporaries
    for lo in range(0, m * n, rows):
        theta = (curves.coeffs[lo:lo + rows] @ basis.T).reshape(-1, p, G)
        inc = (h / 2.0)[:, None] * np.stack([np.cos(theta) @ w, np.sin(theta) @ w], axis=-1)
        start = curves.starts[lo:lo + rows, None, :]
        block = np.cumsum(inc, axis=1)
        block += start
        body[lo:lo + rows, 0] = start[:, 0]
        body[lo:lo + rows, 1:] = block[:, :-1]
        ends[lo:lo + rows] = block[:, -1]
    pts = np.concatenate([body.reshape(m, n * p, 2), ends.reshape(m, n, 2)[:, -1:]], axis=1)
    _SAMPLED.update(key=key, curves=curves, pts=pts)
    return pts


_SAMPLED: dict = {}          # the last course samples (course_samples)


def frames_at(curves: Curves, grid: Grid, course: np.ndarray, S: np.ndarray):
    """Position, unit tangent, unit left normal and curvature at course arc S."""
    k, s = grid.loop_of(course, S)
    P, T, kappa = curves.frames(k, s)
    return P, T, np.stack([-T[..., 1], T[..., 0]], axis=-1), kappa


def polish(curves: Curves, grid: Grid, ca: np.ndarray, Sa: np.ndarray, cb: np.ndarray,
           Sb: np.ndarray, move_a: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Newton on ½|P_A(S_A) − P_B(S_B)|² from (Sa, Sb) (both, or S_B only: the foot of a fixed
    point), each S kept on its course and within a few samples of its start. Points are
    taken ``POLISHED`` at a time (each point's frames hold some 100 numbers)."""
    Sa, Sb = Sa.astype(float).copy(), Sb.astype(float).copy()
    for lo in range(0, len(Sa), POLISHED):
        part = slice(lo, lo + POLISHED)
        Sa[part], Sb[part] = _polish(curves, grid, ca[part], Sa[part], cb[part], Sb[part],
                                     move_a)
    return Sa, Sb


def _polish(curves, grid, ca, Sa, cb, Sb, move_a: bool) -> tuple[np.ndarray, np.ndarray]:
    """:func:`polish` of one slice of points (Sa, Sb: copies, changed in place)."""
    top, step = grid.wales * grid.L, grid.h
    active = np.arange(len(Sa))
    for _ in range(NEWTON_STEPS):
        if active.size == 0:
            break
        a_c, b_c, a_S, b_S = ca[active], cb[active], Sa[active], Sb[active]
        Pa, Ta, Na, ka = frames_at(curves, grid, a_c, a_S)
        Pb, Tb, Nb, kb = frames_at(curves, grid, b_c, b_S)
        d = Pa - Pb
        ga, gb = np.sum(d * Ta, -1), -np.sum(d * Tb, -1)
        haa = 1.0 + ka * np.sum(d * Na, -1)
        hbb = 1.0 - kb * np.sum(d * Nb, -1)
        if move_a:
            hab = -np.sum(Ta * Tb, -1)
            det = haa * hbb - hab ** 2
            ok = (det > 1e-9) & (haa > 0)
            det = np.where(ok, det, 1.0)
            da = np.where(ok, -(hbb * ga - hab * gb) / det, -ga)
            db = np.where(ok, -(haa * gb - hab * ga) / det, -gb)
        else:
            da = np.zeros_like(a_S)
            ok = hbb > 1e-6
            db = np.where(ok, -gb / np.where(ok, hbb, 1.0), -gb)
        scale = np.minimum(1.0, step / np.maximum(np.hypot(da, db), 1e-300))
        Sa[active] = np.clip(a_S + da * scale, 0.0, top)
        Sb[active] = np.clip(b_S + db * scale, 0.0, top)
        active = active[np.abs(da) + np.abs(db) > 1e-12 * grid.L]
    return Sa, Sb


@dataclass
class Feet:
    """For each (sample u of course cu, strand of course cv near it): the nearest sample v, the
    foot on the polyline (arc Sf), the distance and the polyline's left normal there."""

    cu: np.ndarray
    iu: np.ndarray
    cv: np.ndarray
    iv: np.ndarray
    Sf: np.ndarray
    foot: np.ndarray
    normal: np.ndarray
    dist: np.ndarray


def strand_feet(pts: np.ndarray, grid: Grid, reach: float, exclusion: float, tree=None):
    """Valid feet of every sample on every strand within ``reach`` (see the module notes),
    yielded for slices of at most ``CHUNK`` samples and about ``ROWS`` neighbour rows
    (near.neighbours), in sample order: a sample's feet depend only on its own neighbours, and
    the neighbours and feet of all samples at once (some 100 neighbours each with the
    checker's 200 samples per loop) took more than 9.9 GB on a 100 x 100 fabric."""
    tree = tree_of(pts.reshape(-1, 2)) if tree is None else tree
    for U, V in neighbours(tree, reach, ROWS, CHUNK):
        yield _feet_of(pts, grid, U[U != V], V[U != V], exclusion)


def _feet_of(pts: np.ndarray, grid: Grid, U: np.ndarray, V: np.ndarray,
             exclusion: float) -> Feet:
    """:func:`strand_feet` of the samples U (flat indices) from their neighbours V."""
    m, K = pts.shape[:2]
    cu, iu = np.divmod(U, K)
    cv, iv = np.divmod(V, K)
    S = grid.S
    order = np.argsort(U * (m * K) + V, kind="stable")
    U, V, cu, iu, cv, iv = U[order], V[order], cu[order], iu[order], cv[order], iv[order]
    # the same piece of yarn: never a partner, but it may stand between u and a partner
    excluded = (cu == cv) & (np.abs(S[iu] - S[iv]) <= exclusion)
    dist = np.linalg.norm(pts[cu, iu] - pts[cv, iv], axis=-1)
    new_group = np.r_[True, (U[1:] != U[:-1]) | (cv[1:] != cv[:-1])]
    new_run = new_group | np.r_[True, (iv[1:] != iv[:-1] + 1) | (excluded[1:] != excluded[:-1])]
    run = np.cumsum(new_run) - 1
    group = np.cumsum(new_group) - 1
    # nearest sample of each run
    best = np.lexsort((dist, run))
    first = best[np.r_[True, run[best][1:] != run[best][:-1]]]
    first = first[~excluded[first]]
    fc, fiu, fcv, fiv = cu[first], iu[first], cv[first], iv[first]
    P = pts[fc, fiu]
    foot, tangent, Sf = _polyline_foot(pts, grid, fcv, fiv, P)
    normal = np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
    d = np.linalg.norm(P - foot, axis=1)
    valid = _not_blocked(pts, P, foot, group[first], group, cv, iv, run[first], run)
    return Feet(fc[valid], fiu[valid], fcv[valid], fiv[valid], Sf[valid], foot[valid],
                normal[valid], d[valid])


def _polyline_foot(pts, grid, cv, iv, P):
    """Projection of P on the two polyline segments around sample iv of course cv."""
    K = pts.shape[1]
    best_d = np.full(len(P), np.inf)
    foot, tangent, Sf = np.zeros_like(P), np.zeros_like(P), np.zeros(len(P))
    S = grid.S
    for lo in (iv - 1, iv):
        a = np.clip(lo, 0, K - 2)
        p0, p1 = pts[cv, a], pts[cv, a + 1]
        e = p1 - p0
        ee = np.maximum(np.sum(e * e, 1), 1e-300)
        t = np.clip(np.sum((P - p0) * e, 1) / ee, 0.0, 1.0)
        f = p0 + t[:, None] * e
        d = np.linalg.norm(P - f, axis=1)
        better = d < best_d
        best_d = np.where(better, d, best_d)
        foot[better] = f[better]
        tangent[better] = (e / np.sqrt(ee)[:, None])[better]
        Sf[better] = (S[a] + t * (S[a + 1] - S[a]))[better]
    return foot, tangent, Sf


def _not_blocked(pts, P, foot, fgroup, group, cv, iv, frun, run) -> np.ndarray:
    """Whether the segment P–foot crosses no polyline segment of another run of its group
    (feet taken so that each batch checks at most about ``ROWS`` segments: a group holding
    many strands of one course, a thick yarn's wide reach, checks each foot against all)."""
    starts = np.searchsorted(group, fgroup, side="left")
    ends = np.searchsorted(group, fgroup, side="right")
    blocked = np.zeros(len(P), dtype=bool)
    total = np.concatenate([[0], np.cumsum(ends - starts)])
    lo = 0
    while lo < len(P):
        hi = max(lo + 1, int(np.searchsorted(total, total[lo] + ROWS, side="right")) - 1)
        owner, rows = expand(starts[lo:hi], ends[lo:hi])
        owner += lo
        other = run[rows] != frun[owner]
        owner, rows = owner[other], rows[other]
        a = np.clip(iv[rows], 0, pts.shape[1] - 2)
        for seg in (np.clip(a - 1, 0, pts.shape[1] - 2), a):
            q0, q1 = pts[cv[rows], seg], pts[cv[rows], seg + 1]
            hit = _segments_cross(P[owner], foot[owner], q0, q1)
            blocked[owner[hit]] = True
        lo = hi
    return ~blocked


def _segments_cross(p0, p1, q0, q1) -> np.ndarray:
    """Proper intersection of segments p0p1 and q0q1 (row by row)."""
    def orient(a, b, c):
        return (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    o1, o2 = orient(p0, p1, q0), orient(p0, p1, q1)
    o3, o4 = orient(q0, q1, p0), orient(q0, q1, p1)
    return (o1 * o2 < 0) & (o3 * o4 < 0)


def find_pairs(fab: NaturalFabric, curves: Curves, grid: Grid, reach: float,
               zones: Zones | None = None, limit: float | None = None) -> Pairs:
    """Closest points (polished local minima of the distance) with gap below required +
    ``reach``, on an uncrossed state (``zones``: the designed zones that follow slid
    crossings, zones.py; required gap 0 in them). The samples' feet are taken a chunk at a
    time (:func:`strand_feet`): the same pairs, in the same order, as from all at once (to
    rounding: numpy may round differently on shorter arrays). A search estimated to look at
    more than ``limit`` sample pairs (near.estimate) raises :class:`TooLarge` before it
    starts. The search samples no finer than ``MOST_PAIR_SAMPLES`` per loop, whatever the
    grid (it only proposes candidates; :func:`pair_samples`)."""
    grid = grid.sampled_at(min(grid.per_loop, MOST_PAIR_SAMPLES))
    pts = course_samples(curves, grid)                        # (m, K, 2)
    within = 2 * fab.radius + reach + grid.h
    S = grid.S
    minima, lines, edges = [], [], []
    tree = tree_of(pts.reshape(-1, 2))
    if limit is not None:
        rows = estimate(tree, within)
        if rows > limit:
            raise TooLarge(rows, limit)
    for feet in strand_feet(pts, grid, within, fab.exclusion, tree):
        low = _discrete_minima(pts, feet.cu, feet.iu, feet.cv, feet.iv) & (feet.dist < within)
        minima.append((feet.cu[low], S[feet.iu[low]], feet.cv[low], feet.Sf[low]))
        line, edge = _vertices(fab, curves, grid, feet, reach, zones)
        lines.append(line)
        edges.append(edge)
    if not minima:                                            # no samples at all
        return Pairs.empty()
    closest = _closest(fab, curves, grid, *(np.concatenate(c) for c in zip(*minima)), reach,
                       zones)
    line = Pairs.joined(lines)
    if len(closest) and len(line):
        # drop samples next to a closest-points pair on the same two loops
        line = line.select(~_next_to(line, closest, grid.h / 4))
    return Pairs.joined([closest, line, *edges])


def reseat(fab: NaturalFabric, curves: Curves, grid: Grid,
           pairs: Pairs, zones: Zones | None = None) -> tuple[Pairs, np.ndarray]:
    """The pairs of another state carried to this (uncrossed) one: each A point (material,
    fixed) against its foot on B here, polished from B's old point (as :func:`_vertices` pairs
    a sample with its foot: polishing both points could slide them into a designed crossing),
    with this state's side and gap; pairs that become one piece of yarn, exempt or a crossing
    are dropped. Also which of the given pairs are kept (a mask)."""
    if len(pairs) == 0:
        return Pairs.empty(), np.zeros(0, dtype=bool)
    n = grid.wales
    ca, cb = pairs.kA // n, pairs.kB // n
    Sa, Sb = pairs.kA % n * grid.L + pairs.sA, pairs.kB % n * grid.L + pairs.sB
    _, Sb = polish(curves, grid, ca, Sa, cb, Sb, move_a=False)
    top = grid.wales * grid.L
    inside = (Sb > 1e-9 * grid.L) & (Sb < top - 1e-9 * grid.L)     # a true foot, normal to B
    return _pairs_at(fab, curves, grid, ca, Sa, cb, Sb, where=inside, zones=zones)


def _vertices(fab, curves, grid, feet: Feet, reach: float,
              zones: Zones | None = None) -> tuple[Pairs, Pairs]:
    """Samples of a yarn within reach of a strand, each against its foot (polished): where two
    yarns lie along each other they touch along a line, and one pair per sample holds the
    whole line, not only its closest points. Not in designed interlocks (required gap 0: a
    crossing may slide past a sample there); those within h/4 of a closest-points pair are
    dropped by the caller (:func:`_next_to`). Also the pairs at the edges of designed boxes."""
    S = grid.S
    same, required = _classify(fab, grid, feet.cu, S[feet.iu], feet.cv, feet.Sf, zones)[4:]
    keep = ~same & (required > 0) & (feet.dist < required + reach)
    ca, Sa, cb, Sb = feet.cu[keep], S[feet.iu[keep]], feet.cv[keep], feet.Sf[keep]
    _, Sb = polish(curves, grid, ca, Sa, cb, Sb, move_a=False)
    top = grid.wales * grid.L
    inside = (Sb > 1e-9 * grid.L) & (Sb < top - 1e-9 * grid.L)     # a true foot, normal to B
    out = _pairs_at(fab, curves, grid, ca[inside], Sa[inside], cb[inside], Sb[inside], reach,
                    zones=zones)[0]
    return out, _box_edges(fab, curves, grid, feet, same, required, reach, zones)


def same_loops(old: Pairs, new: Pairs) -> tuple[np.ndarray, np.ndarray]:
    """Every pair of ``new`` against every pair of ``old`` on the same two loops (k_A, k_B):
    the new pairs' indices (ascending) and the old ones', found through the sorted loop keys,
    never all against all."""
    if len(old) == 0 or len(new) == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    big = int(max(old.kB.max(), new.kB.max())) + 1
    ko, kn = old.kA * big + old.kB, new.kA * big + new.kB
    order = np.argsort(ko, kind="stable")
    ko = ko[order]
    owner, rows = expand(np.searchsorted(ko, kn, "left"), np.searchsorted(ko, kn, "right"))
    return owner, order[rows]


def _next_to(out: Pairs, closest: Pairs, tol: float) -> np.ndarray:
    """Which pairs of ``out`` lie within tol (|Δs_A| + |Δs_B|) of a pair of ``closest`` on the
    same two loops (:func:`same_loops`: a scan of all pairs per pair of loops took minutes at
    100 x 100)."""
    owner, rows = same_loops(closest, out)
    d = np.abs(out.sA[owner] - closest.sA[rows]) + np.abs(out.sB[owner] - closest.sB[rows])
    near = np.zeros(len(out), dtype=bool)
    near[owner[d < tol]] = True
    return near


def _pairs_at(fab, curves, grid, ca, Sa, cb, Sb, reach: float = np.inf,
              where: np.ndarray | None = None,
              zones: Zones | None = None) -> tuple[Pairs, np.ndarray]:
    """Pairs of the points (course, arc) (ca, Sa) and (cb, Sb) that must keep a gap (not one
    piece of yarn, not in a designed interlock, not crossing) and lie within ``reach`` of it
    (and in ``where``), with their side and gap; and which of the points made one."""
    kA, sA, kB, sB, same, required = _classify(fab, grid, ca, Sa, cb, Sb, zones)
    normal, dist = _normal_gap(curves, grid, ca, Sa, cb, Sb)
    keep = ~same & (required > 0) & (np.abs(normal) < required + reach) & (
        dist > CROSSING * grid.L)
    if where is not None:
        keep &= where
    return Pairs(kA[keep], sA[keep], kB[keep], sB[keep], np.where(normal < 0, -1.0, 1.0)[keep],
                 required[keep], np.abs(normal)[keep]), keep


def _box_edges(fab, curves, grid, feet: Feet, same: np.ndarray, required: np.ndarray,
               reach: float, zones: Zones | None = None) -> Pairs:
    """Pairs at the edges of designed interlock boxes: where a yarn leaves a box its required
    gap jumps from 0 to 2r while the distance is still near its minimum, so the closest
    outside point is the edge itself, between two samples (a 6 x 6 diagonal pull kept every
    sample pair at 2r while the checker, sampling finer, found 0.68 x 2r there). For every two
    consecutive samples of a yarn, one in a box and one out (each against its foot on the
    same strand), the edge is bisected along the yarn, the foot following it, and the first
    point out is paired with its foot (``same``, ``required``: the feet's classification)."""
    S = grid.S
    inside = ~same & (required <= 0)
    outside = ~same & (required > 0) & (feet.dist < 2 * fab.radius + reach + grid.h)
    key = (feet.cu * (grid.wales * grid.per_loop + 1) + feet.iu) * (grid.courses + 1) + feet.cv
    out_at = {k: i for i, k in zip(np.nonzero(outside)[0].tolist(), key[outside].tolist())}
    lo, hi = [], []
    step = (grid.courses + 1)
    for i, k in zip(np.nonzero(inside)[0].tolist(), key[inside].tolist()):
        for j in (out_at.get(k - step), out_at.get(k + step)):
            if j is not None and feet.cu[j] == feet.cu[i] and \
                    abs(feet.Sf[j] - feet.Sf[i]) < 4 * grid.h:          # same yarn, same strand
                lo.append(i)
                hi.append(j)
    if not lo:
        return Pairs.empty()
    lo, hi = np.array(lo), np.array(hi)
    ca, cb = feet.cu[lo], feet.cv[lo]
    a_in, a_out, Sb = S[feet.iu[lo]], S[feet.iu[hi]], feet.Sf[hi].astype(float)
    Sb_out = Sb.copy()
    for _ in range(EDGE_STEPS):
        mid = 0.5 * (a_in + a_out)
        _, Sb = polish(curves, grid, ca, mid, cb, Sb, move_a=False)
        req = _classify(fab, grid, ca, mid, cb, Sb, zones)[5]
        out = req > 0
        a_out, Sb_out = np.where(out, mid, a_out), np.where(out, Sb, Sb_out)
        a_in = np.where(out, a_in, mid)
    return _pairs_at(fab, curves, grid, ca, a_out, cb, Sb_out, reach, zones=zones)[0]


def _discrete_minima(pts: np.ndarray, ca, ia, cb, ib) -> np.ndarray:
    """Sample pairs whose distance is not above any of its 8 neighbours' on the two courses."""
    K = pts.shape[1]
    d0 = np.linalg.norm(pts[ca, ia] - pts[cb, ib], axis=-1)
    keep = np.ones(d0.shape, dtype=bool)
    for da in (-1, 0, 1):
        for db in (-1, 0, 1):
            if da == db == 0:
                continue
            ja, jb = ia + da, ib + db
            inside = (ja >= 0) & (ja < K) & (jb >= 0) & (jb < K)
            ja, jb = np.clip(ja, 0, K - 1), np.clip(jb, 0, K - 1)
            d = np.linalg.norm(pts[ca, ja] - pts[cb, jb], axis=-1)
            keep &= ~inside | (d0 <= d)
    return keep


def _classify(fab: NaturalFabric, grid: Grid, ca, Sa, cb, Sb, zones: Zones | None = None):
    """Loops, material points, whether the pair is one piece of yarn, required gap (0 in
    a natural designed box or, given ``zones``, around a slid designed crossing)."""
    kA, sA = grid.loop_of(ca, Sa)
    kB, sB = grid.loop_of(cb, Sb)
    di = kB // grid.wales - kA // grid.wales
    dj = kB % grid.wales - kA % grid.wales
    same, required = fab.lookup(di, dj, sA, sB)
    same |= (ca == cb) & (np.abs(Sa - Sb) <= fab.exclusion)
    if zones is not None:
        required = np.where(zones.exempt(ca, Sa, cb, Sb), 0.0, required)
    return kA, sA, kB, sB, same, required


def _normal_gap(curves, grid, ca, Sa, cb, Sb):
    """(P_A − P_B)·N_B and |P_A − P_B|."""
    Pa = frames_at(curves, grid, ca, Sa)[0]
    Pb, _, Nb, _ = frames_at(curves, grid, cb, Sb)
    return np.sum((Pa - Pb) * Nb, -1), np.linalg.norm(Pa - Pb, axis=-1)


def _closest(fab, curves, grid, ca, Sa, cb, Sb, reach, zones: Zones | None = None) -> Pairs:
    """Polished local minima of the distance, deduplicated, non-exempt, within reach."""
    Sa, Sb = polish(curves, grid, ca, Sa, cb, Sb)
    key = np.stack([ca, cb, np.rint(Sa / (1e-6 * grid.L)), np.rint(Sb / (1e-6 * grid.L))], 1)
    _, first = np.unique(key, axis=0, return_index=True)
    # each minimum is found from both yarns: keep it once, course pair in increasing order
    ca, Sa, cb, Sb = ca[first], Sa[first], cb[first], Sb[first]
    swap = (ca > cb) | ((ca == cb) & (Sa > Sb))
    ca, cb = np.where(swap, cb, ca), np.where(swap, ca, cb)
    Sa, Sb = np.where(swap, Sb, Sa), np.where(swap, Sa, Sb)
    key = np.stack([ca, cb, np.rint(Sa / (1e-6 * grid.L)), np.rint(Sb / (1e-6 * grid.L))], 1)
    _, first = np.unique(key, axis=0, return_index=True)
    ca, Sa, cb, Sb = ca[first], Sa[first], cb[first], Sb[first]
    # the gap is measured along B's normal: B's point must not be a yarn end (there the
    # distance is not normal to B); with A's point at an end it is (a yarn end against a yarn)
    top = grid.wales * grid.L
    end_a = (Sa <= 1e-9 * grid.L) | (Sa >= top - 1e-9 * grid.L)
    end_b = (Sb <= 1e-9 * grid.L) | (Sb >= top - 1e-9 * grid.L)
    swap = end_b & ~end_a
    ca, cb = np.where(swap, cb, ca), np.where(swap, ca, cb)
    Sa, Sb = np.where(swap, Sb, Sa), np.where(swap, Sa, Sb)
    both_ends = end_a & end_b
    kA, sA, kB, sB, same, required = _classify(fab, grid, ca, Sa, cb, Sb, zones)
    same |= both_ends
    normal, dist = _normal_gap(curves, grid, ca, Sa, cb, Sb)
    crossing = dist < CROSSING * grid.L
    sigma = np.where(normal < 0, -1.0, 1.0)
    gap = np.abs(normal)
    keep = ~same & ~crossing & (gap < required + reach)
    return Pairs(kA[keep], sA[keep], kB[keep], sB[keep], sigma[keep], required[keep],
                 gap[keep])
