"""The contact rows added to the full weft NLP, with closed-form first and second derivatives.

A contact *slot* c holds one pair of material points: s_A on loop k_A and s_B on loop k_B, with
side σ (all three are NLP parameters, so the contact points move along the yarns between solves
without rebuilding anything; only the loops of a slot are structural). Its one row is the
signed normal gap, written directly in the loops' variables (no lifted variables: the KKT
system grows by one row per slot, not eleven):

    g_c = σ (P_A − P_B)·N(Θ) ≥ required_c,    N(Θ) = (−sin Θ, cos Θ),
    P_A = X_kA + I(a_kA; s_A),  P_B = X_kB + I(a_kB; s_B),  Θ = φ(s_B)·a_kB,

with I(a; s) = ∫₀ˢ (cos θ, sin θ) du, θ = φ(u)·a (eqs. 1, 14-15), by the cell rule of
``curves.py``: I = Σ_{i<j} ΔI_i(a) + ∫_{s_j}^{s}, the whole cells' increments ΔI_i computed
once per loop and shared by every slot on it (picked by a 0/1 mask per slot, U_i = [i < j],
also a parameter), the partial cell by NODES nodes per point. g_c is the distance between the
two points when P_A − P_B is normal to yarn B (the outer loop puts (s_A, s_B) on the closest
points). A slot not in use gets the bound −∞.

Derivatives (everything else in the NLP is handled by derivatives.py), with d = P_A − P_B,
T = (cos Θ, sin Θ), μ = λσ, v_S = ∂I_Sᵀ T:
- ∂I/∂a = Σ_i U_i ∂ΔI_i/∂a + ℓ Σ_q w_q (−sin θ_q, cos θ_q) φ(s_j + ℓ ξ_q)ᵀ, ℓ = s − s_j;
- ∂g/∂X_A = σN, ∂g/∂X_B = −σN, ∂g/∂a_A = σ ∂I_Aᵀ N, ∂g/∂a_B = −σ ∂I_Bᵀ N − σ (d·T) φ_B;
- λ∇²g: μ N·∂²I_A − μ N·∂²I_B on the loops' own blocks (∂²I = −∫ (cos θ, sin θ) φφᵀ, by
  the per-point and per-cell sums), + μ (v_B φ_Bᵀ + φ_B v_Bᵀ) − λ g φ_B φ_Bᵀ on (a_B, a_B),
  −μ T φ_Bᵀ on (X_A, a_B), μ T φ_Bᵀ on (X_B, a_B), −μ v_A φ_Bᵀ on (a_A, a_B): blocks between
  the two loops of a slot, summed where slots share them (and where k_A = k_B).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ...layout import Layout
from ..model.basis import n_coeffs
from ..model.contact.curves import basis_at, cell_of, cell_rule
from .derivatives import _block_triu_sparsity, _triu_pairs, closed_form_derivatives
from .full import FullNLP



@dataclass
class ContactNLP:
    """The full weft NLP of ``base`` with contact rows appended (parameters and rows; the
    variables are the base NLP's).

    Parameters: base p, then s_A, s_B, σ of every slot, then the cell masks U of A's and of B's
    points (cells × slots each). Rows: base g, then the gap rows (1 per slot).
    ``points`` maps (x, p) to the slots' P_A, P_B (2 × slots each) and Θ (1 × slots).
    """

    base: FullNLP
    kA: np.ndarray
    kB: np.ndarray
    nlp: dict
    nlpsol_options: dict
    x: Layout
    g: Layout
    gap_rows: slice
    points: ca.Function
    model: str = "full"
    extra_p: int = 0
    jacobian: ca.Function | None = field(default=None, repr=False)

    @property
    def problem(self):
        return self.base.problem

    @property
    def n_slots(self) -> int:
        return len(self.kA)

    @property
    def n_variables(self) -> int:
        return self.x.size

    @property
    def n_constraints(self) -> int:
        return self.g.size

    @property
    def params(self):
        return self.base.params

    @property
    def lbg(self) -> np.ndarray:
        """Bounds with no slot in use (each solve passes its own, :meth:`bounds`)."""
        return self.bounds(np.zeros(self.n_slots), np.zeros(self.n_slots, dtype=bool))[0]

    @property
    def ubg(self) -> np.ndarray:
        return self.bounds(np.zeros(self.n_slots), np.zeros(self.n_slots, dtype=bool))[1]

    def parameters(self, p_base: np.ndarray, sA: np.ndarray, sB: np.ndarray,
                   sigma: np.ndarray) -> np.ndarray:
        """The NLP's parameter vector (the cell masks computed from s_A and s_B)."""
        pr = self.problem
        M = cell_rule(pr.t)[0]
        masks = [(np.arange(M)[:, None] < cell_of(s, pr.L, pr.t)[None, :]).astype(float)
                 for s in (sA, sB)]
        return np.concatenate([p_base, sA, sB, sigma] + [m.ravel(order="F") for m in masks])

    def bounds(self, required: np.ndarray, used: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """lbg, ubg: the base rows' own bounds, gap ≥ required where a slot is used (no bound
        on an unused slot)."""
        nb = self.base.n_constraints
        lbg, ubg = np.zeros(self.n_constraints), np.zeros(self.n_constraints)
        lbg[:nb], ubg[:nb] = self.base.lbg, self.base.ubg
        lbg[self.gap_rows] = np.where(used, required, -np.inf)
        ubg[self.gap_rows] = np.inf
        return lbg, ubg

    def lift(self, x_base: np.ndarray, sA: np.ndarray, sB: np.ndarray) -> np.ndarray:
        """A decision vector from a base one: the same (the contact rows lift nothing)."""
        return np.array(x_base, dtype=float)

    def lift_multipliers(self, xval: np.ndarray, sigma: np.ndarray,
                         lam_gap: np.ndarray) -> np.ndarray:
        """Multipliers of lifting rows: there are none."""
        return np.zeros(0)

    def gaps(self, xval: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Signed normal gaps of every slot at a decision vector and parameter vector."""
        return np.asarray(ca.Function("gaps", [self.nlp["x"], self.nlp["p"]],
                                      [self.nlp["g"][self.gap_rows]])(xval, params)).ravel()


def build_contact_nlp(base: FullNLP, kA: np.ndarray, kB: np.ndarray) -> ContactNLP:
    """The base NLP with one contact slot per entry of (kA, kB), closed-form derivatives."""
    if base.model != "full":
        raise ValueError("contact is built on the full model")
    kA, kB = np.asarray(kA, dtype=int), np.asarray(kB, dtype=int)
    n, nx0, ng0, np0 = len(kA), base.n_variables, base.n_constraints, base.p.size
    M = cell_rule(base.problem.t)[0]
    extra = (3 + 2 * M) * n
    x = ca.MX.sym("x", nx0)
    p = ca.MX.sym("p", np0 + extra)
    pb = p[:np0]
    f_base = ca.Function("f_base", [base.nlp["x"], base.nlp["p"]], [base.nlp["f"]])
    g_base = ca.Function("g_base", [base.nlp["x"], base.nlp["p"]], [base.nlp["g"]])
    sA, sB, sigma = p[np0:np0 + n], p[np0 + n:np0 + 2 * n], p[np0 + 2 * n:np0 + 3 * n]
    masks = ca.reshape(p[np0 + 3 * n:], M, 2 * n)
    geo = _Geometry(base, x, sA, sB, sigma, kA, kB, (masks[:, :n], masks[:, n:]))
    g = ca.vertcat(g_base(x, pb), geo.gap)
    xl = Layout()
    for name, (_, _, shape) in base.x.blocks.items():
        xl.add(name, *shape)
    gl = Layout()
    for name, (_, _, shape) in base.g.blocks.items():
        gl.add(name, *shape)
    gap_rows = gl.add("contact_gap", n, 1)
    nlp = {"x": x, "p": p, "f": f_base(x, pb), "g": g}
    derivs = _derivatives(base, geo, x, p, g, ng0, n)
    points = ca.Function("contact_points", [x, p], [geo.PA, geo.PB, geo.Th],
                         ["x", "p"], ["P_A", "P_B", "Theta"])
    return ContactNLP(base, kA, kB, nlp, derivs, xl, gl, gap_rows, points, extra_p=extra,
                      jacobian=derivs["jac_g"])


class _Geometry:
    """Symbolic pieces shared by the rows and their derivatives, vectorised over the points
    (nodes × points matrices; measured 2x faster to evaluate than a small SX Function mapped
    over the points), and the loops' whole-cell increments (nodes × loops)."""

    def __init__(self, base: FullNLP, x: ca.MX, sA: ca.MX, sB: ca.MX, sigma: ca.MX,
                 kA: np.ndarray, kB: np.ndarray, masks: tuple[ca.MX, ca.MX]) -> None:
        pr = base.problem
        n = len(kA)
        nc, N, L, t = n_coeffs(pr.t), pr.n_loops, pr.L, pr.t
        A = ca.reshape(x[base.x.slice("coeffs")], nc, N)
        X = ca.reshape(x[base.x.slice("starts")], 2, N)
        self.n, self.nc, self.kA, self.kB = n, nc, kA, kB
        M, xi, w = cell_rule(t)
        self.w = ca.DM(w)
        self.cells = _Cells(A, L, t)
        self.sides = []
        Q = len(xi)
        for k, s, U in ((kA, sA, masks[0]), (kB, sB, masks[1])):
            srow = ca.transpose(s)
            sj = (L / M) * ca.sum1(U)                                  # cell starts, 1 × n
            ell = srow - sj
            nodes = ca.repmat(sj, Q, 1) + ca.mtimes(ca.DM(xi), ell)    # Q × n
            phis = _basis(nodes, L, t)                                 # nc matrices Q × n
            Ak = A[:, k.tolist()]                                      # nc × n
            theta = sum(phis[c] * ca.repmat(Ak[c, :], Q, 1) for c in range(nc))
            cos, sin = ca.cos(theta), ca.sin(theta)
            kl = k.tolist()
            whole = self.cells
            I = ca.vertcat(ca.sum1(U * whole.dx[:, kl]) + ell * ca.mtimes(self.w.T, cos),
                           ca.sum1(U * whole.dy[:, kl]) + ell * ca.mtimes(self.w.T, sin))
            ws = ca.repmat(self.w, 1, n) * ca.repmat(ell, Q, 1)         # ℓ·w_q, Q × n
            dIx = ca.vertcat(*[ca.sum1(U * whole.ddx[c][:, kl]) - ca.sum1(ws * sin * phis[c])
                               for c in range(nc)])
            dIy = ca.vertcat(*[ca.sum1(U * whole.ddy[c][:, kl]) + ca.sum1(ws * cos * phis[c])
                               for c in range(nc)])
            self.sides.append((k, U, (ws, cos, sin, phis), I, dIx, dIy, X[:, kl]))
        self.phiB = ca.vertcat(*_basis(ca.transpose(sB), L, t))          # nc × n
        self.Th = ca.sum1(self.phiB * A[:, kB.tolist()])
        self.PA = self.sides[0][6] + self.sides[0][3]
        self.PB = self.sides[1][6] + self.sides[1][3]
        self.T = ca.vertcat(ca.cos(self.Th), ca.sin(self.Th))
        self.N = ca.vertcat(-ca.sin(self.Th), ca.cos(self.Th))
        self.d = self.PA - self.PB
        self.sigma = ca.transpose(sigma)
        self.gap = ca.vec(self.sigma * ca.sum1(self.d * self.N))


class _Cells:
    """Every loop's whole-cell increments ΔI_i = ∫ over cell i of (cos θ, sin θ) (M × N for
    x and y) and their derivatives by each coefficient (nc matrices M × N each): the cells'
    nodes are fixed, so φ there is a constant matrix and θ = Φ·A one product for all loops."""

    def __init__(self, A: ca.MX, L: float, t: int) -> None:
        M, xi, w = cell_rule(t)
        h = L / M
        u = ((np.arange(M)[:, None] + xi[None, :]) * h).ravel()         # M·Q nodes
        self.phi = basis_at(u, L, t)                                   # M·Q × nc
        theta = ca.mtimes(ca.DM(self.phi), A)                          # M·Q × N
        self.cos, self.sin = ca.cos(theta), ca.sin(theta)
        self.rep = np.kron(np.eye(M), h * w[:, None])                  # M·Q × M: h w_q
        W = ca.DM(self.rep.T)                                          # M × M·Q
        self.dx, self.dy = ca.mtimes(W, self.cos), ca.mtimes(W, self.sin)
        self.ddx = [-ca.mtimes(ca.DM(self.rep.T * self.phi[:, c]), self.sin)
                    for c in range(self.phi.shape[1])]
        self.ddy = [ca.mtimes(ca.DM(self.rep.T * self.phi[:, c]), self.cos)
                    for c in range(self.phi.shape[1])]

    def hessian_blocks(self, omega_x: ca.MX, omega_y: ca.MX, iu, ju) -> ca.MX:
        """Σ_iq h w_q (Ω_x,i cos θ_iq + Ω_y,i sin θ_iq) φ_c φ_d at the cells' nodes, for the
        upper-triangle pairs (c, d) = (iu, ju): pairs × N."""
        R = ca.DM(self.rep)
        coef = ca.mtimes(R, omega_x) * self.cos + ca.mtimes(R, omega_y) * self.sin
        pp = ca.DM(np.stack([self.phi[:, i] * self.phi[:, j] for i, j in zip(iu, ju)]))
        return ca.mtimes(pp, coef)


def _basis(u: ca.MX, L: float, t: int) -> list[ca.MX]:
    """φ_c(u) of eq. (15) elementwise on a matrix u, one matrix per basis function; the
    harmonics by the angle-addition recurrence (two trigonometric calls, not 2t)."""
    c1, s1 = ca.cos(2 * np.pi * u / L), ca.sin(2 * np.pi * u / L)
    sins, coss = [s1], [c1]
    for _ in range(t - 1):
        sins.append(sins[-1] * c1 + coss[-1] * s1)
        coss.append(coss[-1] * c1 - sins[-2] * s1)
    return sins + coss + [u, ca.MX.ones(u.shape)]


def _derivatives(base: FullNLP, geo: _Geometry, x, p, g, ng0: int, n: int) -> dict:
    """``jac_g`` and ``hess_lag`` of the whole NLP: the base parts from derivatives.py, the
    contact parts in closed form (module docstring)."""
    nx = base.n_variables
    base_d = closed_form_derivatives(base)
    pb = p[:base.p.size]
    g_b, J_b = base_d["jac_g"](x, pb)
    J = ca.vertcat(J_b, _contact_jacobian(base, geo, nx))
    jac_g = ca.Function("nlp_jac_g", [x, p], [g, J], ["x", "p"], ["g", "jac_g_x"])
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", ng0 + n)
    H = base_d["hess_lag"](x, pb, lam_f, lam_g[:ng0]) + _contact_hessian(
        base, geo, lam_g[ng0:], nx)
    hess_lag = ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [H],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    return {"jac_g": jac_g, "hess_lag": hess_lag}


def _contact_jacobian(base: FullNLP, geo: _Geometry, nx: int) -> ca.MX:
    """The gap rows by columns of x (entries of a slot with k_A = k_B summed)."""
    n, nc = geo.n, geo.nc
    coeff0, start0 = base.x.slice("coeffs").start, base.x.slice("starts").start
    slot = np.arange(n)
    sN = ca.repmat(geo.sigma, 2, 1) * geo.N                             # σN, 2 × n
    (kA, *_a, dIxA, dIyA, _xa), (kB, *_b, dIxB, dIyB, _xb) = geo.sides
    dT = ca.sum1(geo.d * geo.T)
    rows, cols, vals = [], [], []
    for d in range(2):
        rows += [slot, slot]
        cols += [start0 + 2 * kA + d, start0 + 2 * kB + d]
        vals += [sN[d, :], -sN[d, :]]
    gA = ca.repmat(sN[0, :], geo.nc, 1) * dIxA + ca.repmat(sN[1, :], geo.nc, 1) * dIyA
    gB = -(ca.repmat(sN[0, :], geo.nc, 1) * dIxB + ca.repmat(sN[1, :], geo.nc, 1) * dIyB) \
        - ca.repmat(geo.sigma * dT, geo.nc, 1) * geo.phiB
    for c in range(nc):
        rows += [slot, slot]
        cols += [coeff0 + nc * kA + c, coeff0 + nc * kB + c]
        vals += [gA[c, :], gB[c, :]]
    return _assemble_sum(rows, cols, vals, n, nx)


def _contact_hessian(base: FullNLP, geo: _Geometry, lam_gap: ca.MX, nx: int) -> ca.MX:
    """Upper triangle of Σ λ_c ∇²g_c: the loops' own coefficient blocks and the blocks between
    the two loops of each slot (module docstring)."""
    nc, N = geo.nc, base.problem.n_loops
    coeff0, start0 = base.x.slice("coeffs").start, base.x.slice("starts").start
    lg = ca.transpose(lam_gap)
    mu = lg * geo.sigma                                                 # λσ, 1 × n
    iu, ju = _triu_pairs(nc)
    blocks = ca.MX(len(iu), N)
    M = geo.cells.dx.shape[0]
    omega_x, omega_y = ca.MX(M, N), ca.MX(M, N)
    for side, (k, U, (ws, cos, sin, phis), *_rest) in enumerate(geo.sides):
        Q = ws.shape[0]
        sign = -1.0 if side == 0 else 1.0          # +I_A, −I_B in d: the (λ_x, λ_y) of −I
        lx, ly = sign * mu * geo.N[0, :], sign * mu * geo.N[1, :]
        omega = ws * (ca.repmat(lx, Q, 1) * cos + ca.repmat(ly, Q, 1) * sin)   # Q × n
        per_point = ca.vertcat(*[ca.sum1(omega * phis[i] * phis[j]) for i, j in zip(iu, ju)])
        scatter = _scatter(k, N)
        blocks += ca.mtimes(per_point, scatter)                        # sum points per loop
        omega_x += ca.mtimes(U * ca.repmat(lx, M, 1), scatter)          # Ω per loop and cell
        omega_y += ca.mtimes(U * ca.repmat(ly, M, 1), scatter)
    blocks += geo.cells.hessian_blocks(omega_x, omega_y, iu, ju)
    (kA, *_a, dIxA, dIyA, _xa), (kB, *_b, dIxB, dIyB, _xb) = geo.sides
    Tx, Ty = ca.repmat(geo.T[0, :], nc, 1), ca.repmat(geo.T[1, :], nc, 1)
    vA, vB = Tx * dIxA + Ty * dIyA, Tx * dIxB + Ty * dIyB                # ∂Iᵀ T, nc × n
    phiB = geo.phiB
    g = ca.transpose(geo.gap)
    own_B = ca.vertcat(*[mu * (vB[i, :] * phiB[j, :] + phiB[i, :] * vB[j, :])
                         - lg * g * phiB[i, :] * phiB[j, :] for i, j in zip(iu, ju)])
    blocks += ca.mtimes(own_B, _scatter(kB, N))
    H_blocks = ca.MX(_block_triu_sparsity(N, nc, coeff0, nx), ca.vec(blocks))
    rows, cols, vals = [], [], []
    for d in range(2):
        for c in range(nc):
            rows += [start0 + 2 * kA + d, start0 + 2 * kB + d]
            cols += [coeff0 + nc * kB + c, coeff0 + nc * kB + c]
            vals += [-mu * geo.T[d, :] * phiB[c, :], mu * geo.T[d, :] * phiB[c, :]]
    for i in range(nc):
        for j in range(nc):
            rows.append(coeff0 + nc * kA + i)
            cols.append(coeff0 + nc * kB + j)
            vals.append(-mu * vA[i, :] * phiB[j, :])
    return H_blocks + _assemble_sum(rows, cols, vals, nx, nx, upper=True)


def _scatter(k: np.ndarray, N: int) -> ca.DM:
    """The sparse n × N matrix adding each point's block into its loop's."""
    sp = ca.Sparsity.triplet(len(k), N, np.arange(len(k)).tolist(), np.asarray(k).tolist())
    return ca.DM(sp, 1.0)


def _assemble_sum(rows, cols, vals, nrow: int, ncol: int, upper: bool = False) -> ca.MX:
    """A sparse MX from triplet blocks whose entries may repeat (summed). With ``upper``, the
    entries are of a symmetric matrix given once each, stored in its upper triangle: (r, c)
    and (c, r) land on one entry, and an entry on the diagonal counts twice (it stands for
    both)."""
    r = np.concatenate([np.asarray(a).ravel() for a in rows]).astype(int)
    c = np.concatenate([np.asarray(a).ravel() for a in cols]).astype(int)
    factor = np.ones(len(r))
    if upper:
        factor[r == c] = 2.0
        r, c = np.minimum(r, c), np.maximum(r, c)
    v = ca.vertcat(*[ca.vec(ca.MX(val) if isinstance(val, ca.DM) else val) for val in vals])
    uniq, inv = np.unique(c * nrow + r, return_inverse=True)          # column-major order
    sp = ca.Sparsity.triplet(nrow, ncol, (uniq % nrow).tolist(), (uniq // nrow).tolist())
    total = ca.DM(ca.Sparsity.triplet(len(uniq), len(r), inv.tolist(), list(range(len(r)))),
                  factor)
    return ca.MX(sp, ca.mtimes(total, v))
