"""Crossings of the projected centrelines, counted per pair of loops and compared with the
natural fabric's.

Every course is sampled as a polyline (:func:`crossing_samples` segments per loop, 200 unless a
check asks for more, the same for the solver and ``check``); segment pairs come from a k-d tree
over segment midpoints (two segments can only meet if their midpoints are within one segment
length), or from a cell list where the crossings' order does not show (near.cell_pairs), never
from all pairs, and a bounded number at a time (near.close_pairs). Two segments
cross when their parameters both lie in [0, 1) (half-open, so a crossing at a shared sample is
counted once); neighbouring segments of one course share a sample and are skipped. A crossing
is located on both yarns by its loops and material points. A pair of loops crossing more often
than the same two loops of the natural fabric (``NaturalFabric.crossings`` of their offset: 4
for vertically neighbouring jersey loops, 0 otherwise) has new crossings: yarns that passed
through each other.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .curves import Curves
from .natural import NaturalFabric
from .ranges import expand
from .zones import Zones, half_width
from .near import cell_pairs, close_pairs
from .pairs import MAX_SAMPLES, ROWS, SAMPLES, Grid, course_samples


@dataclass
class Crossings:
    """All crossings of a state: loops (k_A < k_B, or equal), material points, position."""

    kA: np.ndarray
    sA: np.ndarray
    kB: np.ndarray
    sB: np.ndarray
    xy: np.ndarray
    _counts: dict[tuple[int, int], int] | None = field(default=None, repr=False, compare=False)
    _pairs: tuple[np.ndarray, np.ndarray, np.ndarray] | None = field(default=None, repr=False,
                                                                     compare=False)

    def __len__(self) -> int:
        return len(self.kA)

    def counts(self) -> dict[tuple[int, int], int]:
        """Crossings per pair of loops, {(k_A, k_B): count} in the order of the pairs."""
        if self._counts is None:
            a, b, n = self.pair_counts()
            self._counts = dict(zip(zip(a.tolist(), b.tolist()), n.tolist()))
        return self._counts

    def pair_counts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Crossings per pair of loops as arrays k_A, k_B, count, sorted by (k_A, k_B);
        counted once (the judge and the check's report both ask): one key per pair of loops
        and a 1-D unique (a row-wise unique and a dict built from numpy scalars took 0.8 s
        of a 100 x 100 check; the judge reads these arrays, not the dict)."""
        if self._pairs is None:
            if len(self.kA) == 0:
                z = np.zeros(0, dtype=np.int64)
                self._pairs = z, z, z
            else:
                big = int(max(self.kA.max(), self.kB.max())) + 1
                keys, n = np.unique(self.kA.astype(np.int64) * big + self.kB,
                                    return_counts=True)
                a, b = np.divmod(keys, big)
                self._pairs = a, b, n.astype(np.int64)
        return self._pairs


def find_crossings(curves: Curves, grid: Grid, ordered: bool = True) -> Crossings:
    """Every crossing of two pieces of yarn (different loops, or one course with itself),
    counted on polylines of :func:`crossing_samples` segments per loop; ``ordered``: in the
    k-d tree's order (near.close_pairs), which ``knit-nlp check`` lists each pair of loops'
    crossing points in, else in the cell list's (near.cell_pairs: the same crossings, found
    with less work and without SciPy, for callers that only count them)."""
    grid = grid.sampled_at(crossing_samples(grid.per_loop))
    pts = course_samples(curves, grid)                       # (m, K, 2)
    m, K = pts.shape[:2]
    if m * (K - 1) == 0:
        return _empty()
    points = pts.reshape(-1, 2)     # segment u starts at row u + u // (K − 1): no copy of p0
    d = pts[:, 1:] - pts[:, :-1]
    mid = d * 0.5                   # the midpoints p0 + d / 2 in one array (halving is exact)
    mid += pts[:, :-1]
    d, mid = d.reshape(-1, 2), mid.reshape(-1, 2)
    search = close_pairs if ordered else cell_pairs
    parts = [_crossing_segments(points, d, K, uv)
             for uv in search(mid, _longest(d) + 1e-12, ROWS)]
    parts = [p for p in parts if len(p[0])]
    if not parts:
        return _empty()
    u, v, tu, tv = (np.concatenate(c) for c in zip(*parts))
    cu, iu = np.divmod(u, K - 1)
    cv, iv = np.divmod(v, K - 1)
    S = grid.S
    h = S[1] - S[0]
    Su, Sv = S[iu] + tu * h, S[iv] + tv * h
    kA, sA = grid.loop_of(cu, Su)
    kB, sB = grid.loop_of(cv, Sv)
    swap = (kA > kB) | ((kA == kB) & (sA > sB))
    xy = points[u + cu] + tu[:, None] * d[u]
    return Crossings(np.where(swap, kB, kA), np.where(swap, sB, sA), np.where(swap, kA, kB),
                     np.where(swap, sA, sB), xy)


def _longest(d: np.ndarray) -> float:
    """The longest of the segments ``d`` (rows x, y), its lengths taken a block at a time
    (hypot: a third of norm's time on 2 million segments; no array of them all)."""
    return max(float(np.hypot(d[lo:lo + ROWS, 0], d[lo:lo + ROWS, 1]).max())
               for lo in range(0, len(d), ROWS))


def crossing_samples(per_loop: int) -> int:
    """Segments per loop of the crossing count: ``SAMPLES`` (200), or more when a grid asks
    for more (``check --samples``), at most ``MAX_SAMPLES``. The solver's grids (about one
    sample per radius) and check's default count on the same polylines, so that both count
    the same crossings: a designed crossing is one thing to both (on a 20 x 20 pull at
    r = 0.15 the solver, counting at 67 per loop, found 79 lost where check found 77; on a
    6 x 6 stretch at r = 0.656, 16 per loop, it missed 8 new crossings)."""
    return int(min(MAX_SAMPLES, max(SAMPLES, per_loop)))


def _crossing_segments(points: np.ndarray, d: np.ndarray, K: int, uv: np.ndarray):
    """Of candidate segment pairs (u < v), those that cross: u, v and the parameters on both
    (half-open [0, 1), so a crossing at a shared sample is counted once; neighbouring segments
    of one course share a sample and are skipped). ``points``: the courses' samples, K a
    course, one after the other (segment u starts at row u + u // (K − 1))."""
    u, v = uv[:, 0], uv[:, 1]
    # v = u + 1: the next segment, unless u ends its course (v starts the next one)
    apart = (v - u != 1) | (v % (K - 1) == 0)
    u, v = u[apart], v[apart]
    return segments_crossing(points, d, u, v, u + u // (K - 1), v + v // (K - 1))


def segments_crossing(p0: np.ndarray, d: np.ndarray, u: np.ndarray, v: np.ndarray,
                      at_u: np.ndarray | None = None, at_v: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Of the segment pairs (u, v) (starts ``p0``, vectors ``d``, read in x, y), those whose
    projections cross, with the parameters on both, half-open [0, 1): u, v, t_u, t_v. The
    starts are rows u, v of ``p0``, or ``at_u``, ``at_v`` (the crossing count's ``p0`` is
    every sample of the courses, a segment's start and the previous one's end one row)."""
    at_u = u if at_u is None else at_u
    at_v = v if at_v is None else at_v
    # rows gathered by take (half of fancy indexing's time on the 100 x 100 pull's pairs)
    du, dv = np.take(d, u, axis=0), np.take(d, v, axis=0)
    den = du[:, 0] * dv[:, 1] - du[:, 1] * dv[:, 0]
    r = np.take(p0, at_v, axis=0) - np.take(p0, at_u, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        tu = (r[:, 0] * dv[:, 1] - r[:, 1] * dv[:, 0]) / den
        tv = (r[:, 0] * du[:, 1] - r[:, 1] * du[:, 0]) / den
    hit = (den != 0) & (tu >= 0) & (tu < 1) & (tv >= 0) & (tv < 1)
    return u[hit], v[hit], tu[hit], tv[hit]


def _empty() -> Crossings:
    z = np.zeros(0)
    return Crossings(z.astype(int), z, z.astype(int), z, np.zeros((0, 2)))


REACH = 2                  # offsets |Δi|, |Δj| <= REACH are searched for natural crossings


@dataclass
class Verdict:
    """Crossings judged against the natural fabric, per pair of loops: ``new`` maps each pair
    of loops (k_A, k_B) with more crossings than its natural count to how many more;
    ``lost_pairs`` maps each pair of loops with fewer crossings than its natural count to how
    many fewer, and ``lost`` counts them all."""

    new: dict[tuple[int, int], int]
    lost_pairs: dict[tuple[int, int], int]

    @property
    def lost(self) -> int:
        return sum(self.lost_pairs.values())

    @property
    def clean(self) -> bool:
        return not self.new

    @property
    def n_new(self) -> int:
        return sum(self.new.values())


def judge(fab: NaturalFabric, found: Crossings, courses: int, wales: int) -> Verdict:
    """Count the crossings of every pair of loops against the natural count of its offset. A
    designed crossing may slide past the end of a loop into the next loop of its course: one
    crossing too many on a pair of loops next to one too few on the pair that shares a loop
    with it and whose other loop is the neighbour in the same course is such a slide, not a
    new crossing. Slides are paired with missing crossings by a maximum matching
    (:func:`_slides`), so that a row of interlocks that each slid one loop along is seen as
    slides however the pairs are ordered. Pairs of loops are keys a·N + b (N loops) in
    arrays: dicts of Python tuples, built and looked up pair by pair, took 0.2-0.3 s of a
    100 x 100 check."""
    big = courses * wales
    a, b, cc = found.pair_counts()
    ck = a * big + b                                   # sorted, as the pairs (a, b)
    nk, nc = _natural(fab, courses, wales)             # in the order of designed_offsets
    natural_of = _lookup(nk, nc, ck)
    more = cc > natural_of
    ek, ev = ck[more], (cc - natural_of)[more]
    now = _lookup(ck, cc, nk)
    fewer = now < nc
    dk, dv = nk[fewer], (nc - now)[fewer]
    _slides(ek, ev, dk, dv, wales, big)
    return Verdict(_pairs_dict(ek, ev, big), _pairs_dict(dk, dv, big))


def _find(keys: np.ndarray, wanted: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each wanted key is in ``keys`` (unique, not empty), and whether it is there."""
    order = np.argsort(keys, kind="stable")
    at = order[np.minimum(np.searchsorted(keys[order], wanted), len(keys) - 1)]
    return at, keys[at] == wanted


def _lookup(keys: np.ndarray, values: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """The value of each wanted key (0 where ``keys``, unique, do not hold it)."""
    if not len(keys):
        return np.zeros(len(wanted), dtype=values.dtype)
    at, found = _find(keys, wanted)
    return np.where(found, values[at], 0)


def _natural(fab: NaturalFabric, courses: int, wales: int) -> tuple[np.ndarray, np.ndarray]:
    """Keys a·N + b of the pairs of loops that cross in the natural fabric and their natural
    counts (``NaturalFabric.crossings`` once per offset), offset by offset, loop by loop."""
    keys, counts = [], []
    i, j = np.divmod(np.arange(courses * wales), wales)
    for di, dj in designed_offsets(fab):
        inside = (i + di < courses) & (j + dj >= 0) & (j + dj < wales)
        a = (i * wales + j)[inside]
        keys.append(a * (courses * wales) + a + di * wales + dj)
        counts.append(np.full(a.size, fab.crossings((di, dj)), dtype=np.int64))
    if not keys:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    return np.concatenate(keys), np.concatenate(counts)


def _pairs_dict(keys: np.ndarray, values: np.ndarray, big: int) -> dict[tuple[int, int], int]:
    """{(a, b): value} of the keys a·big + b with a positive value, in their order."""
    keep = values > 0
    a, b = np.divmod(keys[keep], big)
    return dict(zip(zip(a.tolist(), b.tolist()), values[keep].tolist()))


def _slides(ek: np.ndarray, ev: np.ndarray, dk: np.ndarray, dv: np.ndarray, wales: int,
            big: int) -> None:
    """Take the slides out of the excess counts ``ev`` and the deficits ``dv`` (in place; their
    pairs of loops: keys ``ek``, ``dk``, a·big + b, unique): each crossing too many on loops
    (a, b) may stand for one too few on (a ± 1, b) or (a, b ± 1), the neighbour in the same
    course. A maximum bipartite matching of single crossings (SciPy's Hopcroft-Karp) pairs as
    many as can be paired; a greedy pass, pair by pair, could spend the missing crossing a
    later slide needed (a sheared row of interlocks by the 100 x 100 pull's pinned corner:
    (11,1)-(12,2), (11,2)-(12,3), (11,3)-(12,4) against (11,1)-(12,1), (11,2)-(12,2),
    (11,3)-(12,3); the greedy pass left (11,3)-(12,4) "new")."""
    if not len(ek) or not len(dk):
        return
    unit = np.repeat(np.arange(len(ek)), ev)           # each crossing too many: its pair
    hole0 = np.concatenate([[0], np.cumsum(dv)])        # each pair's missing crossings
    a, b = np.divmod(ek[unit], big)
    moved = np.stack([np.stack([a - 1, b], -1), np.stack([a + 1, b], -1),
                      np.stack([a, b - 1], -1), np.stack([a, b + 1], -1)], axis=1)
    na, nb = moved[..., 0], moved[..., 1]
    course = (na // wales == (a // wales)[:, None]) & (nb // wales == (b // wales)[:, None])
    key = np.minimum(na, nb) * big + np.maximum(na, nb)
    at, there = _find(dk, key)
    hit = course & there
    owner, cols = expand(np.where(hit, hole0[at], 0).ravel(),
                         np.where(hit, hole0[at + 1], 0).ravel())
    if not len(cols):
        return
    rows = owner // 4                                   # unit by unit, moves and holes in order
    from scipy.sparse import csr_matrix                # lazy, as find_crossings' cKDTree
    from scipy.sparse.csgraph import maximum_bipartite_matching
    graph = csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(len(unit), hole0[-1]))
    match = maximum_bipartite_matching(graph, perm_type="column")
    paired = match >= 0
    np.subtract.at(ev, unit[paired], 1)
    np.subtract.at(dv, np.searchsorted(hole0, match[paired], side="right") - 1, 1)


def designed_offsets(fab: NaturalFabric) -> list[tuple[int, int]]:
    """Offsets (Δi, Δj) with Δi > 0 or (Δi = 0, Δj > 0) whose natural loops cross."""
    return [(di, dj) for di in range(0, REACH + 1) for dj in range(-REACH, REACH + 1)
            if (di > 0 or dj > 0) and fab.crossings((di, dj)) > 0]


def designed_zones(fab: NaturalFabric, curves: Curves, grid: Grid, found: Crossings,
                   new: dict) -> Zones:
    """The zones of the crossings ``found`` on pairs of loops not in ``new`` (those the count
    finds with more crossings than their natural count)."""
    keep = np.array([(int(a), int(b)) not in new for a, b in zip(found.kA, found.kB)],
                    dtype=bool)
    kA, sA, kB, sB = found.kA[keep], found.sA[keep], found.kB[keep], found.sB[keep]
    sin = np.abs(np.sin(curves.angle(kA, sA) - curves.angle(kB, sB)))
    z = half_width(fab.radius, sin, grid.L)
    n = grid.wales
    ca, Sa = kA // n, kA % n * grid.L + sA
    cb, Sb = kB // n, kB % n * grid.L + sB
    return Zones(np.concatenate([ca, cb]), np.concatenate([Sa, Sb]),
                 np.concatenate([cb, ca]), np.concatenate([Sb, Sa]), np.concatenate([z, z]))
