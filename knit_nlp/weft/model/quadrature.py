"""Gauss–Legendre panels on [0, L] for the position integrals of eq. (1), and the integrals by
any fixed rule (:func:`rule_integrals`, written once for numbers and CasADi).

The panels break at every material point whose position the model needs, so each position is
a cumulative sum of whole-panel integrals and converges with the node count like the rule itself.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from .basis import phi


@dataclass(frozen=True)
class PanelRule:
    """Nodes and weights on [0, L] and the cumulative weight matrix.

    ``cumulative[p] @ f(nodes)`` is ∫₀^{points[p]} f ds for the requested ``points``.
    """

    nodes: np.ndarray
    weights: np.ndarray
    points: np.ndarray
    nodes_per_panel: int
    point_panels: np.ndarray

    @property
    def cumulative(self) -> np.ndarray:
        """Dense (points × nodes) matrix: row p holds the weights of all panels ending by s_p."""
        panel_end = np.repeat(np.arange(self.nodes.size // self.nodes_per_panel), self.nodes_per_panel)
        return (panel_end[None, :] < self.point_panels[:, None]) * self.weights[None, :]

    def integrate(self, values: np.ndarray) -> np.ndarray:
        """∫₀^{s_p} f ds for every point from f at the nodes (axis 0); memory O(nodes)."""
        panels = (self.weights[:, None] * values.reshape(self.nodes.size, -1)).reshape(
            -1, self.nodes_per_panel, values.reshape(self.nodes.size, -1).shape[1]).sum(axis=1)
        cum = np.vstack([np.zeros((1, panels.shape[1])), np.cumsum(panels, axis=0)])
        return cum[self.point_panels].reshape((self.points.size,) + values.shape[1:])


def rule_integrals(Phi: Any, W: Any, A: Any, cos: Callable, sin: Callable,
                   mtimes: Callable) -> tuple[Any, Any, Any, Any]:
    """The integrals of eq. (1) by a fixed rule for loops with coefficients A (nc × N): θ = Φ·A
    at the rule's nodes (Φ: nodes × nc, eq. 14), then W·cos θ and W·sin θ (W: one row of node
    weights per integral: the cumulative panel weights to each material point,
    ``PanelRule.cumulative``, or each cell's weights, ``contact.curves``). Written once for
    numbers (``np.cos``, ``np.sin``, ``np.matmul``) and for CasADi (``ca.cos``, ``ca.sin``,
    ``ca.mtimes`` with Φ and W as ``ca.DM``); returns cos θ, sin θ and the two integrals
    (integrals × N)."""
    theta = mtimes(Phi, A)
    c, s = cos(theta), sin(theta)
    return c, s, mtimes(W, c), mtimes(W, s)


def panel_rule(points: np.ndarray | list[float], L: float, nodes_per_panel: int,
               max_panel: float | None = None) -> PanelRule:
    """A composite Gauss–Legendre rule on [0, L] with breakpoints at ``points``.

    Panels longer than ``max_panel`` (default L/4) are split evenly.
    """
    points = np.asarray(points, dtype=float)
    if np.any(points < 0) or np.any(points > L):
        raise ValueError("quadrature points must lie in [0, L]")
    max_panel = L / 4 if max_panel is None else max_panel
    breaks = np.unique(np.concatenate([[0.0, L], points]))
    edges = [breaks[0]]
    for lo, hi in zip(breaks[:-1], breaks[1:]):
        if hi - lo < 1e-12 * L:
            continue
        pieces = int(np.ceil((hi - lo) / max_panel - 1e-9))
        edges.extend(np.linspace(lo, hi, pieces + 1)[1:])
    edges = np.asarray(edges)
    x, w = np.polynomial.legendre.leggauss(nodes_per_panel)
    half = 0.5 * np.diff(edges)
    mid = 0.5 * (edges[:-1] + edges[1:])
    nodes = (mid[:, None] + half[:, None] * x[None, :]).ravel()
    weights = (half[:, None] * w[None, :]).ravel()
    point_panels = np.searchsorted(edges, points + 1e-12 * L, side="right") - 1
    return PanelRule(nodes, weights, points, nodes_per_panel, point_panels)


def positions(coeffs: np.ndarray, s: np.ndarray | list[float], L: float, t: int,
              nodes_per_panel: int = 24) -> np.ndarray:
    """Displacements x(s) − x(0), y(s) − y(0) along loops (the integrals of eq. 1).

    ``coeffs`` is one loop (2t+2,) or many (N, 2t+2); the result is (len(s), 2) or (N, len(s), 2).
    A numpy reference with fine panels, used for natural geometry, sampling and checks.
    """

    s = np.atleast_1d(np.asarray(s, dtype=float))
    many = np.ndim(coeffs) == 2
    a = np.atleast_2d(coeffs)
    rule = panel_rule(s, L, nodes_per_panel, max_panel=L / 16)
    theta = phi(rule.nodes, L, t) @ a.T                      # (nodes, N)
    xy = np.stack([rule.integrate(np.cos(theta)), rule.integrate(np.sin(theta))], axis=-1)
    xy = np.transpose(xy, (1, 0, 2))                         # (N, len(s), 2)
    return xy if many else xy[0]
