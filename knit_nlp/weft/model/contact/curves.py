"""Loop centrelines at arbitrary material points, on numbers: the positions of eq. (1) by the
cell rule below, the same rule the contact rows of the NLP use (so lifted contact points start
exactly on their rows), and their tangent angles.

P(k, s) = X_k + ∫₀ˢ (cos θ_k, sin θ_k) du with θ_k(u) = φ(u)·a_k (eqs. 14-15). [0, L] is cut
into :func:`cells` equal cells of width h; s lies in cell j = ⌊s/h⌋ (clipped to the first and
last), and the integral is the sum of the whole cells before j (each by ``NODES`` Gauss nodes,
shared by every point of the loop) plus the partial cell [j h, s] by ``NODES`` Gauss nodes
scaled to it (:func:`partial_cell`, written once for these numbers and the contact rows'
CasADi expressions). s may lie a little outside [0, L] (the formula continues the loop smoothly);
contact uses that for feet just past a loop's end.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import Any, Callable

import numpy as np

from ..basis import basis_at, basis_terms, dbasis_at
from ..quadrature import rule_integrals

NODES = 8           # Gauss-Legendre nodes per cell


def cells(t: int) -> int:
    """Equal cells on [0, L] for t harmonics: 8 for t <= 3, growing with t. Measured on loops
    with θ = 2 sin(2πu/L) (the natural jersey's) plus random coefficients of every harmonic
    (sd 0.4; t = 3, L = 10, s in [-0.3, L + 0.3]): 8 cells of 8 nodes err by 1.6e-8, as the
    composite rule on [0, s] this replaced (4 panels of 12 nodes: 3.7e-8); 8 cells of 6 nodes
    by 5.5e-6."""
    return max(8, -(-8 * t // 3))


@lru_cache(maxsize=16)
def cell_rule(t: int) -> tuple[int, np.ndarray, np.ndarray]:
    """Cells M, and nodes ξ and weights w of one cell's rule on [0, 1] (Σ w = 1)."""
    x, w = np.polynomial.legendre.leggauss(NODES)
    return cells(t), (x + 1.0) / 2.0, w / 2.0


def cell_nodes(L: float, t: int) -> tuple[np.ndarray, np.ndarray]:
    """The whole cells' nodes u on [0, L], shape (cells, NODES), and their weights h·w."""
    M, xi, w = cell_rule(t)
    h = L / M
    return (np.arange(M)[:, None] + xi) * h, h * w


@lru_cache(maxsize=16)
def cell_weights(L: float, t: int) -> tuple[np.ndarray, np.ndarray]:
    """φ at every whole cell's nodes (cells·NODES × 2t+2) and the weights W (cells ×
    cells·NODES, row i: cell i's h·w) with which ``quadrature.rule_integrals`` gives each
    cell's increment ΔI_i of eq. (1), here and in the contact rows (``transcription.contact``)."""
    u, hw = cell_nodes(L, t)
    Phi, W = basis_at(u.ravel(), L, t), np.kron(np.eye(len(u)), hw[None, :])
    Phi.setflags(write=False)               # shared by every caller (cached)
    W.setflags(write=False)
    return Phi, W


def cell_of(s: np.ndarray, L: float, t: int) -> np.ndarray:
    """The cell j of each material point s (integers; points before 0 or past L take the
    first or last cell)."""
    M = cells(t)
    return np.clip(np.floor(np.asarray(s, dtype=float) * M / L), 0, M - 1).astype(int)


@dataclass(frozen=True)
class PartialCell:
    """The partial cell [start, s] of eq. (1) at n points (rows 1 × n, nodes × points Q × n):
    its length ℓ = s − start, φ's terms at the nodes start + ℓ·ξ_q (eq. 15, one Q × n matrix
    per coefficient), cos θ and sin θ there, and the integral ℓ·Σ_q w_q (cos θ_q, sin θ_q)."""

    length: Any
    terms: list
    cos: Any
    sin: Any
    dx: Any
    dy: Any


def partial_cell(start: Any, s: Any, A: Any, L: float, t: int, sin: Callable, cos: Callable,
                 mtimes: Callable, rows: Callable) -> PartialCell:
    """The partial cell of the cell rule (module docstring) at n points: ``start`` and ``s``
    rows 1 × n (the cell's start and the material point), ``A`` the points' loop
    coefficients nc × n. Written once for numbers (:meth:`Curves.points`: ``np.sin``,
    ``np.cos``, ``np.matmul`` and ``rows`` broadcasting) and for the contact rows' CasADi
    expressions (``transcription.contact``: ``ca.sin``, ``ca.cos``, ``ca.mtimes`` and ``rows``
    by ``ca.repmat``); ``rows(v, Q)`` is the row v at each of the Q nodes."""
    _, xi, w = cell_rule(t)
    Q = len(xi)
    length = s - start
    nodes = rows(start, Q) + mtimes(xi[:, None], length)
    terms = basis_terms(nodes, L, t, sin, cos, np.ones((Q, s.shape[1])))
    theta = sum(rows(A[c:c + 1, :], Q) * term for c, term in enumerate(terms))
    c, sn = cos(theta), sin(theta)
    return PartialCell(length, terms, c, sn, length * mtimes(w[None, :], c),
                       length * mtimes(w[None, :], sn))


def _broadcast_rows(v: np.ndarray, _nodes: int) -> np.ndarray:
    """``partial_cell``'s ``rows`` for numbers: numpy broadcasts a 1 × n row itself."""
    return v


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

    @cached_property
    def prefix(self) -> np.ndarray:
        """∫ from 0 to each cell's start, every loop: (N, cells + 1, 2), by the cell rule."""
        Phi, W = cell_weights(self.L, self.t)
        _, _, dx, dy = rule_integrals(Phi, W, self.coeffs.T, np.cos, np.sin, np.matmul)
        inc = np.stack([dx.T, dy.T], axis=-1)                          # (N, M, 2)
        return np.concatenate([np.zeros((len(self.coeffs), 1, 2)), np.cumsum(inc, axis=1)],
                              axis=1)

    def points(self, k: np.ndarray, s: np.ndarray) -> np.ndarray:
        """Positions P(k, s), shape k.shape + (2,), by the cell rule."""
        k, s = np.broadcast_arrays(np.asarray(k), np.asarray(s, dtype=float))
        j = cell_of(s, self.L, self.t)
        start = j * (self.L / cells(self.t))
        part = partial_cell(start.reshape(1, -1), s.reshape(1, -1), self.coeffs.T[:, k.ravel()],
                            self.L, self.t, np.sin, np.cos, np.matmul,
                            _broadcast_rows)
        inc = np.stack([part.dx[0], part.dy[0]], axis=-1).reshape(s.shape + (2,))
        return self.starts[k] + (self.prefix[k, j] + inc)

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
