"""Grips no configuration can satisfy, found before any solve.

The yarn of one course is inextensible (eq. 1: every loop's centreline has length L, and the
loops of a course chain end to start), so two held material points of one course, at arc
coordinates a and b along it, can never be more than |a − b| apart; a target that asks for more
has no feasible configuration, and IPOPT would spend its whole time limit discovering it.
Between courses only the interlocking springs act (eqs. 6-7), which stretch without bound, so no
such limit exists there.

A load needs something to push against: a net force along a coordinate no clamp or rigid clamp
holds has no equilibrium (the energy is unbounded below along that translation).
"""
from __future__ import annotations

from collections import defaultdict
from typing import Any, NamedTuple, Protocol, Sequence

import numpy as np

SLACK = 1e-9        # relative: a target pair exactly taut (a straight yarn) is still reachable


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
