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
from .quadrature import panel_rule


def loop_displacements(L: float, t: int, points: np.ndarray, nodes_per_panel: int) -> ca.Function:
    """Function a (2t+2) -> D (2 × P): displacement from the loop start to each point s_p."""
    rule = panel_rule(points, L, nodes_per_panel)
    a = ca.MX.sym("a", n_coeffs(t))
    theta = ca.mtimes(ca.DM(phi(rule.nodes, L, t)), a)
    trig = ca.horzcat(ca.cos(theta), ca.sin(theta))
    disp = ca.mtimes(ca.DM(rule.cumulative), trig).T
    return ca.Function("loop_displacements", [a], [disp], ["a"], ["D"])
