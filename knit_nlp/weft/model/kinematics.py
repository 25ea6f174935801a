"""Per-loop positions of eq. (1) as a small CasADi Function, mapped over the fabric.

For one loop with coefficients a, ``loop_displacements`` returns ∫₀^{s_p}(cos θ, sin θ) ds for the
requested material points s_p, with θ = Φ·a evaluated at all quadrature nodes at once and the
integrals as one product with the cumulative weight matrix (vector operations, so the Function
and its derivatives stay small).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from .basis import n_coeffs, phi
from .quadrature import panel_rule, rule_integrals


def loop_displacements(L: float, t: int, points: np.ndarray, nodes_per_panel: int) -> ca.Function:
    """Function a (2t+2) -> D (2 × P): displacement from the loop start to each point s_p."""
    rule = panel_rule(points, L, nodes_per_panel)
    a = ca.MX.sym("a", n_coeffs(t))
    _, _, dx, dy = rule_integrals(ca.DM(phi(rule.nodes, L, t)), ca.DM(rule.cumulative), a,
                                  ca.cos, ca.sin, ca.mtimes)
    return ca.Function("loop_displacements", [a], [ca.horzcat(dx, dy).T], ["a"], ["D"])


class LoopIntegrals:
    """The same per-loop integrals in closed form on numbers, with their derivatives, for many
    loops at once (the condensed reduced model assembles its derivatives from these).

    θ = Φa at the quadrature nodes, D = W·(cos θ, sin θ) with W the cumulative weights, so
    ∂D_x/∂a = −W diag(sin θ) Φ, ∂D_y/∂a = W diag(cos θ) Φ and
    Σ_p μ_p·∇²D_p = Φᵀ diag(−cos θ·Wᵀμ_x − sin θ·Wᵀμ_y) Φ.
    """

    def __init__(self, L: float, t: int, points: np.ndarray, nodes_per_panel: int) -> None:
        rule = panel_rule(points, L, nodes_per_panel)
        self.Phi = phi(rule.nodes, L, t)                                  # Q × nc
        self.W = rule.cumulative                                          # P × Q
        self.PhiPhi = np.einsum("qa,qb->qab", self.Phi, self.Phi).reshape(len(rule.nodes), -1)

    def values(self, A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """θ at the nodes (N × Q) and D (N × P × 2) for coefficients A (N × nc), by the rule
        ``loop_displacements`` evaluates in CasADi (``quadrature.rule_integrals``)."""
        theta = A @ self.Phi.T
        _, _, dx, dy = rule_integrals(self.Phi, self.W, A.T, np.cos, np.sin, np.matmul)
        return theta, np.stack([dx.T, dy.T], axis=-1)

    def jacobians(self, theta: np.ndarray) -> np.ndarray:
        """∂D/∂a per loop, (N × P × 2 × nc)."""
        sin, cos = np.sin(theta), np.cos(theta)
        J = np.empty((theta.shape[0], self.W.shape[0], 2, self.Phi.shape[1]))
        for p, w in enumerate(self.W):                  # one (N × Q)(Q × nc) product per point
            J[:, p, 0] = -(sin * w) @ self.Phi
            J[:, p, 1] = (cos * w) @ self.Phi
        return J

    def weighted_hessians(self, theta: np.ndarray, mu: np.ndarray) -> np.ndarray:
        """Σ_p μ_p·∇²D_p per loop (N × nc × nc) for adjoints μ (N × P × 2)."""
        omega = -(np.cos(theta) * (mu[:, :, 0] @ self.W) + np.sin(theta) * (mu[:, :, 1] @ self.W))
        nc = self.Phi.shape[1]
        return (omega @ self.PhiPhi).reshape(-1, nc, nc)
