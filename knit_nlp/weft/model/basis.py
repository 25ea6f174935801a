"""The loop functions φ(s) of eq. (15) and the linear rows built from them (eqs. 11, 18-21).

A loop's tangent angle is θ(s) = a·φ(s) (eq. 14) with
φ(s) = [sin(2πks/L) for k=1..t, cos(2πks/L) for k=1..t, s, 1]  (2t+2 entries, that order).
"""
from __future__ import annotations

import numpy as np


def n_coeffs(t: int) -> int:
    """Number of loop parameters per loop, 2t+2 (eq. 16)."""
    return 2 * t + 2


def phi(s: np.ndarray | float, L: float, t: int) -> np.ndarray:
    """φ(s) of eq. (15), one row per s: shape (len(s), 2t+2)."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    k = np.arange(1, t + 1)
    arg = 2 * np.pi * np.outer(s, k) / L
    return np.hstack([np.sin(arg), np.cos(arg), s[:, None], np.ones((s.size, 1))])


def dphi(s: np.ndarray | float, L: float, t: int) -> np.ndarray:
    """dφ/ds, one row per s: θ'(s) = a·dφ(s) is the curvature."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    k = np.arange(1, t + 1)
    om = 2 * np.pi * k / L
    arg = np.outer(s, om)
    return np.hstack([om * np.cos(arg), -om * np.sin(arg), np.ones((s.size, 1)),
                      np.zeros((s.size, 1))])


def bending_diagonal(L: float, t: int) -> np.ndarray:
    """D with ∫₀ᴸ (θ' − θ0')² ds = Σ D_k (a − a0)_k² exactly (closed form of eq. 11).

    On [0, L] the derivatives of the Fourier terms are orthogonal to each other and to the
    constant derivative of the linear term: ∫(2πk/L)² cos² = ∫(2πk/L)² sin² = (2πk)²/(2L),
    ∫1² = L; the constant term a^{2t+2} has no curvature.
    """
    k = np.arange(1, t + 1)
    four = (2 * np.pi * k) ** 2 / (2 * L)
    return np.concatenate([four, four, [L, 0.0]])


def continuity_rows(L: float, t: int) -> tuple[np.ndarray, np.ndarray]:
    """Rows (E, S) with continuity (18)-(19) reading E·a_ij − S·a_i,j+1 = 0.

    Row 0 is the angle θ, row 1 the curvature θ', at s = L (E) and s = 0 (S).
    """
    end = np.vstack([phi(L, L, t), dphi(L, L, t)])
    start = np.vstack([phi(0.0, L, t), dphi(0.0, L, t)])
    return end, start
