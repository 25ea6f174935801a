"""The loop functions φ(s) of eq. (15) and the linear rows built from them (eqs. 11, 18-21).

A loop's tangent angle is θ(s) = a·φ(s) (eq. 14) with
φ(s) = [sin(2πks/L) for k=1..t, cos(2πks/L) for k=1..t, s, 1]  (2t+2 entries, that order),
written once (:func:`basis_terms`) and evaluated on numbers (:func:`basis_at`, :func:`phi`) and
on CasADi matrices (``transcription.contact.basis_mx``).
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np


def n_coeffs(t: int) -> int:
    """Number of loop parameters per loop, 2t+2 (eq. 16)."""
    return 2 * t + 2


def basis_terms(u: Any, L: float, t: int, sin: Callable, cos: Callable, one: Any) -> list:
    """φ_c(u) of eq. (15) elementwise on u, one term per basis function in φ's order
    (sin 2πku/L for k = 1..t, cos 2πku/L for k = 1..t, u, 1; ``one`` is the last, of u's
    shape); the harmonics by the angle-addition recurrence (two trigonometric calls, not 2t).
    Written once for numpy arrays (:func:`basis_at`) and CasADi matrices
    (``transcription.contact.basis_mx``): ``sin``, ``cos`` are the library's."""
    c1, s1 = cos(2 * np.pi * u / L), sin(2 * np.pi * u / L)
    sins, coss = [s1], [c1]
    for _ in range(t - 1):
        sins.append(sins[-1] * c1 + coss[-1] * s1)
        coss.append(coss[-1] * c1 - sins[-2] * s1)
    return sins + coss + [u, one]


def basis_at(u: np.ndarray | float, L: float, t: int) -> np.ndarray:
    """φ(u) of eq. (15) for an array u of any shape: shape u.shape + (2t+2,)."""
    u = np.asarray(u, dtype=float)
    return np.stack(basis_terms(u, L, t, np.sin, np.cos, np.ones_like(u)), axis=-1)


def dbasis_at(u: np.ndarray | float, L: float, t: int) -> np.ndarray:
    """dφ/du for an array u: shape u.shape + (2t+2,); θ' = a·dφ is the curvature. From the
    terms of φ: d sin(ωu)/du = ω cos(ωu), d cos(ωu)/du = −ω sin(ωu)."""
    u = np.asarray(u, dtype=float)
    terms = basis_terms(u, L, t, np.sin, np.cos, np.ones_like(u))
    om = 2 * np.pi * np.arange(1, t + 1) / L
    return np.stack([w * c for w, c in zip(om, terms[t:2 * t])]
                    + [-w * s for w, s in zip(om, terms[:t])]
                    + [np.ones_like(u), np.zeros_like(u)], axis=-1)


def phi(s: np.ndarray | float, L: float, t: int) -> np.ndarray:
    """φ(s) of eq. (15), one row per s: shape (len(s), 2t+2)."""
    return basis_at(np.atleast_1d(np.asarray(s, dtype=float)), L, t)


def dphi(s: np.ndarray | float, L: float, t: int) -> np.ndarray:
    """dφ/ds, one row per s: θ'(s) = a·dφ(s) is the curvature."""
    return dbasis_at(np.atleast_1d(np.asarray(s, dtype=float)), L, t)


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
