"""A loop's centreline as an inextensible space curve (docs/weft3d.md, eqs. S1-S4).

The tangent at arc length s is (S1)

    T(s) = (cos φ cos θ, cos φ sin θ, sin φ),

θ(s) = a·Φ_t(s) the paper's in-plane angle (eq. 14) and φ(s) = b·Φ_q(s) the elevation, in the
same loop functions (``basis.phi``) with its own number of harmonics q. Positions are the
integrals of T (S2, the 3-D eq. 1), by the same Gauss–Legendre panels (``quadrature``); a
position at a *variable* material coordinate σ is the panel integral to a fixed s₀ plus a
Gauss rule mapped onto [s₀, σ] (S3), smooth in σ. Bending (S4):

    U_bend = ½ B ∫₀ᴸ [(cos φ θ′ − cos φ₀ θ₀′)² + (φ′ − φ₀′)²] ds,

κ² = φ′² + cos²φ θ′² split into its two components (the paper's eq. 11 when φ = φ₀ = 0).
"""
from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from ..basis import dphi, n_coeffs, phi
from ..quadrature import panel_rule


def tangent(theta: Any, elevation: Any, lib: Any = np) -> tuple[Any, Any, Any]:
    """The unit tangent (S1) from θ and φ (numpy arrays or CasADi expressions, ``lib``)."""
    c = lib.cos(elevation)
    return c * lib.cos(theta), c * lib.sin(theta), lib.sin(elevation)


def symbolic_phi(s: ca.SX | ca.MX, L: float, t: int) -> ca.SX | ca.MX:
    """``basis.phi`` at a symbolic scalar s, as a row (1 × 2t+2): the same loop functions
    (eq. 15), for a material coordinate that is a decision variable (tested equal)."""
    k = np.arange(1, t + 1)
    arg = ca.DM(2 * np.pi * k / L).T * s
    return ca.horzcat(ca.sin(arg), ca.cos(arg), s, 1)


def positions3d(a: np.ndarray, b: np.ndarray, s: np.ndarray | list[float], L: float, t: int,
                q: int, nodes_per_panel: int = 24) -> np.ndarray:
    """Displacements x(s) − x(0) (len(s), 3) of one loop, or (N, len(s), 3) of many (a, b with
    a leading loop axis): the numpy reference of (S2), fine panels as ``quadrature.positions``."""
    s = np.atleast_1d(np.asarray(s, dtype=float))
    many = np.ndim(a) == 2
    A, B = np.atleast_2d(a), np.atleast_2d(b)
    rule = panel_rule(s, L, nodes_per_panel, max_panel=L / 16)
    theta, elev = phi(rule.nodes, L, t) @ A.T, phi(rule.nodes, L, q) @ B.T   # (nodes, N)
    out = np.stack([rule.integrate(c) for c in tangent(theta, elev)], axis=-1)
    out = np.transpose(out, (1, 0, 2))
    return out if many else out[0]


def loop_displacements3d(L: float, t: int, q: int, points: np.ndarray,
                         nodes_per_panel: int) -> ca.Function:
    """Function (a, b) -> D (3 × P): displacement from the loop start to each point s_p (S2)
    by the panel rule of the planar model (``kinematics.loop_displacements``)."""
    rule = panel_rule(points, L, nodes_per_panel)
    a, b = ca.SX.sym("a", n_coeffs(t)), ca.SX.sym("b", n_coeffs(q))
    theta = ca.mtimes(ca.DM(phi(rule.nodes, L, t)), a)
    elev = ca.mtimes(ca.DM(phi(rule.nodes, L, q)), b)
    disp = ca.mtimes(ca.DM(rule.cumulative), ca.horzcat(*tangent(theta, elev, ca))).T
    return ca.Function("loop_displacements3d", [a, b], [disp], ["a", "b"], ["D"])


def segment(L: float, t: int, q: int, nodes: int = 8) -> ca.Function:
    """Function (a, b, s0, σ) -> (∫_{s0}^{σ} T ds (3), T(σ) (3)): the Gauss rule of ``nodes``
    points mapped onto [s0, σ] (S3), smooth in σ (exact to rounding for σ near s0)."""
    a, b = ca.SX.sym("a", n_coeffs(t)), ca.SX.sym("b", n_coeffs(q))
    s0, sig = ca.SX.sym("s0"), ca.SX.sym("sigma")
    xi, w = np.polynomial.legendre.leggauss(nodes)
    half = 0.5 * (sig - s0)
    total = ca.SX.zeros(3)
    for x_i, w_i in zip(xi, w):
        s_i = s0 + half * (1 + x_i)
        tx = tangent(ca.mtimes(symbolic_phi(s_i, L, t), a), ca.mtimes(symbolic_phi(s_i, L, q), b), ca)
        total += w_i * half * ca.vertcat(*tx)
    tang = ca.vertcat(*tangent(ca.mtimes(symbolic_phi(sig, L, t), a),
                               ca.mtimes(symbolic_phi(sig, L, q), b), ca))
    return ca.Function("segment", [a, b, s0, sig], [total, tang],
                       ["a", "b", "s0", "sigma"], ["delta", "tangent"])


def bending3d(L: float, t: int, q: int, nodes_per_panel: int) -> ca.Function:
    """Function (a, b, a0, b0, B) -> U_bend of one loop (S4) by Gauss–Legendre panels of at
    most L/8 (with φ = φ₀ = 0 it is eq. 11, whose closed form ``basis.bending_diagonal`` it
    equals to 1e-11 relative with 8 nodes: tested; panels of L/4 gave 8e-11)."""
    rule = panel_rule([], L, nodes_per_panel, max_panel=L / 8)
    a, b = ca.SX.sym("a", n_coeffs(t)), ca.SX.sym("b", n_coeffs(q))
    a0, b0, B = ca.SX.sym("a0", n_coeffs(t)), ca.SX.sym("b0", n_coeffs(q)), ca.SX.sym("B")
    P, dP = ca.DM(phi(rule.nodes, L, q)), ca.DM(dphi(rule.nodes, L, q))
    dT = ca.DM(dphi(rule.nodes, L, t))
    geo = ca.cos(ca.mtimes(P, b)) * ca.mtimes(dT, a) - ca.cos(ca.mtimes(P, b0)) * ca.mtimes(dT, a0)
    nor = ca.mtimes(dP, b - b0)
    u = 0.5 * B * ca.dot(ca.DM(rule.weights), geo ** 2 + nor ** 2)
    return ca.Function("bending3d", [a, b, a0, b0, B], [u], ["a", "b", "a0", "b0", "B"], ["U"])


def bending3d_numpy(a: np.ndarray, b: np.ndarray, a0: np.ndarray, b0: np.ndarray, L: float,
                    t: int, q: int, B: float, nodes_per_panel: int = 16) -> float:
    """(S4) on numbers, with finer panels: the check of :func:`bending3d`."""
    rule = panel_rule([], L, nodes_per_panel, max_panel=L / 16)
    el, el0 = phi(rule.nodes, L, q) @ b, phi(rule.nodes, L, q) @ b0
    geo = np.cos(el) * (dphi(rule.nodes, L, t) @ a) - np.cos(el0) * (dphi(rule.nodes, L, t) @ a0)
    nor = dphi(rule.nodes, L, q) @ (np.asarray(b) - np.asarray(b0))
    return float(0.5 * B * rule.weights @ (geo ** 2 + nor ** 2))
