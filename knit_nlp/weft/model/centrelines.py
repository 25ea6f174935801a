"""Sampled centrelines: each loop's points at evenly spaced s, from coefficients and starts (eq. 1)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .basis import n_coeffs
from .quadrature import positions

if TYPE_CHECKING:
    from .problem import WeftProblem

SAMPLES = 61


def centrelines(coeffs: np.ndarray, starts: np.ndarray, L: float, t: int,
                samples: int = SAMPLES) -> tuple[np.ndarray, np.ndarray]:
    """Sampled centrelines (m, n, samples, 2) of every loop and the s-values used."""
    m, n = coeffs.shape[:2]
    s = np.linspace(0.0, L, samples)
    disp = positions(coeffs.reshape(m * n, n_coeffs(t)), s, L, t).reshape(m, n, samples, 2)
    return disp + starts[:, :, None, :], s


def natural_centrelines(pr: WeftProblem, samples: int = SAMPLES) -> np.ndarray:
    """Sampled centrelines (m, n, samples, 2) of the natural configuration (in the 3-D model
    the natural 3-D fabric projected, on its own lattice: docs/weft3d.md)."""
    if pr.yarn is not None and pr.yarn.spatial:
        s = np.linspace(0.0, pr.L, samples)
        return pr.natural_starts()[:, :, None, :] + pr.natural_xy(s)[None, None]
    coeffs = np.broadcast_to(pr.natural.coeffs, (pr.courses, pr.wales, n_coeffs(pr.t)))
    return centrelines(coeffs, pr.natural_starts(), pr.L, pr.t, samples)[0]
