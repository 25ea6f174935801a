"""The natural (unloaded) loop and the natural configuration of the fabric.

Default preset ``jersey``: θ0(s) = ω sin(2πs/L), L = 10, ω = 2 rad; wale spacing w = x(L) − x(0),
loop height H = max y − min y, course spacing c = H/2 (docs/weft_model.md, "Natural state").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .basis import dphi, n_coeffs
from .quadrature import positions

PRESETS = ("jersey", "straight")
JERSEY_OMEGA = 2.0


@dataclass(frozen=True)
class NaturalLoop:
    """The unloaded loop shared by every loop of the fabric.

    ``coeffs`` a0 (2t+2,), ``wale_spacing`` w = x(L) − x(0), ``rise`` y(L) − y(0), ``height`` H,
    ``course_spacing`` c (given, or H/2).
    """

    length: float
    harmonics: int
    coeffs: np.ndarray
    wale_spacing: float
    rise: float
    height: float
    course_spacing: float

    def xy(self, s: np.ndarray | list[float]) -> np.ndarray:
        """Positions along the natural loop from its start, shape (len(s), 2)."""
        return positions(self.coeffs, s, self.length, self.harmonics)

    @property
    def is_straight(self) -> bool:
        """True when the natural loop has no curvature anywhere (a straight rod)."""
        s = np.linspace(0.0, self.length, 65)
        return bool(np.allclose(dphi(s, self.length, self.harmonics) @ self.coeffs, 0.0))


def preset_coeffs(preset: str, t: int) -> np.ndarray:
    """Natural coefficients of a named preset for t harmonics."""
    a0 = np.zeros(n_coeffs(t))
    if preset == "jersey":
        a0[0] = JERSEY_OMEGA
    elif preset != "straight":
        raise ValueError(f"unknown preset {preset!r}")
    return a0


def natural_loop(coeffs: np.ndarray, length: float, harmonics: int,
                 course_spacing: float | None = None) -> NaturalLoop:
    """Measure the natural loop: w, rise, H (on a fine grid refined near the extremes), c."""
    coeffs = np.asarray(coeffs, dtype=float)
    s = np.linspace(0.0, length, 2001)
    xy = positions(coeffs, s, length, harmonics)
    height = _refined_extent(coeffs, length, harmonics, s, xy[:, 1])
    end = xy[-1]
    spacing = height / 2 if course_spacing is None else course_spacing
    return NaturalLoop(length, harmonics, coeffs, float(end[0]), float(end[1]), height, spacing)


def _refined_extent(coeffs: np.ndarray, L: float, t: int, s: np.ndarray, y: np.ndarray) -> float:
    """max y − min y, each extreme polished by golden-section search around the grid extreme."""
    def polish(k: int, sign: float) -> float:
        lo, hi = s[max(k - 1, 0)], s[min(k + 1, s.size - 1)]
        g = (np.sqrt(5) - 1) / 2
        for _ in range(60):
            a, b = hi - g * (hi - lo), lo + g * (hi - lo)
            ya, yb = positions(coeffs, [a, b], L, t)[:, 1] * sign
            lo, hi = (lo, b) if ya > yb else (a, hi)
        return float(positions(coeffs, [0.5 * (lo + hi)], L, t)[0, 1])
    return polish(int(np.argmax(y)), 1.0) - polish(int(np.argmin(y)), -1.0)


def natural_starts(loop: NaturalLoop, m: int, n: int) -> np.ndarray:
    """Start points of every loop in the natural configuration, shape (m, n, 2).

    Loop (i, j) starts at ((j−1)·w, (i−1)·c) plus (j−1) times the loop's rise (zero for jersey).
    """
    i, j = np.meshgrid(np.arange(m), np.arange(n), indexing="ij")
    return np.stack([j * loop.wale_spacing, i * loop.course_spacing + j * loop.rise], axis=-1)
