"""Neighbour searches in bounded memory: the k-d tree queries of the crossing count and the pair
search, a bounded number of neighbour rows at a time, and the cell list (:func:`cell_pairs`)
that counts crossings where their order does not show.

A query over all points at once holds every neighbour pair in memory at once: a 10 x 10 result
judged at r = 1.0 or 2.4 asked for 42 million rows and more (a MemoryError, or the kernel's kill
at 22 GB). Here the rows of a slice of points are estimated before they are stored (the
neighbour counts of ``PROBES`` of its points, evenly spread; ``query_ball_point`` counts without
storing), and a slice estimated above ``rows`` is halved until it is not; :func:`estimate` says
in advance how many rows a search will look at in all, so that a caller can refuse a search
that could not finish. (Exact counts by ``count_neighbors`` cost more than the search itself:
1.9 s against 0.9 s for the 2 million segments of a 100 x 100 result.)
"""
from __future__ import annotations

from typing import Iterator

import numpy as np

from .ranges import expand


def tree_of(points: np.ndarray):
    """A k-d tree over ``points`` (N, 2), built the quick way (unbalanced, loose nodes: 0.6 s
    against 1.4 s for the 2 million segments of a 100 x 100 result; the queries cost the
    same)."""
    from scipy.spatial import cKDTree     # lazy: 0.4 s to import, only with contact or check
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


class TooLarge(Exception):
    """A search estimated to look at more rows than its caller allows."""

    def __init__(self, rows: float, limit: float) -> None:
        self.rows, self.limit = rows, limit
        super().__init__(f"an estimated {rows:.3g} neighbour rows; the limit is {limit:.3g}")


PROBES = 64               # points whose neighbours estimate a slice's rows
TOTAL_PROBES = 2000       # ... and all the rows of a search


def estimate(tree, radius: float, lo: int = 0, hi: int | None = None,
             probes: int = TOTAL_PROBES) -> float:
    """Estimated rows (ordered pairs within ``radius``, each point with itself included) of
    the points lo..hi of the tree against all of it: the mean count of ``probes`` of them,
    evenly spread, times their number."""
    hi = tree.n if hi is None else hi
    if hi <= lo:
        return 0.0
    idx = np.unique(np.linspace(lo, hi - 1, min(probes, hi - lo)).astype(np.int64))
    found = tree.query_ball_point(tree.data[idx], radius, return_length=True)
    return float(np.mean(found)) * (hi - lo)


def neighbours(tree, radius: float, rows: int, most: int
               ) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """(i, j): for consecutive slices of the tree's points (by index), every point i of the
    slice with every point j within ``radius`` (i itself included), in increasing i; each
    slice at most ``most`` points and, unless a single point has more, about ``rows`` pairs
    (estimated: :func:`estimate` with ``PROBES`` points)."""
    todo = [(lo, min(lo + most, tree.n)) for lo in range(0, tree.n, most)][::-1]
    while todo:
        lo, hi = todo.pop()
        if hi - lo > 1 and estimate(tree, radius, lo, hi, PROBES) > rows:
            mid = (lo + hi) // 2
            todo += [(mid, hi), (lo, mid)]
            continue
        near = tree_of(tree.data[lo:hi]).sparse_distance_matrix(tree, radius,
                                                                output_type="ndarray")
        yield near["i"].astype(np.int64) + lo, near["j"].astype(np.int64)


AT_ONCE = 1 << 22         # pairs close_pairs asks of the tree at once (64 MB of indices)


def close_pairs(points: np.ndarray, radius: float, rows: int) -> Iterator[np.ndarray]:
    """Every unordered pair (u, v), u < v, of ``points`` within ``radius`` of each other, as
    arrays (k, 2) of at most about ``rows`` pairs: from one query when they are estimated at
    most ``AT_ONCE``, else from slices of the points by index (each pair from the slice of its
    smaller index)."""
    if len(points) < 2:
        return
    tree = tree_of(points)
    if (estimate(tree, radius) - len(points)) / 2 <= AT_ONCE:
        uv = tree.query_pairs(radius, output_type="ndarray")
        for lo in range(0, len(uv), rows):
            yield uv[lo:lo + rows]
        return
    for i, j in neighbours(tree, radius, 2 * rows, len(points)):
        keep = i < j
        yield np.stack([i[keep], j[keep]], axis=1)


WIDER = 1e-6              # cell_pairs' cells are this much (relative) wider than the radius
BLOCK = 1 << 14           # sorted points whose candidates cell_pairs gathers at once, at most


def cell_pairs(points: np.ndarray, radius: float, rows: int) -> Iterator[np.ndarray]:
    """Every unordered pair (u, v), u < v, of ``points`` that lie in one cell or in two
    neighbouring cells (of the 8 around) of a square grid of side radius·(1 + ``WIDER``), once
    each, as arrays (k, 2) of at most about ``rows`` pairs: a superset of :func:`close_pairs`'
    (two points within ``radius`` are at most one cell apart along x and along y, the cells'
    extra width far above the rounding of the coordinates), in the order of the cells, not the
    tree's. numpy only (no SciPy import): the points sorted by cell number (row by row), each
    paired with the points after it up to the end of the cell to its right, and with the
    points of the three cells above (a contiguous run of the sorted points), both found by
    binary search in a window of the sorted cell numbers. The crossing count's 2 million
    midpoints at 100 x 100 give 3.5 million candidate pairs, against the tree's 2.4 million,
    but cost less than the tree's build (NumPy's reductions along the first axis in cKDTree's
    constructor), its traversal past the 2 million neighbours along a course and SciPy's
    spatial import. A grid too fine for 64-bit cell numbers falls back to :func:`close_pairs`."""
    n = len(points)
    if n < 2:
        return
    x, y = points[:, 0], points[:, 1]
    inv = 1.0 / (radius * (1 + WIDER))
    x0, y0 = float(x.min()), float(y.min())
    cells = ((float(x.max()) - x0) * inv + 2) * ((float(y.max()) - y0) * inv + 2)
    if not cells < 2.0 ** 62:
        yield from close_pairs(points, radius, rows)
        return
    kind = np.int32 if cells < 2.0 ** 31 else np.int64
    ix = ((x - x0) * inv).astype(kind)
    nx = int(ix.max()) + 2           # an empty column right of the last: no row wraps over
    key = ((y - y0) * inv).astype(kind)
    key *= nx
    key += ix
    del ix
    order = np.argsort(key)
    key = key[order]
    for lo in range(0, n, BLOCK):
        at = np.arange(lo, min(lo + BLOCK, n))
        k = key[lo:lo + BLOCK]
        # the points after each up to the end of the cell to its right (cell + 1) ...
        a_hi = _sorted_find(key, k + 2, lo)
        # ... and the points of the three cells above (cell + nx − 1 ... cell + nx + 1)
        b_lo = _sorted_find(key, k + (nx - 1), lo)
        b_hi = _sorted_find(key, k + (nx + 2), lo)
        yield from _pairs_of(order, np.concatenate([at, at]), np.concatenate([at + 1, b_lo]),
                             np.concatenate([a_hi, b_hi]), rows)


def _sorted_find(key: np.ndarray, wanted: np.ndarray, lo: int) -> np.ndarray:
    """Where the sorted ``wanted`` (all at least key[lo]) would go into the sorted ``key``
    (searchsorted, left), searched in the window they span only."""
    first = lo + int(np.searchsorted(key[lo:], wanted[0]))
    last = first + int(np.searchsorted(key[first:], wanted[-1], "right"))
    return np.searchsorted(key[first:last], wanted) + first


def _pairs_of(order: np.ndarray, at: np.ndarray, lo: np.ndarray, hi: np.ndarray, rows: int
              ) -> Iterator[np.ndarray]:
    """The pairs of the sorted points ``at`` with the sorted points of their ranges [lo, hi),
    as original indices (u < v), at most about ``rows`` at a time (a single point more)."""
    count = np.cumsum(hi - lo)
    i = 0
    while i < len(at):
        j = max(i + 1, int(np.searchsorted(count, (count[i - 1] if i else 0) + rows, "right")))
        own, q = expand(lo[i:j], hi[i:j])
        u, v = order[at[i:j][own]], order[q]
        yield np.stack([np.minimum(u, v), np.maximum(u, v)], axis=1)
        i = j
