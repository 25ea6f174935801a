"""Designed zones that follow their crossings: where an interlock's crossing has slid along the
yarns, the pieces around it may come as close as they like, as around the natural crossing.

natural.py gives each designed crossing a box fixed in material coordinates (the natural
crossing ± z along both yarns). The crossing count (crossings.judge) lets a designed crossing
slide along its yarns, even past a loop's end. Under a large pull the yarns slide through an
interlock by more than z (the 30 x 30 diagonal pull: course 1 by 5.6 length units through the
loops above the pulled corner); the pieces at the slid crossing are then outside every natural
box, their required gap 2r cannot hold (the distance is zero at a crossing), and every load
step failed on them as "deep pairs". Here each current crossing that the count accepts as
designed gets its own box (built by ``crossings.designed_zones``: this module imports nothing
of the contact package but natural.py and ranges.py, so that pairs.py can take zones): the
pieces within z of it along both yarns, z = max(2r / sin α, ``SLIDE``·L) with α the crossing's
current angle (the natural boxes' rule), but at most ``WIDEST``·L: a crossing that has turned
nearly tangent does not free whole loops around it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .natural import SLIDE
from .ranges import expand

WIDEST = 0.5               # a zone's half-width is at most this many loop lengths


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
        out = np.zeros(ca.size, dtype=bool)
        if self.z.size == 0 or ca.size == 0:
            return out.reshape(ca.shape)
        # zones sorted by (course pair, S_A) on one axis (course pairs ``span`` apart); each
        # query's candidates lie within the widest half-width of it on that axis, with a margin
        # far above the axis's rounding error (a superset); then the course pair and each
        # zone's own half-width along both yarns decide
        span = 4.0 * float(max(np.abs(self.Sa).max(), np.abs(Sa).max(), 1.0))
        top = int(max(self.cb.max(), cb.max())) + 1
        axis = (self.ca * top + self.cb) * span + self.Sa
        order = np.argsort(axis)
        axis = axis[order]
        q = (ca.ravel() * top + cb.ravel()) * span + Sa.ravel()
        reach = float(self.z.max()) * (1 + 1e-9) + 1e-9 * span * top * top
        lo = np.searchsorted(axis, q - reach, side="left")
        hi = np.searchsorted(axis, q + reach, side="right")
        owner, rows = expand(lo, hi)
        j = order[rows]
        inside = (self.ca[j] == ca.ravel()[owner]) & (self.cb[j] == cb.ravel()[owner]) & (
            np.abs(Sa.ravel()[owner] - self.Sa[j]) <= self.z[j]) & (
            np.abs(Sb.ravel()[owner] - self.Sb[j]) <= self.z[j])
        out[owner[inside]] = True
        return out.reshape(ca.shape)


def half_width(radius: float, sin_angle: np.ndarray, L: float) -> np.ndarray:
    """A zone's half-width along both yarns: max(2r / sin α, ``SLIDE``·L), at most
    ``WIDEST``·L (module docstring)."""
    return np.clip(2 * radius / np.maximum(sin_angle, 1e-3), SLIDE * L, WIDEST * L)
