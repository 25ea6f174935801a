"""Closed-form Lagrangian Hessians of the 3-D model's per-loop elements, for all loops at once
(``elements.Element.hessian``; docs/weft3d.md "Cost").

Both per-loop terms are sums over quadrature nodes of a function of (θ, φ) or (θ′, φ, φ′) at the
node, each linear in the loop's coefficients (θ = Φa, θ′ = Φ′a, φ = Ψb, φ′ = Ψ′b, eqs. 14-15,
S1). Their Hessian in (a, b) is therefore Σ_q [basis_q] H_q [basis_q]ᵀ with a 2 × 2 (or 3 × 3)
node matrix H_q: one dense product K·h (K the products of basis columns at the nodes, a
constant; h the node matrices' entries, Q × N) per block, for every loop at once, instead of
CasADi's AD of each loop's scalar graph (measured: 45 000 SX operations per loop).

- Displacements (S2): ℓ = μᵀD = Σ_q ω_q·T_q with ω = Cᵀμ (C the cumulative weights), T the
  tangent (S1): h_θθ = −cos φ (ω_x cos θ + ω_y sin θ), h_θφ = sin φ (ω_x sin θ − ω_y cos θ),
  h_φφ = h_θθ − ω_z sin φ.
- Bending (S4): ℓ = μ ½B Σ_q w_q (u_q² + (φ′ − φ₀′)²_q), u = cos φ θ′ − cos φ₀ θ₀′:
  with ω = μBw, h_θ′θ′ = ω cos²φ, h_θ′φ = −ω sin φ (cos φ θ′ + u),
  h_φφ = ω (sin²φ θ′² − u cos φ θ′), h_φ′φ′ = ω.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..model.basis import dphi, phi
from ..model.quadrature import panel_rule


def _pairs(U: np.ndarray, V: np.ndarray, same: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(products U_i V_j at the nodes (pairs × Q), i, j) over i ≤ j when ``same``, else all."""
    ii, jj = np.meshgrid(np.arange(U.shape[1]), np.arange(V.shape[1]), indexing="ij")
    keep = (ii <= jj) if same else np.ones_like(ii, dtype=bool)
    i, j = ii[keep], jj[keep]
    return (U[:, i] * V[:, j]).T, i, j


class _Blocks:
    """The (a, a), (a, b), (b, b) blocks' constant products and local (row, col) indices."""

    def __init__(self, Ua: np.ndarray, Ub: np.ndarray) -> None:
        nc = Ua.shape[1]
        self.K, rows, cols = [], [], []
        for U, V, same, r0, c0 in ((Ua, Ua, True, 0, 0), (Ua, Ub, False, 0, nc),
                                   (Ub, Ub, True, nc, nc)):
            K, i, j = _pairs(U, V, same)
            self.K.append(ca.DM(K))
            rows.append(r0 + i)
            cols.append(c0 + j)
        self.rows, self.cols = np.concatenate(rows), np.concatenate(cols)

    def values(self, haa: ca.MX, hab: ca.MX, hbb: ca.MX) -> ca.MX:
        return ca.vertcat(*[ca.mtimes(K, h) for K, h in zip(self.K, (haa, hab, hbb))])


def displacement_hessian(L: float, t: int, q: int, points: np.ndarray, nodes_per_panel: int):
    """Hessian provider of ``curve3d.loop_displacements3d`` (module docstring)."""
    rule = panel_rule(points, L, nodes_per_panel)
    Phi, Psi, C = phi(rule.nodes, L, t), phi(rule.nodes, L, q), rule.cumulative
    P = C.shape[0]
    blocks = _Blocks(Phi, Psi)
    Phi_, Psi_, Ct = ca.DM(Phi), ca.DM(Psi), ca.DM(C.T)

    def hessian(args: list, mus: list) -> tuple[ca.MX, np.ndarray, np.ndarray]:
        A, B = args[0], args[1]
        N = A.shape[1]
        mu = mus[0]                                              # 3 × P·N
        wx, wy, wz = (ca.mtimes(Ct, ca.reshape(mu[c, :], P, N)) for c in range(3))
        th, el = ca.mtimes(Phi_, A), ca.mtimes(Psi_, B)
        ct, st, ce, se = ca.cos(th), ca.sin(th), ca.cos(el), ca.sin(el)
        haa = -ce * (wx * ct + wy * st)
        hab = se * (wx * st - wy * ct)
        return blocks.values(haa, hab, haa - wz * se), blocks.rows, blocks.cols

    hessian.variables = (0, 1)                  # local variables (a, b)
    return hessian


def displacement_jacobian(L: float, t: int, q: int, points: np.ndarray, nodes_per_panel: int):
    """Jacobian provider of ``curve3d.loop_displacements3d``: ∂D_p/∂a_i = Σ_q C_pq ∂T_q/∂θ Φ_qi
    (and in b with ∂T/∂φ and Ψ), each as panel integrals (one sparse product over the nodes)
    summed panel by panel to the points (C = cumulative sum ∘ panel weights): about 7 500
    operations per loop against 50 000 for AD of the element."""
    rule = panel_rule(points, L, nodes_per_panel)
    Q, P = rule.nodes.size, rule.points.size
    n_panels = Q // nodes_per_panel
    panel_of = np.repeat(np.arange(n_panels), nodes_per_panel)
    Wp = np.zeros((n_panels, Q))
    Wp[panel_of, np.arange(Q)] = rule.weights
    cum = (np.arange(n_panels)[None, :] < rule.point_panels[:, None]).astype(float)
    Phi, Psi = phi(rule.nodes, L, t), phi(rule.nodes, L, q)
    nc, nq = Phi.shape[1], Psi.shape[1]
    K = {name: ca.sparsify(ca.DM(np.vstack([Wp * B[:, i][None, :] for i in range(B.shape[1])])))
         for name, B in (("a", Phi), ("b", Psi))}
    S = {name: ca.sparsify(ca.DM(np.kron(np.eye(n), cum))) for name, n in (("a", nc), ("b", nq))}
    Phi_, Psi_ = ca.DM(Phi), ca.DM(Psi)
    comps = {"a": (0, 1), "b": (0, 1, 2)}
    rows, cols = [], []
    for name, n, c0 in (("a", nc, 0), ("b", nq, nc)):
        for comp in comps[name]:
            i, pt = np.meshgrid(np.arange(n), np.arange(P), indexing="ij")
            rows.append((3 * pt + comp).ravel())
            cols.append((c0 + i).ravel())
    rows, cols = np.concatenate(rows), np.concatenate(cols)

    def jacobian(args: list) -> tuple[ca.MX, np.ndarray, np.ndarray]:
        th, el = ca.mtimes(Phi_, args[0]), ca.mtimes(Psi_, args[1])
        ct, st, ce, se = ca.cos(th), ca.sin(th), ca.cos(el), ca.sin(el)
        dT = {"a": (-ce * st, ce * ct), "b": (-se * ct, -se * st, ce)}
        vals = [ca.mtimes(S[name], ca.mtimes(K[name], d)) for name in ("a", "b") for d in dT[name]]
        return ca.vertcat(*vals), rows, cols

    jacobian.variables = (0, 1)
    return jacobian


def bending_hessian(L: float, t: int, q: int, nodes_per_panel: int):
    """Hessian provider of ``curve3d.bending3d`` (module docstring)."""
    rule = panel_rule([], L, nodes_per_panel, max_panel=L / 8)
    dT, Ps, dPs = dphi(rule.nodes, L, t), phi(rule.nodes, L, q), dphi(rule.nodes, L, q)
    blocks = _Blocks(dT, Ps)
    # the (b, b) block's part from (φ′ − φ₀′)²: the products of Ψ′ columns
    Kd, _, _ = _pairs(dPs, dPs, True)
    Kd = ca.DM(Kd)
    dT_, Ps_, w = ca.DM(dT), ca.DM(Ps), ca.DM(rule.weights)

    def hessian(args: list, mus: list) -> tuple[ca.MX, np.ndarray, np.ndarray]:
        A, B, a0, b0, stiff = args
        N = A.shape[1]
        om = ca.mtimes(w, mus[0] * stiff)                          # Q × N
        tp, el = ca.mtimes(dT_, A), ca.mtimes(Ps_, B)
        c, s = ca.cos(el), ca.sin(el)
        g0 = ca.cos(ca.mtimes(Ps_, b0)) * ca.mtimes(dT_, a0)       # Q × 1
        u = c * tp - ca.repmat(g0, 1, N)
        haa = om * c ** 2
        hab = -om * s * (c * tp + u)
        hbb = om * (s ** 2 * tp ** 2 - u * c * tp)
        vals = blocks.values(haa, hab, hbb)
        nbb = Kd.shape[0]
        vals = ca.vertcat(vals[:-nbb, :], vals[-nbb:, :] + ca.mtimes(Kd, om))
        return vals, blocks.rows, blocks.cols

    hessian.variables = (0, 1)
    return hessian
