"""The interpolation reduction of eqs. (22)-(27) as a linear map from reduced to full parameters.

Representative courses i_1 = 1 < … < i_p = m and wales j_1 = 1 < … < j_q = n (the paper's corner
form is p = q = 2). Reduced parameters z, in this order: the sub-loop parameters â (2t each) of
every representative loop, course-major; then (a^{2t+1}, a^{2t+2}) of the representative loops in
wale 1. Then
- â_ij is piecewise bilinear over the representative grid (eq. 22; the paper's λ_i, μ_j of eq. 24
  on each cell);
- the last two coefficients of a_i1 are piecewise linear over the representative courses (eq. 23);
- the last two coefficients of every other loop follow from the continuity recursion (20)-(21)
  (eqs. 25-27 are this recursion with eq. 22 substituted), so continuity holds by construction.
Count: p·q·2t + 2p representative parameters (+ 2m course starts, which stay free).
"""
from __future__ import annotations

import numpy as np

from .basis import n_coeffs
from .parametrisation import Reduced
from .problem import WeftProblem


def hat_weights(index: int, reps: tuple[int, ...]) -> np.ndarray:
    """Piecewise-linear interpolation weights of 1-based ``index`` over representatives ``reps``."""
    if len(reps) == 1:
        return np.ones(1)
    eye = np.eye(len(reps))
    return np.array([np.interp(index, reps, eye[r]) for r in range(len(reps))])


def reduction_map(pr: WeftProblem, reduced: Reduced) -> np.ndarray:
    """T with vec(coeffs) = T·z, coeffs (2t+2 × N) column-major by loop k = (i−1)·n + (j−1)."""
    red = reduced.resolve(pr.courses, pr.wales)
    m, n, t, L = pr.courses, pr.wales, pr.t, pr.L
    nc, p, q = n_coeffs(t), len(red.courses), len(red.wales)
    nz = p * q * 2 * t + 2 * p
    hat_cols = np.arange(p * q * 2 * t).reshape(p, q, 2 * t)
    lin_cols = p * q * 2 * t + np.arange(2 * p).reshape(p, 2)
    kdiff = np.concatenate([2 * np.pi * np.arange(1, t + 1) / L, np.zeros(t)])
    cos_sum = np.concatenate([np.zeros(t), np.ones(t)])
    T = np.zeros((nc * m * n, nz))
    for i in range(1, m + 1):
        wi = hat_weights(i, red.courses)
        rows = []                                   # (nc × nz) per loop of this course
        for j in range(1, n + 1):
            vj = hat_weights(j, red.wales)
            a = np.zeros((nc, nz))
            for r in range(p):
                for c in range(q):
                    a[np.arange(2 * t), hat_cols[r, c]] += wi[r] * vj[c]
            if j == 1:
                for r in range(p):
                    a[2 * t, lin_cols[r, 0]] += wi[r]
                    a[2 * t + 1, lin_cols[r, 1]] += wi[r]
            else:
                prev = rows[-1]
                dhat = prev[:2 * t] - a[:2 * t]                        # â_ij − â_i,j+1
                a[2 * t] = kdiff @ dhat + prev[2 * t]                  # eq. (21)
                a[2 * t + 1] = cos_sum @ dhat + prev[2 * t] * L + prev[2 * t + 1]   # eq. (20)
            rows.append(a)
        for j, a in enumerate(rows):
            k = (i - 1) * n + j
            T[k * nc:(k + 1) * nc] = a
    return T
