"""The natural 3-D loop (docs/weft3d.md, "Natural 3-D shape"): its data and the plain-knit
topology; ``natural_fit`` constructs it.

**The order.** A stitch is drawn through the loop below from the back to the front (+z is the
technical face). Its legs therefore lie in front of the head of the loop below (C/F and Q/G:
upper over), and its foot, the sinker loop, lies behind the legs of the loop below (A/D and S/P:
upper under). Legs in front, heads and sinker loops behind: the face shows the V's, the back the
purl bumps.

**The contacts.** The projections of a loop and the loop below cross four times (PAIRS); in
three dimensions each pair of neighbouring crossings (A/D with C/F, Q/G with S/P) is one place
where the upper yarn wraps the lower one, and each wrap is one persistent contact (WRAPS).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..basis import n_coeffs, phi
from ..natural_loop import NaturalLoop
from .crossing_contact import separation
from .curve3d import positions3d, tangent

# (upper label, lower label, order): +1 where the upper course's yarn is in front (+z)
PAIRS = (("A", "D", -1), ("C", "F", +1), ("Q", "G", +1), ("S", "P", -1))
# the interlock contacts: the upper loop wraps the lower one at its left and its right side
WRAPS = ("A/D+C/F", "Q/G+S/P")


class NaturalShapeError(ValueError):
    """No natural 3-D loop was found for these values."""


@dataclass(frozen=True)
class Natural3D:
    """The natural 3-D loop: θ coefficients ``coeffs`` (2t+2), elevation coefficients
    ``elevation`` (2q+2); the interlock contacts' (``labels``: the four designed crossings of
    a thin yarn, or the two wraps) closest points on the upper and the lower loop (``s_upper``, ``s_lower``) and their natural separations ``h0``; the designed
    crossings of the projections (PAIRS: ``cross_upper``, ``cross_lower``, ``order``, +1 upper
    over); the lattice (w, c); ``projection_rms``: the RMS distance of the projection from the
    paper's loop."""

    length: float
    harmonics: int
    modes: int
    radius: float
    coeffs: np.ndarray
    elevation: np.ndarray
    s_upper: np.ndarray
    s_lower: np.ndarray
    h0: np.ndarray
    cross_upper: np.ndarray
    cross_lower: np.ndarray
    order: np.ndarray
    wale_spacing: float
    course_spacing: float
    projection_rms: float

    def xyz(self, s: np.ndarray | list[float]) -> np.ndarray:
        """Positions (len(s), 3) along the natural loop from its start."""
        return positions3d(self.coeffs, self.elevation, s, self.length, self.harmonics,
                           self.modes)

    def tangents(self, s: np.ndarray) -> np.ndarray:
        """Unit tangents (len(s), 3) along the natural loop (S1)."""
        L, t, q = self.length, self.harmonics, self.modes
        return np.stack(tangent(phi(s, L, t) @ self.coeffs, phi(s, L, q) @ self.elevation), 1)

    def crossing_signs(self) -> np.ndarray:
        """ς of each contact of a loop (S6): the sign that makes its separation h positive in
        the natural state, the loop one course up over the loop."""
        up = self.xyz(self.s_upper) + [0.0, self.course_spacing, 0.0]
        h, _ = separation(up, self.tangents(self.s_upper), self.xyz(self.s_lower),
                          self.tangents(self.s_lower), np.ones(self.s_upper.size))
        return np.sign(h)

    def starts(self, m: int, n: int) -> np.ndarray:
        """Natural loop starts (m, n, 3): the lattice at z = 0."""
        i, j = np.meshgrid(np.arange(m), np.arange(n), indexing="ij")
        return np.stack([j * self.wale_spacing, i * self.course_spacing, 0.0 * i], axis=-1)

    @property
    def labels(self) -> tuple[str, ...]:
        """Each contact's name: the designed crossings (PAIRS, thin yarns) or the wraps."""
        if self.s_upper.size == len(PAIRS):
            return tuple(f"{u}/{lo}" for u, lo, _ in PAIRS)
        return WRAPS

    def separations(self) -> np.ndarray:
        """Centreline distance at each interlock contact's closest points (h0)."""
        up = self.xyz(self.s_upper) + [0.0, self.course_spacing, 0.0]
        return np.linalg.norm(up - self.xyz(self.s_lower), axis=1)


def flat(natural: NaturalLoop, modes: int, radius: float) -> Natural3D:
    """The planar natural loop with φ₀ = 0, for fabrics without crossings (one course)."""
    none = np.zeros(0)
    return Natural3D(natural.length, natural.harmonics, modes, radius, natural.coeffs.copy(),
                     np.zeros(n_coeffs(modes)), none, none, none, none, none, none,
                     natural.wale_spacing, natural.course_spacing, 0.0)
