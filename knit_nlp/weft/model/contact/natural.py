"""What the natural fabric says about every pair of yarn pieces: whether they cross by design,
and how close they already are.

All loops share one natural shape placed by translation (docs/weft_model.md, "Natural state"),
so everything here depends only on the offset (Δi, Δj) between two loops and on the material
points s_A, s_B; tables are built per offset on a grid of ``GRID`` points per loop, on demand.

- **Designed pieces.** The natural crossings of two loops (for jersey: the paper's A, C, Q, S of
  the upper loop with D, F, G, P of the lower) are found by polyline intersection. Crossings
  that follow each other along both yarns with the pieces between them within 2r (a lens, like
  A-C with D-F) are one interlock. Piece pairs inside the box [first − z, last + z] ×
  [first' − z, last' + z] of an interlock may come as close as they like (required gap 0: they
  only must not cross anew). z = max(2r / sin α, ``SLIDE``·L): the arc length over which two
  yarns crossing at angle α stay within 2r, or the measured slide of the crossings along the
  yarns, whichever is larger. (The crossings themselves need no zone: contact pairs are local
  minima of the distance, and there is none near a crossing; crossings.py counts them.)
- **Same yarn.** Pieces of one course closer than ``EXCLUSION``·πr along the yarn are one piece.
- **Thick yarn.** ``natural_gap[a, b]``: the natural distance between the pieces around s_A and
  s_B (min over a box of half-width ``NEIGHBOURHOOD``): a pair that was closer than 2r keeps at
  least that distance (``required = min(2r, natural_gap)``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..basis import phi
from .near import cell_pairs

GRID = 801                 # grid points per loop for the natural tables
SLIDE = 0.1                # minimal designed-zone half-width, in loop lengths (measured slides)
EXCLUSION = 1.0            # same-yarn pieces closer than EXCLUSION·π·r along the yarn are one
NEIGHBOURHOOD = 0.05       # half-width (loop lengths) of the natural-gap min over nearby pieces
GRID_SAG = 0.5             # |curvature| / 4 bound of the grid's allowance (1 / length units)
SHARED = 8                 # natural fabrics kept (each with its tables) for later solves


@dataclass(frozen=True)
class Interlock:
    """A designed zone of one loop offset: material boxes on both loops (s ranges)."""

    a: tuple[float, float]
    b: tuple[float, float]
    crossings: tuple[tuple[float, float, float], ...]    # (s_A, s_B, angle in rad)


@dataclass
class OffsetTable:
    """Natural facts about loop B = A + (Δi, Δj): the natural gap of every piece pair (0 inside
    designed interlocks, +inf on the same piece of yarn) and the interlocks."""

    offset: tuple[int, int]
    natural_gap: np.ndarray       # (GRID, GRID) float32
    interlocks: tuple[Interlock, ...]


@dataclass
class NaturalFabric:
    """The natural loop's polyline and placement, the radius, and per-offset tables."""

    L: float
    xy: np.ndarray                 # (GRID, 2) natural loop from its start
    wale: np.ndarray               # (2,) translation from loop (i, j) to (i, j+1)
    course: np.ndarray             # (2,) translation from loop (i, j) to (i+1, j)
    tangent_angle: np.ndarray      # (GRID,) natural θ
    radius: float
    tables: dict[tuple[int, int], OffsetTable] = field(default_factory=dict)
    _locks: dict[tuple[int, int], list[Interlock]] = field(default_factory=dict)

    @classmethod
    def of(cls, problem, radius: float) -> "NaturalFabric":
        """From a weft problem's natural loop and a yarn radius; one shared instance (and its
        tables) per natural loop and radius, so the solves of a study, a fit or a control
        build each table once (a table costs 30-100 ms)."""
        nat = problem.natural
        key = (nat.length, nat.harmonics, tuple(np.ravel(nat.coeffs).tolist()),
               nat.wale_spacing, nat.rise, nat.course_spacing, float(radius))
        if key not in _SHARED:
            if len(_SHARED) >= SHARED:
                _SHARED.pop(next(iter(_SHARED)))
            _SHARED[key] = cls._new(problem, radius)
        return _SHARED[key]

    @classmethod
    def _new(cls, problem, radius: float) -> "NaturalFabric":
        nat = problem.natural
        s = np.linspace(0.0, nat.length, GRID)
        return cls(nat.length, nat.xy(s), np.array([nat.wale_spacing, nat.rise]),
                   np.array([0.0, nat.course_spacing]), phi(s, nat.length, nat.harmonics)
                   @ nat.coeffs, float(radius))

    @property
    def s(self) -> np.ndarray:
        return np.linspace(0.0, self.L, GRID)

    @property
    def exclusion(self) -> float:
        """Arc length within which pieces of one yarn count as one piece."""
        return EXCLUSION * np.pi * self.radius

    def index(self, s: np.ndarray) -> np.ndarray:
        """Nearest grid index of material points s (clipped to the loop)."""
        return np.clip(np.rint(np.asarray(s) / self.L * (GRID - 1)).astype(int), 0, GRID - 1)

    def shift(self, di: np.ndarray, dj: np.ndarray) -> np.ndarray:
        """Natural translation from loop A to loop B = A + (Δi, Δj), shape (..., 2)."""
        return np.asarray(di)[..., None] * self.course + np.asarray(dj)[..., None] * self.wale

    def table(self, offset: tuple[int, int]) -> OffsetTable:
        """The table of one offset (built once)."""
        if offset not in self.tables:
            self.tables[offset] = self._build(offset)
        return self.tables[offset]

    def _build(self, offset: tuple[int, int]) -> OffsetTable:
        di, dj = offset
        a, b = self.xy, self.xy + self.shift(np.array(di), np.array(dj))
        reaching = self._reaching(offset)
        if not reaching and _box_distance(a, b) > 2 * self.radius + self.L / 100:
            # every piece pair is naturally more than 2r apart and none is designed: the
            # required gap is 2r throughout (measured: most offsets a search meets)
            return OffsetTable(offset, np.broadcast_to(np.float32(np.inf), (GRID, GRID)), ())
        dist = _distances(a, b)
        s = self.s
        same = np.zeros_like(dist, dtype=bool)
        if di == 0:
            same = np.abs(dj * self.L + s[None, :] - s[:, None]) < self.exclusion
        interlocks = self._own_interlocks(offset)
        designed = np.zeros_like(same)
        for lock in reaching:
            ia = (s >= lock.a[0]) & (s <= lock.a[1])
            ib = (s >= lock.b[0]) & (s <= lock.b[1])
            designed |= ia[:, None] & ib[None, :]
        width = 2 * int(np.ceil(NEIGHBOURHOOD * (GRID - 1))) + 1
        from scipy import ndimage           # lazy: scipy only when contact is used
        gap = ndimage.minimum_filter(np.where(same, np.inf, np.where(designed, 0.0, dist)),
                                     size=width, mode="nearest")
        # grid points miss the closest points by up to half a spacing on each yarn: allow for
        # the distance that adds (h²/8d for parallel yarns, ~κh²/4 for curved ones)
        h = self.L / (GRID - 1)
        gap = np.maximum(gap - h * h / (8 * np.maximum(gap, h)) - GRID_SAG * h * h, 0.0)
        return OffsetTable(offset, gap.astype(np.float32), tuple(interlocks))

    def _own_interlocks(self, offset: tuple[int, int]) -> list[Interlock]:
        """The interlocks of the natural loops of one offset (memoised)."""
        if offset not in self._locks:
            a = self.xy
            b = self.xy + self.shift(np.array(offset[0]), np.array(offset[1]))
            if _box_distance(a, b) > 2 * self.radius:
                self._locks[offset] = []           # no crossing, no lens: boxes apart
                return []
            self._locks[offset] = _interlocks(self, a, b)
        return self._locks[offset]

    def _reaching(self, offset: tuple[int, int]) -> list[Interlock]:
        """Interlock boxes in this offset's material coordinates, including the parts of boxes
        of neighbouring loop pairs that run past a loop's end into this pair (a box is in arc
        length along each course, and a course's loops follow each other)."""
        di, dj = offset
        L, out = self.L, []
        for da in (-1, 0, 1):
            for db in (-1, 0, 1):
                for lock in self._own_interlocks((di, dj - db + da)):
                    a = (lock.a[0] - da * L, lock.a[1] - da * L)
                    b = (lock.b[0] - db * L, lock.b[1] - db * L)
                    if a[1] >= 0 and a[0] <= L and b[1] >= 0 and b[0] <= L:
                        out.append(Interlock(a, b, lock.crossings))
        return out

    def lookup(self, di: np.ndarray, dj: np.ndarray, sa: np.ndarray, sb: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
        """For piece pairs: whether they are one piece of yarn, and their required gap
        min(2r, natural gap) (0 in a designed interlock: there only crossing is forbidden)."""
        ia, ib = self.index(sa), self.index(sb)
        same = np.zeros(ia.shape, dtype=bool)
        required = np.full(ia.shape, 2 * self.radius)
        for off in set(zip(np.ravel(di).tolist(), np.ravel(dj).tolist())):
            sel = (di == off[0]) & (dj == off[1])
            tab = self.table(off)
            if off[0] == 0:
                same[sel] = np.abs(off[1] * self.L + np.asarray(sb)[sel] - np.asarray(sa)[sel]
                                   ) <= self.exclusion
            required[sel] = np.minimum(required[sel], tab.natural_gap[ia[sel], ib[sel]])
        return same, required

    def crossings(self, offset: tuple[int, int]) -> int:
        """How many times the natural loops of an offset cross (0 for the shared end of two
        neighbours in a course)."""
        return sum(len(lock.crossings) for lock in self._own_interlocks(offset))


_SHARED: dict[tuple, "NaturalFabric"] = {}


def _box_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Distance between the bounding boxes of two polylines (0 where they overlap): a lower
    bound of every distance between their points."""
    gap = np.maximum(np.maximum(a.min(0) - b.max(0), b.min(0) - a.max(0)), 0.0)
    return float(np.hypot(*gap))


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Every point of polyline a against every point of b (hypot: half of norm's time on the
    801 x 801 tables, built for each offset a solve or check meets)."""
    return np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])


def natural_crossings(a: np.ndarray, b: np.ndarray, s: np.ndarray,
                      dist: np.ndarray | None = None, near: bool = False
                      ) -> list[tuple[float, float, float]]:
    """Crossings (s_A, s_B, angle) of two polylines sampled at s (segment intersections), in
    no particular order. Given ``dist`` (:func:`_distances` of a and b), or with ``near``,
    only segments whose first points lie within the two longest segments of each other are
    tried (two segments that meet do): read from the table, or (``near``) found by a cell
    list without it (:func:`_close_points`: no 8 ms table an offset, seven offsets in a first
    check, and no SciPy import). The dense intersection of all 800 x 800 segment pairs took
    0.06 s an offset."""
    da, db = np.diff(a, axis=0), np.diff(b, axis=0)
    if dist is None and not near:
        ia, ib = np.nonzero(np.ones((len(da), len(db)), dtype=bool))
    else:
        reach = np.hypot(*da.T).max() + np.hypot(*db.T).max()
        ia, ib = (np.nonzero(dist[:-1, :-1] <= reach) if dist is not None
                  else _close_points(a[:-1], b[:-1], reach))
    p, dp, q, dq = a[ia], da[ia], b[ib], db[ib]
    den = dp[:, 0] * dq[:, 1] - dp[:, 1] * dq[:, 0]
    r = q - p
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = (r[:, 0] * dq[:, 1] - r[:, 1] * dq[:, 0]) / den
        tb = (r[:, 0] * dp[:, 1] - r[:, 1] * dp[:, 0]) / den
    hit = (np.abs(den) > 0) & (ta >= 0) & (ta < 1) & (tb >= 0) & (tb < 1)
    h = s[1] - s[0]
    out = []
    for i, j, u, v in zip(ia[hit], ib[hit], ta[hit], tb[hit]):
        ua, ub = da[i], db[j]
        cosang = abs(ua @ ub) / (np.linalg.norm(ua) * np.linalg.norm(ub))
        out.append((float(s[i] + u * h), float(s[j] + v * h),
                    float(np.arccos(np.clip(cosang, 0.0, 1.0)))))
    return out


def _close_points(a: np.ndarray, b: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs (i, j) of the points a_i, b_j within ``reach`` of each other, and some
    further (those in neighbouring cells of near.cell_pairs, over a and b together: more
    segment pairs tried, the same ones meeting)."""
    both = np.concatenate([a, b])
    uv = np.concatenate([np.zeros((0, 2), dtype=np.int64),
                         *cell_pairs(both, reach, len(both) ** 2)])
    uv = uv[(uv[:, 0] < len(a)) & (uv[:, 1] >= len(a))]
    return uv[:, 0], uv[:, 1] - len(a)


def _interlocks(fab: NaturalFabric, a: np.ndarray, b: np.ndarray) -> list[Interlock]:
    """Group the natural crossings of two loops into interlocks and give each its box (the
    distances between the pieces of a lens: :func:`_distances` of those pieces only)."""
    s = fab.s
    found = sorted(natural_crossings(a, b, s, near=True))
    if not found:
        return []
    groups: list[list[tuple[float, float, float]]] = [[found[0]]]
    for c in found[1:]:
        prev = groups[-1][-1]
        lo_a, hi_a = fab.index(prev[0]), fab.index(c[0])
        lo_b, hi_b = sorted((fab.index(prev[1]), fab.index(c[1])))
        # a lens: the pieces between the two crossings stay within 2r of each other
        between = _distances(a[lo_a:hi_a + 1], b[lo_b:hi_b + 1])
        lens = between.size and np.max(np.min(between, axis=1)) < 2 * fab.radius + 1e-12 and \
            abs(c[1] - prev[1]) < fab.L / 2
        if lens:
            groups[-1].append(c)
        else:
            groups.append([c])
    out = []
    for g in groups:
        z = max([2 * fab.radius / max(np.sin(ang), 1e-3) for _, _, ang in g] + [SLIDE * fab.L])
        sa = [c[0] for c in g]
        sb = [c[1] for c in g]
        out.append(Interlock((min(sa) - z, max(sa) + z), (min(sb) - z, max(sb) + z), tuple(g)))
    return out
