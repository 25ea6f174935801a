"""Closed-form derivatives of the full weft NLP, handed to IPOPT instead of CasADi's AD.

The only nonlinear terms are the per-loop integrals of eq. (1),
D_p(a) = Σ_q C_pq (cos θ_q, sin θ_q), θ = Φ·a at the quadrature nodes (C the cumulative
weights); the constraints are affine in the variables and D, g = G_x·x + G_D·vec(D) + g_0(p),
and the objective is quadratic (eqs. 6-12). Hence

- ∂D_p/∂a = Σ_q C_pq (−sin θ_q, cos θ_q) φ_qᵀ: per loop and coefficient one product
  C·(trig ∘ Φ_i), for all loops at once;
- ∇²(λᵀg) on loop k's coefficients = Φᵀ diag(w_k) Φ with μ = G_Dᵀλ,
  w_k = −(Cᵀμ_x,k ∘ cos θ_k + Cᵀμ_y,k ∘ sin θ_k): one dense product Ψ·w over all loops, Ψ the
  products φ_i φ_j (i ≤ j) at the nodes.

G_x and G_D are constant sparse matrices read off CasADi's own (affine) constraint expression,
so the assembly follows ``full``'s constraints without restating them.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..model.basis import n_coeffs, phi
from ..model.quadrature import panel_rule
from .full import FullNLP


def closed_form_derivatives(wnlp: FullNLP) -> dict[str, ca.Function]:
    """``jac_g`` and ``hess_lag`` Functions for ``casadi.nlpsol``."""
    pr, nlp = wnlp.problem, wnlp.nlp
    x, p = nlp["x"], nlp["p"]
    N, nc = pr.n_loops, n_coeffs(pr.t)
    rule = panel_rule(np.array(wnlp.eval_points), pr.L, pr.quadrature_nodes)
    P = rule.points.size
    Phi, C = rule_matrices(rule, pr.L, pr.t)
    Gx, GD = _affine_parts(wnlp)
    coeffs = wnlp.x.slice("coeffs")
    A = ca.reshape(x[coeffs], nc, N)
    theta = ca.mtimes(ca.DM(Phi), A)                             # Q × N
    cos, sin = ca.cos(theta), ca.sin(theta)

    # Jacobian: ∂vec(D)/∂vec(A), nonzeros ordered loop, coefficient, point, x/y (column-major)
    Cd = ca.DM(C)
    cols = []
    for i in range(nc):
        Ci = ca.DM(C * Phi[:, i][None, :])                         # C·diag(Φ_i)
        jx = -ca.mtimes(Ci, sin)
        jy = ca.mtimes(Ci, cos)
        cols.append(ca.reshape(ca.vertcat(ca.reshape(jx, 1, P * N), ca.reshape(jy, 1, P * N)),
                               2 * P, N))
    nz = ca.vec(ca.vertcat(*cols))
    Jd = ca.MX(_jd_sparsity(N, P, nc, coeffs.start, wnlp.x.size), nz)
    g = nlp["g"]
    jac = Gx + ca.mtimes(GD, Jd)
    jac_g = ca.Function("nlp_jac_g", [x, p], [g, jac], ["x", "p"], ["g", "jac_g_x"])

    # Hessian of the Lagrangian (upper triangle)
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.numel())
    mu = ca.reshape(ca.mtimes(GD.T, lam_g), 2, P * N)
    W = ca.mtimes(Cd.T, ca.reshape(mu[0, :], P, N))
    V = ca.mtimes(Cd.T, ca.reshape(mu[1, :], P, N))
    w = -(W * cos + V * sin)                                       # Q × N
    iu, ju = triu_pairs(nc)
    Psi = ca.DM(Phi[:, iu] * Phi[:, ju]).T                         # T × Q
    Hg = ca.MX(block_triu_sparsity(N, nc, coeffs.start, wnlp.x.size), ca.vec(ca.mtimes(Psi, w)))
    Hf = ca.triu(ca.hessian(nlp["f"], x)[0])
    hess = lam_f * Hf + Hg
    hess_lag = ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [hess],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    return {"jac_g": jac_g, "hess_lag": hess_lag}


def rule_matrices(rule, L: float, t: int) -> tuple[np.ndarray, np.ndarray]:
    """Φ at the nodes (Q × 2t+2) and the cumulative weights C (P × Q) of a panel rule."""
    return phi(rule.nodes, L, t), rule.cumulative


def _affine_parts(wnlp: FullNLP) -> tuple[ca.DM, ca.DM]:
    """G_x = ∂g/∂x and G_D = ∂g/∂vec(D) (constant: g is affine in x and D)."""
    nlp, D = wnlp.nlp, wnlp.displacements
    Dsym = ca.MX.sym("D", D.shape[0], D.shape[1])
    g = ca.graph_substitute(nlp["g"], [D], [Dsym])
    if ca.depends_on(ca.jacobian(g, ca.vertcat(nlp["x"], ca.vec(Dsym))),
                     ca.vertcat(nlp["x"], ca.vec(Dsym))):
        raise ValueError("constraints are not affine in the variables and D")
    f = ca.Function("G", [nlp["x"], Dsym, nlp["p"]], [ca.jacobian(g, nlp["x"]), ca.jacobian(g, Dsym)])
    Gx, GD = f(np.zeros(wnlp.x.size), np.zeros(D.shape), wnlp.p0)
    return ca.sparsify(Gx), ca.sparsify(GD)


def _jd_sparsity(N: int, P: int, nc: int, offset: int, nx: int) -> ca.Sparsity:
    """Rows vec(D) (2·N·P), columns x: loop k's 2P rows × its nc coefficient columns."""
    k, i, r = np.meshgrid(np.arange(N), np.arange(nc), np.arange(2 * P), indexing="ij")
    rows = (k * 2 * P + r).ravel()
    cols = (offset + k * nc + i).ravel()
    return ca.Sparsity.triplet(2 * N * P, nx, rows.tolist(), cols.tolist())


def triu_pairs(nc: int) -> tuple[np.ndarray, np.ndarray]:
    """(row, column) of the upper triangle of an nc × nc block in column-major order."""
    pairs = [(i, j) for j in range(nc) for i in range(j + 1)]
    return np.array([i for i, _ in pairs]), np.array([j for _, j in pairs])


def block_triu_sparsity(N: int, nc: int, offset: int, nx: int) -> ca.Sparsity:
    """Upper triangles of the N coefficient blocks on the diagonal of the x × x Hessian."""
    iu, ju = triu_pairs(nc)
    base = offset + np.arange(N)[:, None] * nc
    rows, cols = (base + iu).ravel(), (base + ju).ravel()
    return ca.Sparsity.triplet(nx, nx, rows.tolist(), cols.tolist())
