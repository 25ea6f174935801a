"""Designed zones that follow their crossings: where an interlock's crossing has slid along the
yarns, the pieces around it may come as close as they like, as around the natural crossing.

natural.py gives each designed crossing a box fixed in material coordinates (the natural
crossing ± z along both yarns). The crossing count (crossings.judge) lets a designed crossing
slide along its yarns, even past a loop's end. Under a large pull the yarns slide through an
interlock by more than z (the 30 x 30 diagonal pull: course 1 by 5.6 length units through the
loops above the pulled corner); the pieces at the slid crossing are then outside every natural
box, their required gap 2r cannot hold (the distance is zero at a crossing), and every load
step failed on them as "deep pairs". Here each current crossing that the count accepts as
designed gets its own box: the pieces within z of it along both yarns, z = max(2r / sin α,
``SLIDE``·L) with α the crossing's current angle (the natural boxes' rule).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .crossings import Crossings, find_crossings, judge
from .curves import Curves
from .natural import SLIDE, NaturalFabric
from .pairs import Grid

SEPARATE = 1e7             # course index scale in the zone tree: different courses never meet
NEAREST = 8                # zones tested per point pair (crossings within reach of it)


@dataclass(frozen=True)
class Zones:
    """Boxes around current designed crossings, in course coordinates (course, arc S):
    centres (ca, Sa, cb, Sb) and half-widths z, stored in both orders."""

    ca: np.ndarray
    Sa: np.ndarray
    cb: np.ndarray
    Sb: np.ndarray
    z: np.ndarray

    def exempt(self, ca, Sa, cb, Sb) -> np.ndarray:
        """Whether each piece pair (course, arc) lies in a zone: within z of one crossing of
        the same two courses along both yarns."""
        ca, Sa, cb, Sb = np.broadcast_arrays(np.asarray(ca), np.asarray(Sa, dtype=float),
                                             np.asarray(cb), np.asarray(Sb, dtype=float))
        out = np.zeros(ca.shape, dtype=bool)
        if self.z.size == 0 or ca.size == 0:
            return out
        from scipy.spatial import cKDTree     # lazy, as in pairs.py
        tree = cKDTree(np.stack([self.ca * SEPARATE, self.cb * SEPARATE, self.Sa, self.Sb], 1))
        q = np.stack([ca.ravel() * SEPARATE, cb.ravel() * SEPARATE, Sa.ravel(), Sb.ravel()], 1)
        k = min(NEAREST, self.z.size)
        # the tree's bound is strict: widened a hair so that a box's edges belong to it
        _, idx = tree.query(q, k=k, p=np.inf,
                            distance_upper_bound=float(self.z.max()) * (1 + 1e-9))
        idx = idx.reshape(len(q), k)
        found = idx < self.z.size
        j = np.where(found, idx, 0)
        inside = found & (np.abs(Sa.ravel()[:, None] - self.Sa[j]) <= self.z[j]) & (
            np.abs(Sb.ravel()[:, None] - self.Sb[j]) <= self.z[j])
        return inside.any(axis=1).reshape(ca.shape)


def slid_zones(fab: NaturalFabric, curves: Curves, grid: Grid) -> Zones:
    """The zones of a state's designed crossings (:func:`designed_zones`)."""
    found = find_crossings(curves, grid)
    return designed_zones(fab, curves, grid, found,
                          judge(fab, found, grid.courses, grid.wales).new)


def designed_zones(fab: NaturalFabric, curves: Curves, grid: Grid, found: Crossings,
                   new: dict) -> Zones:
    """The zones of the crossings ``found`` on pairs of loops not in ``new`` (those the count
    finds with more crossings than their natural count)."""
    keep = np.array([(int(a), int(b)) not in new for a, b in zip(found.kA, found.kB)],
                    dtype=bool)
    kA, sA, kB, sB = found.kA[keep], found.sA[keep], found.kB[keep], found.sB[keep]
    sin = np.abs(np.sin(curves.angle(kA, sA) - curves.angle(kB, sB)))
    z = np.maximum(2 * fab.radius / np.maximum(sin, 1e-3), SLIDE * grid.L)
    n = grid.wales
    ca, Sa = kA // n, kA % n * grid.L + sA
    cb, Sb = kB // n, kB % n * grid.L + sB
    return Zones(np.concatenate([ca, cb]), np.concatenate([Sa, Sb]),
                 np.concatenate([cb, ca]), np.concatenate([Sb, Sa]), np.concatenate([z, z]))
