"""Neighbour searches in bounded memory: the k-d tree queries of the crossing count and the pair
search, a bounded number of neighbour rows at a time.

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
