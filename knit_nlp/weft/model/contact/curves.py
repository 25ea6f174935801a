"""Loop centrelines at arbitrary material points, on numbers: the positions of eq. (1) by a
composite Gauss-Legendre rule scaled to [0, s], the same rule the contact rows of the NLP use
(so lifted contact points start exactly on their rows), and their tangent angles.

P(k, s) = X_k + ∫₀ˢ (cos θ_k, sin θ_k) du with θ_k(u) = φ(u)·a_k (eqs. 14-15): the integral is
s·Σ_q w_q (cos θ_k(s ξ_q), sin θ_k(s ξ_q)) with nodes ξ_q and weights w_q of :func:`panels`
equal panels of ``NODES`` Gauss nodes on [0, 1].
s may lie a little outside [0, L] (the formula continues the loop smoothly); contact uses that
for feet just past a loop's end.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

NODES = 12          # Gauss-Legendre nodes per panel


def panels(t: int) -> int:
    """Equal panels on [0, s] for t harmonics: 4 for t <= 3, growing with t. Measured on loops
    with random coefficients of all harmonics (t = 3, L = 10, s up to L): 4 panels of 12 nodes
    err by 2e-9, 8 panels of 12 by 3e-15 (4 of 8: 1.6e-5)."""
    return max(4, -(-4 * t // 3))


@lru_cache(maxsize=16)
def unit_rule(t: int) -> tuple[np.ndarray, np.ndarray]:
    """Nodes ξ and weights w of the composite rule on [0, 1] (Σ w = 1) for t harmonics."""
    panels_, nodes = panels(t), NODES
    x, w = np.polynomial.legendre.leggauss(nodes)
    left = np.arange(panels_)[:, None] / panels_
    xi = (left + (x[None, :] + 1.0) / (2 * panels_)).ravel()
    return xi, np.tile(w / (2 * panels_), panels_)


def basis_at(u: np.ndarray, L: float, t: int) -> np.ndarray:
    """φ(u) of eq. (15) for an array u of any shape: shape u.shape + (2t+2,)."""
    u = np.asarray(u, dtype=float)
    arg = 2 * np.pi * u[..., None] * np.arange(1, t + 1) / L
    return np.concatenate([np.sin(arg), np.cos(arg), u[..., None], np.ones(u.shape + (1,))],
                          axis=-1)


def dbasis_at(u: np.ndarray, L: float, t: int) -> np.ndarray:
    """dφ/du for an array u: shape u.shape + (2t+2,); θ' = a·dφ is the curvature."""
    u = np.asarray(u, dtype=float)
    om = 2 * np.pi * np.arange(1, t + 1) / L
    arg = u[..., None] * om
    return np.concatenate([om * np.cos(arg), -om * np.sin(arg), np.ones(u.shape + (1,)),
                           np.zeros(u.shape + (1,))], axis=-1)


@dataclass(frozen=True)
class Curves:
    """The centrelines of a fabric state: coefficients (N, 2t+2) and starts (N, 2) by loop
    index k = (i−1)·n + (j−1), with the loop length L and harmonics t."""

    coeffs: np.ndarray
    starts: np.ndarray
    L: float
    t: int

    @classmethod
    def of(cls, coeffs: np.ndarray, starts: np.ndarray, L: float) -> "Curves":
        """From (m, n, 2t+2) coefficients and (m, n, 2) starts."""
        nc = coeffs.shape[-1]
        return cls(coeffs.reshape(-1, nc), starts.reshape(-1, 2), L, (nc - 2) // 2)

    def angle(self, k: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Tangent angles θ_k(s) (eq. 14)."""
        return np.einsum("...c,...c->...", basis_at(s, self.L, self.t), self.coeffs[k])

    def curvature(self, k: np.ndarray, s: np.ndarray) -> np.ndarray:
        """θ'_k(s), the signed curvature."""
        return np.einsum("...c,...c->...", dbasis_at(s, self.L, self.t), self.coeffs[k])

    def points(self, k: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Positions P(k, s), shape k.shape + (2,), by the composite rule on [0, s]."""
        k, s = np.broadcast_arrays(np.asarray(k), np.asarray(s, dtype=float))
        xi, w = unit_rule(self.t)
        nodes = s[..., None] * xi                                    # (..., Q)
        theta = np.einsum("...qc,...c->...q", basis_at(nodes, self.L, self.t),
                          self.coeffs[k])
        disp = s[..., None] * np.stack([np.cos(theta) @ w, np.sin(theta) @ w], axis=-1)
        return self.starts[k] + disp

    def frames(self, k: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, unit tangents and signed curvatures at (k, s)."""
        th = self.angle(k, s)
        return self.points(k, s), np.stack([np.cos(th), np.sin(th)], axis=-1), \
            self.curvature(k, s)

    def sampled(self, samples: int) -> tuple[np.ndarray, np.ndarray]:
        """Every loop at ``samples`` evenly spaced s in [0, L]: points (N, samples, 2), s."""
        s = np.linspace(0.0, self.L, samples)
        k = np.repeat(np.arange(len(self.coeffs)), samples).reshape(-1, samples)
        return self.points(k, np.broadcast_to(s, k.shape)), s
