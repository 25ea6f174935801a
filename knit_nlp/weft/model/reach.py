"""Grips no configuration can satisfy, found before any solve.

The yarn of one course is inextensible (eq. 1: every loop's centreline has length L, and the
loops of a course chain end to start), so two held material points of one course, at arc
coordinates a and b along it, can never be more than |a − b| apart; a target that asks for more
has no feasible configuration, and IPOPT would spend its whole time limit discovering it.
Between courses only the interlocking springs act (eqs. 6-7), which stretch without bound, so no
such limit exists there; but a yarn path still bounds what a pull asks of them
(:func:`yarn_distances`): the shortest path between two held points along the yarns and across
the crossings (each spring at its natural length) is d, so targets D apart stretch the springs
on every such path by at least D − d in all. In a model whose interlocks do not stretch,
D > d has no configuration (:func:`out_of_reach_through_interlocks`); in the paper's model a
stretch beyond a loop length is named before the solve (:func:`overstretch`).

A load needs something to push against: a net force along a coordinate no clamp or rigid clamp
holds has no equilibrium (the energy is unbounded below along that translation).
"""
from __future__ import annotations

from collections import defaultdict
from typing import Any, NamedTuple, Protocol, Sequence

import numpy as np

SLACK = 1e-9        # relative: a target pair exactly taut (a straight yarn) is still reachable
SOURCES = 48        # held points the yarn-path bound searches paths from (each a Dijkstra)


class Grips(Protocol):
    """What this module reads of a weft problem (the problem reader calls it, so it cannot
    import the problem's class)."""

    clamps: Sequence[Any]
    loads: Sequence[Any]
    rigid_clamps: Sequence[Any]
    units: Any

    @property
    def L(self) -> float: ...

    def natural_position(self, loop: tuple[int, int], s: float) -> np.ndarray: ...


def yarn_between(a: tuple[tuple[int, int], float], b: tuple[tuple[int, int], float],
                 L: float) -> float | None:
    """The length of yarn between material points a and b, each ((course, wale), s), when they
    lie on one course (the loops of a course chain end to start: arc (wale − 1)·L + s); None
    on different courses (only springs join those)."""
    (la, sa), (lb, sb) = a, b
    if la[0] != lb[0]:
        return None
    return abs((la[1] - 1) * L + sa - (lb[1] - 1) * L - sb)


class Held(NamedTuple):
    """One held material point ((course, wale), s), where it must go, which coordinates are
    held, and what holds it (file table, key, point)."""

    loop: tuple[int, int]
    s: float
    target: np.ndarray
    fix: tuple[bool, bool]
    table: str
    key: str
    where: str


def held_points(pr: Grips, targets: np.ndarray, rigid: np.ndarray) -> list[Held]:
    """The held points of ``pr`` at clamp ``targets`` (clamps, 2) and rigid motions ``rigid``
    (rigid clamps, 3: tx, ty, rotation)."""
    out = []
    for q, c in enumerate(pr.clamps):
        if any(c.fix):
            out.append(Held(c.loop, c.s, targets[q], c.fix,
                            c.table or f"clamp {q + 1}", c.key,
                            f"loop {list(c.loop)} {c.point}"))
    for k, rc in enumerate(pr.rigid_clamps):
        tx, ty, phi = rigid[k]
        R = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
        for q, (loop, label, s) in enumerate(rc.points):
            p0 = pr.natural_position(loop, s)
            out.append(Held(loop, s, rc.centre + R @ (p0 - rc.centre) + [tx, ty], (True, True),
                            f"rigid_clamp[{k + 1}]", "translation",
                            f"loop {list(loop)} {label}"))
    return out


def out_of_reach(pr: Grips, targets: np.ndarray, rigid: np.ndarray
                 ) -> tuple[str, str, str] | None:
    """(table, key, message) of the first pair of held points of one course whose targets are
    farther apart than the yarn between them, or None when every pair is within reach."""
    by_course: dict[int, list[Held]] = defaultdict(list)
    for h in held_points(pr, targets, rigid):
        by_course[h.loop[0]].append(h)
    for _, pts in sorted(by_course.items()):
        for a in range(len(pts)):
            for b in range(a + 1, len(pts)):
                found = _pair(pts[a], pts[b], pr)
                if found:
                    return found
    return None


def _pair(p: Held, q: Held, pr: Grips) -> tuple[str, str, str] | None:
    both = [d for d in range(2) if p.fix[d] and q.fix[d]]
    if not both:
        return None
    yarn = yarn_between((p.loop, p.s), (q.loop, q.s), pr.L)
    apart = float(np.linalg.norm((q.target - p.target)[both]))
    if apart <= yarn * (1 + SLACK) + SLACK * pr.L:
        return None
    unit = pr.units.length
    what = "apart" if len(both) == 2 else f"apart in {'xy'[both[0]]}"
    return (q.table, q.key,
            f"is out of reach: {q.where} and {p.where} ({p.table}) lie on course {q.loop[0]} "
            f"with {yarn:.6g} {unit} of inextensible yarn between them, but their targets are "
            f"{apart:.6g} {unit} {what}; move the targets closer (at most {yarn:.6g} {unit})")


def unheld_force(pr: Grips, forces: np.ndarray) -> tuple[str, str, str] | None:
    """(table, key, message) when the loads' net force has a component along a coordinate that
    no clamp or rigid clamp holds (no equilibrium exists), else None."""
    if not len(pr.loads):
        return None
    held = [bool(pr.rigid_clamps) or any(c.fix[d] for c in pr.clamps) for d in range(2)]
    net = np.sum(forces, axis=0)
    scale = max(float(np.abs(forces).max()), 1e-300)
    for d in range(2):
        if not held[d] and abs(net[d]) > 1e-12 * scale:
            first = next(ld for ld, f in zip(pr.loads, forces) if f[d] != 0)
            return (first.table or "load", "force",
                    f"has no equilibrium: the loads' net {'xy'[d]} force is {net[d]:.6g} "
                    f"{pr.units.force} and nothing holds the fabric in {'xy'[d]}; add a "
                    f"[[clamp]] (fix = [\"{'xy'[d]}\"] or both) or a [[rigid_clamp]], or "
                    "balance the loads")
    return None


def unreachable(pr: Grips, targets: np.ndarray, rigid: np.ndarray, forces: np.ndarray
                ) -> tuple[str, str, str] | None:
    """(table, key, message) of the first grip no configuration satisfies at these clamp
    targets, rigid motions and load forces (:func:`out_of_reach`, :func:`unheld_force`)."""
    return out_of_reach(pr, targets, rigid) or unheld_force(pr, forces)


def yarn_distances(pr: Grips, points: Sequence[tuple[tuple[int, int], float]],
                   sources: np.ndarray | None = None) -> np.ndarray:
    """(sources, k) shortest path lengths from ``points[sources]`` (default all) to the k
    material points ((course, wale), s) along the yarns
    (each course one yarn, arc (wale − 1)·L + s) and across the crossing springs at their
    natural length (B of loop (i + 1, j) to E of (i, j), R to H: |B0E0|, |R0H0|, eqs. 6-8);
    inf between points no path joins (no crossings: one course, or none found)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra
    m, n, L, c = pr.courses, pr.wales, pr.L, pr.crossings
    course = [p[0][0] for p in points]
    arc = [(p[0][1] - 1) * L + p[1] for p in points]
    rows: list[np.ndarray] = []
    if c is not None and m >= 2:
        i, j = np.meshgrid(np.arange(1, m + 1), np.arange(1, n + 1), indexing="ij")
        for label in "BERH":
            course += list(i.ravel())
            arc += list((j.ravel() - 1) * L + c.s[label])
    course_a, arc_a = np.array(course), np.array(arc, dtype=float)
    k, size = len(points), len(course)
    order = np.lexsort((arc_a, course_a))                      # along each course in turn
    same = course_a[order][1:] == course_a[order][:-1]
    a, b = order[:-1][same], order[1:][same]
    w = arc_a[b] - arc_a[a]
    if size > k:
        block = m * n                                          # node k + label·mn + (i−1)·n + j−1
        upper = np.arange(n, m * n)                            # loops (i + 1, j), 0-based flat
        lower = upper - n                                      # loops (i, j)
        for up, low, rest in (("B", "E", c.rest_left), ("R", "H", c.rest_right)):
            ia, ib = "BERH".index(up), "BERH".index(low)
            a = np.r_[a, k + ia * block + upper]
            b = np.r_[b, k + ib * block + lower]
            w = np.r_[w, np.full(upper.size, float(np.linalg.norm(rest)))]
    graph = coo_matrix((np.maximum(w, 1e-300), (a, b)), shape=(size, size)).tocsr()
    return dijkstra(graph, directed=False,
                    indices=np.arange(k) if sources is None else sources)[:, :k]


def _worst_stretch(pr: Grips, targets: np.ndarray, rigid: np.ndarray
                   ) -> tuple[float, float, float, Held, Held] | None:
    """(D − d, D, d, p, q) of the pair of held points on different courses, held in a common
    coordinate, with the largest D − d: D their targets' distance (in the common coordinates),
    d the yarn path between them; None without such a pair. Paths are searched from at most
    ``SOURCES`` held points: those in the pairs with the largest D − D₀ (D₀ their natural
    distance, a lower bound of d: the natural fabric realises every path at its length)."""
    held = held_points(pr, targets, rigid)
    if len(held) < 2 or pr.crossings is None:
        return None
    T = np.array([h.target for h in held])
    F = np.array([h.fix for h in held], dtype=bool)
    X = np.array([pr.natural_position(h.loop, h.s) for h in held])
    course = np.array([h.loop[0] for h in held])
    both = F[:, None, :] & F[None, :, :]
    apart = np.sqrt(np.sum(np.where(both, T[None] - T[:, None], 0.0) ** 2, axis=-1))
    ok = both.any(-1) & (course[:, None] != course[None])
    if not ok.any():
        return None
    bound = np.where(ok, apart - np.linalg.norm(X[None] - X[:, None], axis=-1), -np.inf)
    sources = _sources(bound)
    dist = yarn_distances(pr, [(h.loop, h.s) for h in held], sources)
    need = np.where(ok[sources] & np.isfinite(dist), apart[sources] - dist, -np.inf)
    a, b = np.unravel_index(int(np.argmax(need)), need.shape)
    if not np.isfinite(need[a, b]):
        return None
    p, q = sorted((int(sources[a]), int(b)))                  # q: the later table, named
    return float(need[a, b]), float(apart[p, q]), float(dist[a, b]), held[p], held[q]


def _sources(bound: np.ndarray) -> np.ndarray:
    """Held points to search paths from: all of them up to ``SOURCES``, else those first met
    in the pairs of largest ``bound`` (an upper bound of D − d)."""
    k = bound.shape[0]
    if k <= SOURCES:
        return np.arange(k)
    order = np.argsort(-bound, axis=None)[: SOURCES * k]
    rows = np.unravel_index(order, bound.shape)[0]
    return np.array(list(dict.fromkeys(rows.tolist()))[:SOURCES])


def overstretch(pr: Grips, targets: np.ndarray, rigid: np.ndarray) -> str | None:
    """One line when the targets ask the crossing springs (paper's model) to stretch by more
    than a loop length L in all along every yarn path between two held points, else None."""
    found = _worst_stretch(pr, targets, rigid)
    if found is None or found[0] <= pr.L:
        return None
    need, apart, path, p, q = found
    unit = pr.units.length
    return (f"{q.where} ({q.table}) and {p.where} ({p.table}) are to be {apart:.6g} {unit} "
            f"apart, but the shortest path along the yarns and across the crossings is "
            f"{path:.6g} {unit}: the crossing springs on it must stretch by {need:.6g} {unit} "
            f"({need / pr.L:.3g} loop lengths) in all, which the paper's springs allow but no "
            "knitted fabric does; expect a long solve and a fabric pulled apart")


def out_of_reach_through_interlocks(pr: Grips, targets: np.ndarray, rigid: np.ndarray
                                    ) -> tuple[str, str, str] | None:
    """(table, key, message) of the held pair whose targets are farther apart than the
    shortest yarn path between them, for a model whose interlocks do not stretch (D > d has
    no configuration there), else None."""
    found = _worst_stretch(pr, targets, rigid)
    if found is None:
        return None
    _, apart, path, p, q = found
    if apart <= path * (1 + SLACK) + SLACK * pr.L:
        return None
    unit = pr.units.length
    return (q.table, q.key, f"is out of reach: {q.where} and {p.where} ({p.table}) are joined "
            f"by at most {path:.6g} {unit} of yarn through the interlocks, but their targets "
            f"are {apart:.6g} {unit} apart; move the targets closer")
