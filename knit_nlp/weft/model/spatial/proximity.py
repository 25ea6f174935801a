"""The 3-D model's independent check over all pairs of yarn pieces (docs/weft3d.md, "Check").

Every course's deformed centreline, sampled (``SpatialNLP.centrelines3d``, or rebuilt from a
result JSON), is one polyline along its yarn; its material coordinate u = (j − 1)·L + s is the
arc length along the course (the yarn is inextensible). The polylines are cut into pieces
(segments) and:

- **Broad phase** (bounded memory): a k-d tree over the segments' midpoints; two segments whose
  midpoints are more than ``reach`` + the longest segment apart are farther than ``reach``
  (triangle inequality, each point of a segment lies within half its length of its midpoint).
  The candidate pairs come from ``contact.near.close_pairs``, a bounded number at a time.
- **Narrow phase**: the exact distance between two segments (:func:`segment_distance`,
  vectorised; the closest points of two segments, clamped to both, as in Ericson, *Real-time
  collision detection*, 5.1.9).
- **Same yarn** (the planar rule of ``contact/natural.py``, ``EXCLUSION``; ``contact/rule.py``
  refuses radii for which it is ambiguous): pieces of one course whose closest points are
  closer than EXCLUSION·π·r along the yarn (|u_a − u_b|) are one piece and not judged.
- **Designed crossings, independently.** Between courses i and i − 1 the projections' crossings
  are found (2-D segment intersections, half-open parameters); each designed crossing (A/D,
  C/F, Q/G, S/P of plain knit, ``natural3d.PAIRS``) is matched to the nearest one in material
  coordinates (both within ``MATCH``·L of the natural crossing's), and its order is read from
  the geometry: the sign of z_upper − z_lower at the crossing of the two projections. A designed
  crossing whose sign differs from the plain-knit order has **flipped**; one with no crossing of
  the projections near it is **lost** (its yarns slid apart in projection: reported, not a
  violation). Segment pairs within ``DESIGNED``·2r along both yarns of a matched crossing are
  that crossing's own contact (pressed by design, its law is the crossing's); every other pair
  closer than 2r is an **other contact**.

An answer is **clean** when no pair of pieces is closer than the hard core 2R_c and no designed
crossing flipped.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterator

import numpy as np

from ..contact.crossings import segments_crossing
from ..contact.natural import EXCLUSION
from ..contact.near import close_pairs
from .natural3d import PAIRS, Natural3D

ROWS = 1 << 20              # candidate segment pairs judged at once (about 0.3 GB of temporaries)
MATCH = 0.25                # a designed crossing matches a projected crossing within MATCH·L
DESIGNED = 2.0              # a crossing's own contact: within DESIGNED·2r along both yarns
LISTED = 100                # closest pairs listed per kind


def segment_distance(p: np.ndarray, dp: np.ndarray, q: np.ndarray, dq: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact distances between segments p + a·dp and q + b·dq, a, b ∈ [0, 1], row by row
    ((k, 3) arrays), and the parameters (a, b) of a pair of closest points (Ericson 5.1.9:
    the unconstrained closest points, b clamped, a recomputed for the clamped b and clamped;
    (nearly) parallel segments take a = 0 first and then the nearest of their four ends'
    closest points, ``_ends``)."""
    r = p - q
    A = np.einsum("ki,ki->k", dp, dp)
    E = np.einsum("ki,ki->k", dq, dq)
    F = np.einsum("ki,ki->k", dq, r)
    C = np.einsum("ki,ki->k", dp, r)
    B = np.einsum("ki,ki->k", dp, dq)
    tiny = 1e-300
    den = A * E - B * B
    with np.errstate(divide="ignore", invalid="ignore"):
        a = np.where(den > 1e-14 * A * E, np.clip((B * F - C * E) / den, 0.0, 1.0), 0.0)
        b = (B * a + F) / E
        a = np.where(b < 0.0, np.clip(-C / A, 0.0, 1.0),
                     np.where(b > 1.0, np.clip((B - C) / A, 0.0, 1.0), a))
        b = np.clip(b, 0.0, 1.0)
        # degenerate segments (points): the other's closest point to it
        a = np.where(E <= tiny, np.clip(-C / A, 0.0, 1.0), a)
        b = np.where(E <= tiny, 0.0, b)
        b = np.where(A <= tiny, np.clip(F / E, 0.0, 1.0), b)
        a = np.where(A <= tiny, 0.0, a)
    b = np.where((A <= tiny) & (E <= tiny), 0.0, b)
    gap = r + a[:, None] * dp - b[:, None] * dq
    d = np.sqrt(np.einsum("ki,ki->k", gap, gap))
    flat = np.flatnonzero((den <= 1e-14 * A * E) & (A > tiny) & (E > tiny))
    if flat.size:            # (nearly) parallel: the nearest pair may sit at any end
        d, a, b = _ends(p, dp, q, dq, flat, d, a, b)
    return d, a, b


def _ends(p: np.ndarray, dp: np.ndarray, q: np.ndarray, dq: np.ndarray, rows: np.ndarray,
          d: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, ...]:
    """For (nearly) parallel rows, the better of (a, b) and the four ends' closest points."""
    d, a, b = d.copy(), a.copy(), b.copy()
    P, DP, Q, DQ = p[rows], dp[rows], q[rows], dq[rows]
    for ea in (0.0, 1.0):                 # an end of p against segment q
        bb = np.clip(np.einsum("ki,ki->k", P + ea * DP - Q, DQ) / np.einsum("ki,ki->k", DQ, DQ), 0, 1)
        _keep(rows, d, a, b, np.full(rows.size, ea), bb, P, DP, Q, DQ)
    for eb in (0.0, 1.0):                 # an end of q against segment p
        aa = np.clip(np.einsum("ki,ki->k", Q + eb * DQ - P, DP) / np.einsum("ki,ki->k", DP, DP), 0, 1)
        _keep(rows, d, a, b, aa, np.full(rows.size, eb), P, DP, Q, DQ)
    return d, a, b


def _keep(rows: np.ndarray, d: np.ndarray, a: np.ndarray, b: np.ndarray, aa: np.ndarray,
          bb: np.ndarray, P: np.ndarray, DP: np.ndarray, Q: np.ndarray, DQ: np.ndarray) -> None:
    """Take (aa, bb) on the rows where it is nearer (in place)."""
    gap = P + aa[:, None] * DP - Q - bb[:, None] * DQ
    dd = np.sqrt(np.einsum("ki,ki->k", gap, gap))
    better = dd < d[rows]
    d[rows[better]], a[rows[better]], b[rows[better]] = dd[better], aa[better], bb[better]


@dataclass(frozen=True)
class Courses:
    """Every course as a polyline: ``points`` (m, K, 3) at material coordinates ``u`` (K,)
    along the course (K = n·(S − 1) + 1 for n loops of S samples), loop length L."""

    points: np.ndarray
    u: np.ndarray
    L: float
    wales: int

    @classmethod
    def of(cls, centrelines: np.ndarray, L: float) -> "Courses":
        """From sampled centrelines (m, n, S, 3) at s = linspace(0, L, S): a loop's last sample
        is the next loop's first (loops are chained, eq. S2)."""
        m, n, S, _ = centrelines.shape
        body = centrelines[:, :, :-1].reshape(m, n * (S - 1), 3)
        pts = np.concatenate([body, centrelines[:, -1:, -1]], axis=1)
        return cls(pts, np.linspace(0.0, n * L, n * (S - 1) + 1), L, n)

    @property
    def per_course(self) -> int:
        return self.points.shape[1] - 1

    def segments(self) -> tuple[np.ndarray, np.ndarray]:
        """Starts and directions (M, 3) of all segments, course by course."""
        p = self.points
        return p[:, :-1].reshape(-1, 3), (p[:, 1:] - p[:, :-1]).reshape(-1, 3)

    def locate(self, seg: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Course and material coordinate u along it of parameter a on segments ``seg``."""
        course, g = np.divmod(seg, self.per_course)
        return course, self.u[g] + a * (self.u[g + 1] - self.u[g])

    def loop_of(self, course: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Loop index k = i·n + j (0-based) and s on it of points u along courses."""
        j = np.clip(np.floor(u / self.L).astype(int), 0, self.wales - 1)
        return course * self.wales + j, u - j * self.L


@dataclass
class Near:
    """Segment pairs closer than the check's reach: courses, material coordinates of the
    closest points, distances, and whether each is a designed crossing's own contact."""

    ca: np.ndarray
    ua: np.ndarray
    cb: np.ndarray
    ub: np.ndarray
    d: np.ndarray
    designed: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))

    def select(self, keep: np.ndarray) -> "Near":
        designed = (self.designed if len(self.designed) == len(self.d)
                    else np.zeros(len(self.d), bool))
        return Near(self.ca[keep], self.ua[keep], self.cb[keep], self.ub[keep], self.d[keep],
                    designed[keep])


def close_segments(courses: Courses, reach: float, exclusion: float, rows: int = ROWS
                   ) -> Iterator[Near]:
    """Every pair of segments of different pieces of yarn (not one piece by the same-yarn rule,
    ``exclusion`` along the course) closer than ``reach``, in chunks of at most ``rows``
    candidate pairs (module docstring: broad and narrow phase)."""
    p, d = courses.segments()
    length = float(np.sqrt(np.max(np.einsum("ki,ki->k", d, d)))) if len(d) else 0.0
    K = courses.per_course
    for uv in close_pairs(p + d / 2, reach + length + 1e-12, rows):
        u, v = uv[:, 0], uv[:, 1]
        same = (u // K == v // K)
        far = ~same | (np.abs(courses.u[u % K] - courses.u[v % K]) >= exclusion - 2 * length)
        u, v = u[far], v[far]
        dist, a, b = segment_distance(p[u], d[u], p[v], d[v])
        ca, ua = courses.locate(u, a)
        cb, ub = courses.locate(v, b)
        keep = (dist < reach) & ((ca != cb) | (np.abs(ua - ub) >= exclusion))
        yield Near(ca[keep], ua[keep], cb[keep], ub[keep], dist[keep])


@dataclass
class Designed:
    """Every designed crossing (course i ≥ 1 over/under course i − 1, wale j, pair of PAIRS):
    its natural material coordinates, order (+1: upper over), and what the geometry says:
    the matched crossing of the projections (u on both, NaN when lost) and z_upper − z_lower
    there."""

    course: np.ndarray
    wale: np.ndarray
    pair: np.ndarray
    order: np.ndarray
    u_upper: np.ndarray
    u_lower: np.ndarray
    dz: np.ndarray

    @property
    def lost(self) -> np.ndarray:
        return np.isnan(self.dz)

    @property
    def flipped(self) -> np.ndarray:
        return ~self.lost & (np.sign(np.nan_to_num(self.dz)) != self.order)


def reference_crossings(natural: Courses, rows: int = ROWS) -> tuple[np.ndarray, np.ndarray]:
    """Where a loop's designed crossings are, from the natural fabric's geometry: the crossings
    of the projections of a loop of course 2 with course 1 (its wale in the middle), as
    material coordinates on the upper loop (s) and offsets on the lower course from the same
    wale's start, in the order along the upper loop: the PAIRS (A/D, C/F, Q/G, S/P)."""
    found = projected_crossings(Courses(natural.points[:2], natural.u, natural.L,
                                        natural.wales), rows)
    j = natural.wales // 2
    L = natural.L
    mine = found[(found[:, 1] >= j * L) & (found[:, 1] < (j + 1) * L)]
    mine = mine[np.argsort(mine[:, 1])]
    if len(mine) != len(PAIRS):
        raise ValueError(f"the natural fabric's projections cross {len(mine)} times per loop, "
                         f"plain knit's {len(PAIRS)} designed crossings expected")
    return mine[:, 1] - j * L, mine[:, 2] - j * L


def designed_crossings(courses: Courses, s_upper: np.ndarray, s_lower: np.ndarray,
                       rows: int = ROWS) -> Designed:
    """The designed crossings of a fabric (``reference_crossings``: per loop, on the upper loop
    and offsets on the lower course; PAIRS order) matched to the crossings of the projections
    (module docstring)."""
    m, n, L = courses.points.shape[0], courses.wales, courses.L
    i, j, q = (g.ravel() for g in np.meshgrid(np.arange(1, m), np.arange(n), np.arange(4),
                                              indexing="ij"))
    order = np.array([o for _, _, o in PAIRS], dtype=float)[q]
    u0, l0 = j * L + np.asarray(s_upper)[q], j * L + np.asarray(s_lower)[q]
    uu, ul, dz = (np.full(i.shape, np.nan) for _ in range(3))
    found = projected_crossings(courses, rows)
    for c in range(1, m):
        mine = np.flatnonzero(i == c)
        hits = found[(found[:, 0] == c)]
        if not len(hits) or not len(mine):
            continue
        far = np.maximum(np.abs(hits[None, :, 1] - u0[mine, None]),
                         np.abs(hits[None, :, 2] - l0[mine, None]))
        for r, h in _greedy(far, MATCH * L):
            uu[mine[r]], ul[mine[r]], dz[mine[r]] = hits[h, 1], hits[h, 2], hits[h, 3]
    return Designed(i, j, q, order, uu, ul, dz)


def _greedy(cost: np.ndarray, limit: float) -> list[tuple[int, int]]:
    """Pairs (row, column) of smallest cost first, each row and column once, cost < limit."""
    r, c = np.nonzero(cost < limit)
    out, used_r, used_c = [], set(), set()
    for k in np.argsort(cost[r, c], kind="stable"):
        if r[k] not in used_r and c[k] not in used_c:
            out.append((int(r[k]), int(c[k])))
            used_r.add(r[k])
            used_c.add(c[k])
    return out


def projected_crossings(courses: Courses, rows: int = ROWS) -> np.ndarray:
    """Crossings of the projections (x, y) of neighbouring courses i and i − 1: rows
    (i, u on course i, u on course i − 1, z_i − z_{i−1} there)."""
    p, d = courses.segments()
    K = courses.per_course
    length = float(np.sqrt(np.max(np.einsum("ki,ki->k", d[:, :2], d[:, :2])))) if len(d) else 0.0
    out = []
    for uv in close_pairs((p + d / 2)[:, :2], length + 1e-12, rows):
        u, v = uv[:, 0], uv[:, 1]
        keep = np.abs(u // K - v // K) == 1
        u, v = u[keep], v[keep]
        up = u // K > v // K
        u, v = np.where(up, u, v), np.where(up, v, u)         # u on the upper course
        u, v, a, b = segments_crossing(p, d, u, v)
        cu, uu = courses.locate(u, a)
        _, ul = courses.locate(v, b)
        dz = (p[u, 2] + a * d[u, 2]) - (p[v, 2] + b * d[v, 2])
        out.append(np.stack([cu, uu, ul, dz], axis=1))
    return np.concatenate(out) if out else np.zeros((0, 4))


def own_contact(near: Near, found: Designed, window: float, wales: int, L: float
                ) -> np.ndarray:
    """Which pairs are a matched designed crossing's own contact: on courses i and i − 1, both
    closest points within ``window`` of the crossing along their yarns (the crossings of the
    upper point's wale and its two neighbours are looked at)."""
    out = np.zeros(len(near.d), dtype=bool)
    if not len(found.order):
        return out
    a_up = near.ca == near.cb + 1
    pair = a_up | (near.cb == near.ca + 1)
    course = np.where(a_up, near.ca, near.cb)
    upper, lower = np.where(a_up, near.ua, near.ub), np.where(a_up, near.ub, near.ua)
    j0 = np.floor(upper / L).astype(int)
    for dj in (-1, 0, 1):
        j = j0 + dj
        valid = pair & (j >= 0) & (j < wales)
        for q in range(len(PAIRS)):
            idx = np.where(valid, ((course - 1) * wales + j) * len(PAIRS) + q, 0)
            out |= valid & ~found.lost[idx] & (np.abs(upper - found.u_upper[idx]) < window) & (
                np.abs(lower - found.u_lower[idx]) < window)
    return out


def reduce(near: Near, cell: float, L: float) -> Near:
    """The closest pair of each cell (``cell`` of a loop along both yarns, designed contacts
    apart from the others): every distance the report states (the smallest, the closest per
    pair of loops and kind) is kept, and the pairs of one contact (tens of segment pairs)
    become a few."""
    if not len(near.d):
        return near
    per = int(np.ceil(L / cell)) + 1
    ia = np.floor(near.ua / L).astype(np.int64) * per + np.floor(near.ua % L / cell).astype(np.int64)
    ib = np.floor(near.ub / L).astype(np.int64) * per + np.floor(near.ub % L / cell).astype(np.int64)
    span = int(max(ia.max(), ib.max())) + 1
    key = ((near.ca.astype(np.int64) * span + ia) * (int(near.cb.max()) + 1) + near.cb) * span + ib
    key = 2 * key + (near.designed if len(near.designed) == len(near.d) else 0)
    order = np.lexsort((near.d, key))
    _, first = np.unique(key[order], return_index=True)
    return near.select(order[first])


@dataclass
class ProximityReport:
    """What the check found (module docstring). Distances in the problem's length unit."""

    radius: float
    core: float
    samples: int
    smallest: float | None = None                 # over all pairs of different pieces
    smallest_where: dict[str, Any] | None = None
    smallest_other: float | None = None           # over pairs that are no designed contact
    inside_core: list[dict[str, Any]] = field(default_factory=list)
    n_inside_core: int = 0
    other_touching: list[dict[str, Any]] = field(default_factory=list)
    n_other_touching: int = 0                     # loop pairs, not designed, closer than 2r
    designed_touching: int = 0                    # designed crossings pressed closer than 2r
    n_designed: int = 0
    flipped: list[dict[str, Any]] = field(default_factory=list)
    lost: int = 0
    touching: Near | None = None                  # every pair closer than 2r, designed or not:
    #                                               the rounds' candidates (the model decides
    #                                               which are its designed contacts' own)
    order_unknown: str | None = None              # why the crossings' order was not read

    @property
    def ok(self) -> bool:
        return self.n_inside_core == 0 and not self.flipped and self.order_unknown is None

    def verdict(self, unit: str = "") -> str:
        """One sentence."""
        u = f" {unit}" if unit else ""
        near = ("no pieces within 2r" if self.smallest is None else
                f"smallest distance between non-neighbouring pieces {self.smallest:.4g}{u}")
        text = (f"{'clean' if self.ok else 'NOT CLEAN'}: all pairs of yarn pieces in 3-D, "
                f"{self.n_inside_core} pairs of loops inside the hard core 2R_c = "
                f"{self.core:.4g}{u}, " + (
                    f"{len(self.flipped)} of {self.n_designed} designed crossings flipped "
                    f"({self.lost} lost in projection)" if self.order_unknown is None else
                    f"crossing order not read ({self.order_unknown})") + f"; {near}; "
                f"{self.n_other_touching} other contacts closer than 2r = {2 * self.radius:.4g}{u}")
        return text + ("" if self.ok else ": the yarns pass through each other")

    def block(self, unit: str = "") -> dict[str, Any]:
        """The result JSON's ``check`` block of a 3-D result."""
        return {"model": "3d", "ok": self.ok, "verdict": self.verdict(unit),
                "smallest_distance": self.smallest, "smallest_where": self.smallest_where,
                "smallest_other_distance": self.smallest_other,
                "core": self.core, "touch": 2 * self.radius,
                "inside_core_count": self.n_inside_core, "inside_core": self.inside_core,
                "other_contacts_count": self.n_other_touching,
                "other_contacts": self.other_touching,
                "designed_crossings": self.n_designed, "designed_pressed": self.designed_touching,
                "flipped": len(self.flipped), "flipped_crossings": self.flipped,
                "lost_in_projection": self.lost, "order_unknown": self.order_unknown,
                "samples_per_loop": self.samples,
                "same_yarn_rule": f"pieces of one course closer than {EXCLUSION:g}*pi*r along "
                                  "the yarn are one piece"}


def natural_lines(shape: Natural3D, wales: int, samples: int) -> np.ndarray:
    """The natural 3-D centrelines of two courses of at least three wales (m, n, S, 3): where
    :func:`check_3d` reads the designed crossings (``reference_crossings``)."""
    s = np.linspace(0.0, shape.length, samples)
    return shape.xyz(s)[None, None] + shape.starts(2, max(wales, 3))[:, :, None, :]


def check_3d(centrelines: np.ndarray, natural: np.ndarray, L: float, radius: float,
             core_radius: float, rows: int = ROWS) -> ProximityReport:
    """The independent check of sampled 3-D centrelines (m, n, S, 3), the designed crossings
    located on the natural fabric's centrelines ``natural`` (at least 2 courses, 3 wales,
    sampled alike) (module docstring)."""
    m, n, S, _ = centrelines.shape
    courses = Courses.of(np.asarray(centrelines, dtype=float), L)
    rep = ProximityReport(radius, 2 * core_radius, S)
    found = Designed(*(np.zeros(0) for _ in range(7)))
    if m >= 2:
        try:
            ref = reference_crossings(Courses.of(np.asarray(natural, dtype=float), L), rows)
            found = designed_crossings(courses, *ref, rows)
        except ValueError as err:             # the order cannot be read from projections
            rep.order_unknown = str(err)
    rep.n_designed, rep.lost = len(found.order), int(found.lost.sum())
    rep.flipped = [_crossing_row(found, k, n) for k in np.flatnonzero(found.flipped)]
    parts = []
    for chunk in close_segments(courses, 2 * radius, EXCLUSION * np.pi * radius, rows):
        chunk.designed = own_contact(chunk, found, DESIGNED * 2 * radius, n, L)
        parts.append(reduce(chunk, radius, L))
    if not parts or not sum(len(q.d) for q in parts):
        return rep
    near = reduce(Near(*(np.concatenate(c) for c in zip(*[
        (q.ca, q.ua, q.cb, q.ub, q.d, q.designed) for q in parts]))), radius, L)
    k = int(np.argmin(near.d))
    rep.smallest, rep.smallest_where = float(near.d[k]), _where(courses, near, k)
    if (~near.designed).any():
        rep.smallest_other = float(near.d[~near.designed].min())
    rep.n_inside_core, rep.inside_core = _by_loops(courses, near.select(near.d < 2 * core_radius))
    other = near.select(~near.designed)
    rep.n_other_touching, rep.other_touching = _by_loops(courses, other)
    rep.touching = near
    rep.designed_touching = _by_loops(courses, near.select(near.designed))[0]
    return rep


def _where(courses: Courses, near: Near, k: int) -> dict[str, Any]:
    ka, sa = courses.loop_of(near.ca[k:k + 1], near.ua[k:k + 1])
    kb, sb = courses.loop_of(near.cb[k:k + 1], near.ub[k:k + 1])
    n = courses.wales
    return {"loops": [_loop(int(ka[0]), n), _loop(int(kb[0]), n)],
            "s": [float(sa[0]), float(sb[0])], "distance": float(near.d[k]),
            "designed": bool(near.designed[k]) if near.designed.size else False}


def _by_loops(courses: Courses, near: Near) -> tuple[int, list[dict[str, Any]]]:
    """Pairs grouped by their two loops: how many pairs of loops, and the closest pair of each
    of the ``LISTED`` closest pairs of loops, closest first."""
    if not len(near.d):
        return 0, []
    ka, _ = courses.loop_of(near.ca, near.ua)
    kb, _ = courses.loop_of(near.cb, near.ub)
    lo, hi = np.minimum(ka, kb), np.maximum(ka, kb)
    key = lo.astype(np.int64) * (int(hi.max()) + 1) + hi
    order = np.lexsort((near.d, key))
    _, first = np.unique(key[order], return_index=True)
    best = order[first]
    best = best[np.argsort(near.d[best], kind="stable")]
    return len(best), [_where(courses, near, int(k)) for k in best[:LISTED]]


def _crossing_row(found: Designed, k: int, n: int) -> dict[str, Any]:
    p = PAIRS[int(found.pair[k])]
    i, j = int(found.course[k]), int(found.wale[k])
    return {"upper": [i + 1, j + 1], "lower": [i, j + 1], "pair": f"{p[0]}/{p[1]}",
            "upper_over": bool(p[2] > 0), "dz": float(found.dz[k])}


def _loop(k: int, n: int) -> list[int]:
    return [k // n + 1, k % n + 1]
