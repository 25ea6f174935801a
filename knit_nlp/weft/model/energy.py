"""Stored energy of the fabric: crossing springs (eqs. 6-10) and yarn bending (eqs. 11-12).

Each term is a small CasADi Function for one spring pair or one loop; the NLP maps them over
the fabric and the results module evaluates the same Functions on numbers.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from .basis import bending_diagonal, dphi, n_coeffs
from .quadrature import panel_rule


def spring_pair_energy() -> ca.Function:
    """U = ½ Δzᵀ diag(k_a, k_b) Δz for one crossing spring pair (eqs. 6-8).

    Inputs: the spring vector from the upper loop's point to the lower loop's point (BE or RH),
    its natural value (B0E0 or R0H0), the frame rows (a; b) and k = (k_a, k_b).
    Δz = F·(vector − rest), F = [aᵀ; bᵀ].
    """
    vec, rest = ca.SX.sym("vector", 2), ca.SX.sym("rest", 2)
    frame, k = ca.SX.sym("frame", 2, 2), ca.SX.sym("k", 2)
    dz = ca.mtimes(frame, vec - rest)
    u = 0.5 * ca.dot(k, dz ** 2)
    return ca.Function("spring_pair_energy", [vec, rest, frame, k], [u],
                       ["vector", "rest", "frame", "k"], ["U"])


def bending_energy(L: float, t: int) -> ca.Function:
    """U_bend = ½ R_f Σ D_k (a − a0)_k² for one loop: eq. (11) in closed form (basis.bending_diagonal)."""
    a, a0, rf = ca.SX.sym("a", n_coeffs(t)), ca.SX.sym("a0", n_coeffs(t)), ca.SX.sym("R_f")
    d = ca.DM(bending_diagonal(L, t))
    u = 0.5 * rf * ca.dot(d, (a - a0) ** 2)
    return ca.Function("bending_energy", [a, a0, rf], [u], ["a", "a0", "R_f"], ["U"])


def bending_energy_quadrature(a: np.ndarray, a0: np.ndarray, L: float, t: int, R_f: float,
                              nodes_per_panel: int = 16) -> float:
    """Eq. (11) by Gauss–Legendre quadrature: the independent check of the closed form."""
    rule = panel_rule([], L, nodes_per_panel)
    kappa = dphi(rule.nodes, L, t) @ (np.asarray(a) - np.asarray(a0))
    return float(0.5 * R_f * rule.weights @ kappa ** 2)
