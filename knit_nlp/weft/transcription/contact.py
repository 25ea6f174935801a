"""The contact rows added to the full weft NLP, with closed-form first and second derivatives.

A contact *slot* c holds one pair of material points: s_A on loop k_A and s_B on loop k_B, with
side σ (all three are NLP parameters, so the contact points move along the yarns between solves
without rebuilding anything; only the loops of a slot are structural). Each slot lifts five
variables, like nlp.py lifts clamped points:

    P_A − X_kA − I(a_kA; s_A) = 0,   P_B − X_kB − I(a_kB; s_B) = 0,   Θ − φ(s_B)·a_kB = 0,

with I(a; s) = ∫₀ˢ (cos θ, sin θ) du, θ = φ(u)·a (eqs. 1, 14-15), by the cell rule of
``curves.py``: I = Σ_{i<j} ΔI_i(a) + ∫_{s_j}^{s}, the whole cells' increments ΔI_i computed
once per loop and shared by every slot on it (picked by a 0/1 mask per slot, U_i = [i < j],
also a parameter), the partial cell by NODES nodes per point (8 nodes per point where a rule
on all of [0, s] took 48; ``curves.partial_cell``, the definition the numbers use too); and one
inequality row, the signed normal gap

    g_c = σ (P_A − P_B)·N(Θ) ≥ required_c,    N(Θ) = (−sin Θ, cos Θ),

the distance between the two points when P_A − P_B is normal to yarn B (the outer loop puts
(s_A, s_B) on the closest points). A slot not in use gets the bound −∞. IPOPT sees every
contact row times ``ROW_SCALE`` (its bounds and multipliers too: ``bounds``,
``gap_multipliers`` and ``warm_multipliers`` convert), so that its filter line search does not
weigh the slots' rows above the model's own (the constant's comment has the measurements).

Derivatives (everything else in the NLP is handled by derivatives.py):
- ∂I/∂a = Σ_i U_i ∂ΔI_i/∂a + ℓ Σ_q w_q (−sin θ_q, cos θ_q) φ(s_j + ℓ ξ_q)ᵀ, ℓ = s − s_j, with
  ∂ΔI_i/∂a = h Σ_q w_q (−sin θ_iq, cos θ_iq) φ_iqᵀ per loop;  λᵀ of the lifting rows adds
  Σ_q ℓ w_q (λ_x cos θ_q + λ_y sin θ_q) φ_q φ_qᵀ per slot and Σ_iq h w_q (Ω_x,i cos θ_iq +
  Ω_y,i sin θ_iq) φ_iq φ_iqᵀ per loop (Ω_i = Σ of U_i λ over the slots' sides on the loop) to
  loop k's coefficient block (the block the bending energy and eq. (1) already fill: no new
  sparsity);
- ∂g/∂P_A = σN, ∂g/∂P_B = −σN, ∂g/∂Θ = −σ (P_A − P_B)·T;  ∂²g/∂P_A∂Θ = −σT,
  ∂²g/∂P_B∂Θ = σT, ∂²g/∂Θ² = −g  (T = (cos Θ, sin Θ)).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from ...layout import Layout
from ..model.basis import basis_terms, n_coeffs
from ..model.parametrisation import Full
from ..model.contact.curves import Curves, cell_of, cell_rule, cell_weights, partial_cell
from ..model.quadrature import rule_integrals
from .derivatives import block_triu_sparsity, triu_pairs, closed_form_derivatives
from .full import FullNLP
from .protocol import WeftNLP

VARS = 5               # P_A (2), P_B (2), Θ per slot
LIFT = 5               # lifting rows per slot
# every contact row (lifting and gap) is scaled by this in the NLP that IPOPT sees. IPOPT's
# filter line search weighs infeasibility as the 1-norm over all rows; six rows per slot, each
# nonlinear in its loops' rotation, outweighed the model's own rows by thousands of slots, and
# the filter cut every step (30 x 30 diagonal pull, first load step from the natural fabric:
# steps of 0.005 for 90 IPOPT iterations, 111 iterations and 76 s; with 0.1, 37 and 22 s; with
# 0.01, 33 and 19 s there, but 45 iterations instead of 28 at the 10 x 10 pull's last step).
# Multipliers and bounds are read and written unscaled through ContactNLP's methods
ROW_SCALE = 0.1


@dataclass
class Slots:
    """The contact slots of a contact NLP: slot c holds a pair of points on loops kA[c] and
    kB[c] (which points, and their side, are parameters set per solve)."""

    kA: np.ndarray
    kB: np.ndarray


def _from_base(name: str) -> property:
    """A member of the contact NLP that is its base NLP's (the problem, its clamped and loaded
    points, their rows, its parameter values)."""
    return property(lambda self: getattr(self.base, name),
                    doc=f"The base NLP's ``{name}`` (``WeftNLP``).")


@dataclass
class ContactNLP(WeftNLP):
    """The full weft NLP of ``base`` with contact slots appended (variables, parameters, rows):
    a :class:`~knit_nlp.weft.transcription.protocol.WeftNLP` (``factory.transcribe(problem,
    Full(), contact=Slots(kA, kB))``).

    Variables: base x, then per slot (P_A, P_B, Θ). Parameters: base p, then s_A, s_B, σ of
    every slot, then the cell masks U of A's and of B's points (cells × slots each). Rows: base
    g, then the lifting rows (5 per slot), then the gap rows (1 per slot). What the protocol
    reads of a decision vector (loops, starts, special points, energy) is its base part's.
    """

    base: FullNLP
    kA: np.ndarray
    kB: np.ndarray
    nlp: dict
    nlpsol_options: dict
    x: Layout
    p: Layout
    g: Layout
    gap_rows: slice
    jacobian: ca.Function | None = field(default=None, repr=False)
    parametrisation: Full = Full()
    model: str = "full"

    problem = _from_base("problem")
    params = _from_base("params")
    clamp_table = _from_base("clamp_table")
    n_parameters = _from_base("n_parameters")

    @property
    def n_slots(self) -> int:
        return len(self.kA)

    @property
    def p0(self) -> np.ndarray:
        """The problem's parameters with every slot at mid-loop (``parameters``)."""
        mid = np.full(self.n_slots, 0.5 * self.problem.L)
        return self.parameters(self.base.p0, mid, mid, np.ones(self.n_slots))

    @property
    def x0(self) -> np.ndarray:
        """The natural state, every slot's points at mid-loop."""
        mid = np.full(self.n_slots, 0.5 * self.problem.L)
        return self.lift_slots(self.base.x0, mid, mid)

    @property
    def lbg(self) -> np.ndarray:
        """Bounds with no slot in use (each solve passes its own, :meth:`bounds`)."""
        return self.bounds(np.zeros(self.n_slots), np.zeros(self.n_slots, dtype=bool))[0]

    @property
    def ubg(self) -> np.ndarray:
        return self.bounds(np.zeros(self.n_slots), np.zeros(self.n_slots, dtype=bool))[1]

    def energy(self, x: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
        return self.base.energy(np.asarray(x)[:self.base.n_variables],
                                np.asarray(p)[:self.base.p.size])

    def coefficients(self, x: np.ndarray) -> np.ndarray:
        return self.base.coefficients(np.asarray(x)[:self.base.n_variables])

    def starts(self, x: np.ndarray) -> np.ndarray:
        return self.base.starts(np.asarray(x)[:self.base.n_variables])

    def special_positions(self, x: np.ndarray) -> np.ndarray:
        return self.base.special_positions(np.asarray(x)[:self.base.n_variables])

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """The decision vector of these loops, every slot's points at mid-loop."""
        mid = np.full(self.n_slots, 0.5 * self.problem.L)
        return self.lift_slots(self.base.lift(coeffs, starts), mid, mid)

    def representatives(self) -> None:
        return None

    def parameters(self, p_base: np.ndarray, sA: np.ndarray, sB: np.ndarray,
                   sigma: np.ndarray) -> np.ndarray:
        """The NLP's parameter vector (the cell masks computed from s_A and s_B)."""
        pr = self.problem
        M = cell_rule(pr.t)[0]
        masks = [(np.arange(M)[:, None] < cell_of(s, pr.L, pr.t)[None, :]).astype(float)
                 for s in (sA, sB)]
        return np.concatenate([p_base, sA, sB, sigma] + [m.ravel(order="F") for m in masks])

    def bounds(self, required: np.ndarray, used: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """lbg, ubg: the base rows' own bounds, equalities for the lifting rows, gap ≥ required
        where a slot is used (no bound on an unused slot)."""
        nb = self.base.n_constraints
        lbg, ubg = np.zeros(self.n_constraints), np.zeros(self.n_constraints)
        lbg[:nb], ubg[:nb] = self.base.lbg, self.base.ubg
        lbg[self.gap_rows] = np.where(used, ROW_SCALE * np.asarray(required), -np.inf)
        ubg[self.gap_rows] = np.inf
        return lbg, ubg

    def lift_slots(self, x_base: np.ndarray, sA: np.ndarray, sB: np.ndarray) -> np.ndarray:
        """A full decision vector: base x and the slots' points and angles computed from it."""
        pr = self.problem
        curves = Curves.of(self.base.coefficients(x_base), self.base.starts(x_base), pr.L)
        z = np.zeros((self.n_slots, VARS))
        z[:, 0:2] = curves.points(self.kA, sA)
        z[:, 2:4] = curves.points(self.kB, sB)
        z[:, 4] = curves.angle(self.kB, sB)
        return np.concatenate([x_base, z.ravel()])

    def gap_multipliers(self, lam_g: np.ndarray) -> np.ndarray:
        """Each slot's multiplier λ of its gap row as written (unscaled: the contact force is
        −λ) from the multipliers IPOPT returns for the whole NLP (its rows are ``ROW_SCALE``
        times these)."""
        return ROW_SCALE * np.asarray(lam_g)[self.gap_rows]

    def warm_multipliers(self, xval: np.ndarray, sigma: np.ndarray,
                         lam_gap: np.ndarray) -> np.ndarray:
        """IPOPT's starting multipliers of the contact rows (lifting, then gap) for given
        unscaled gap multipliers: the lifting rows' balance them (:meth:`lift_multipliers`)."""
        lam_gap = np.asarray(lam_gap, dtype=float)
        return np.concatenate([self.lift_multipliers(xval, sigma, lam_gap), lam_gap]) / ROW_SCALE

    def lift_multipliers(self, xval: np.ndarray, sigma: np.ndarray,
                         lam_gap: np.ndarray) -> np.ndarray:
        """Multipliers of the lifting rows (unscaled) that balance given gap multipliers
        (stationarity in P_A, P_B, Θ): λ_A = −λσN, λ_B = λσN, λ_Θ = λσ(P_A − P_B)·T."""
        z = np.asarray(xval)[self.base.n_variables:].reshape(-1, VARS)
        n = np.stack([-np.sin(z[:, 4]), np.cos(z[:, 4])], axis=1)
        t = np.stack([np.cos(z[:, 4]), np.sin(z[:, 4])], axis=1)
        ls = (lam_gap * sigma)[:, None]
        out = np.concatenate([-ls * n, ls * n, ls * np.sum((z[:, 0:2] - z[:, 2:4]) * t, 1,
                                                           keepdims=True)], axis=1)
        return out.ravel()

    def gaps(self, xval: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """Signed normal gaps of every slot at a decision vector."""
        z = np.asarray(xval)[self.base.n_variables:].reshape(-1, VARS)
        n = np.stack([-np.sin(z[:, 4]), np.cos(z[:, 4])], axis=1)
        return sigma * np.sum((z[:, 0:2] - z[:, 2:4]) * n, axis=1)


def build_contact_nlp(base: FullNLP, slots: Slots) -> ContactNLP:
    """The base NLP with one contact slot per entry of (kA, kB), closed-form derivatives
    (``factory.transcribe(problem, Full(), contact=slots)`` calls it)."""
    if base.model != "full":
        raise ValueError("contact is built on the full model")
    kA, kB = np.asarray(slots.kA, dtype=int), np.asarray(slots.kB, dtype=int)
    n, nx0, ng0, np0 = len(kA), base.n_variables, base.n_constraints, base.p.size
    x = ca.MX.sym("x", nx0 + VARS * n)
    M = cell_rule(base.problem.t)[0]
    pl = _extended(base.p, [("contact_s_A", n, 1), ("contact_s_B", n, 1),
                            ("contact_sigma", n, 1), ("contact_masks", M, 2 * n)])
    p = ca.MX.sym("p", pl.size)
    xb, pb = x[:nx0], p[:np0]
    f_base = ca.Function("f_base", [base.nlp["x"], base.nlp["p"]], [base.nlp["f"]])
    g_base = ca.Function("g_base", [base.nlp["x"], base.nlp["p"]], [base.nlp["g"]])
    sA, sB, sigma = (p[pl.slice(name)] for name in ("contact_s_A", "contact_s_B",
                                                     "contact_sigma"))
    masks = ca.reshape(p[pl.slice("contact_masks")], M, 2 * n)
    geo = _Geometry(base, x, sA, sB, sigma, kA, kB, (masks[:, :n], masks[:, n:]))
    g = ca.vertcat(g_base(xb, pb), ROW_SCALE * geo.lift_rows, ROW_SCALE * geo.gap)
    xl = _extended(base.x, [("contact", VARS, n)])
    gl = _extended(base.g, [("contact_lift", LIFT, n), ("contact_gap", n, 1)])
    nlp = {"x": x, "p": p, "f": f_base(xb, pb), "g": g}
    derivs = _derivatives(base, geo, x, p, g, nx0, ng0, n)
    return ContactNLP(base, kA, kB, nlp, derivs, xl, pl, gl, gl.slice("contact_gap"),
                      jacobian=derivs["jac_g"])


def _extended(layout: Layout, more: list[tuple[str, int, int]]) -> Layout:
    """A copy of ``layout`` with the blocks ``more`` (name, rows, columns) appended."""
    out = Layout()
    for name, (_, _, shape) in layout.blocks.items():
        out.add(name, *shape)
    for name, rows, cols in more:
        out.add(name, rows, cols)
    return out

class _Geometry:
    """Symbolic pieces shared by the rows and their derivatives, vectorised over the points
    (nodes × points matrices; measured 2x faster to evaluate than a small SX Function mapped
    over the points), and the loops' whole-cell increments (nodes × loops)."""

    def __init__(self, base: FullNLP, x: ca.MX, sA: ca.MX, sB: ca.MX, sigma: ca.MX,
                 kA: np.ndarray, kB: np.ndarray, masks: tuple[ca.MX, ca.MX]) -> None:
        pr = base.problem
        n, nx0 = len(kA), base.n_variables
        nc, N, L, t = n_coeffs(pr.t), pr.n_loops, pr.L, pr.t
        A = ca.reshape(x[base.x.slice("coeffs")], nc, N)
        X = ca.reshape(x[base.x.slice("starts")], 2, N)
        z = ca.reshape(x[nx0:], VARS, n)
        self.n, self.nc, self.kA, self.kB = n, nc, kA, kB
        M, xi, w = cell_rule(t)
        self.w = ca.DM(w)
        self.cells = _Cells(A, L, t)
        self.sides = []
        Q = len(xi)
        for k, s, U in ((kA, sA, masks[0]), (kB, sB, masks[1])):
            kl = k.tolist()
            sj = (L / M) * ca.sum1(U)                                  # cell starts, 1 × n
            part = partial_cell(sj, ca.transpose(s), A[:, kl], L, t, ca.sin, ca.cos,
                                ca.mtimes, _repeat_rows)               # as the numbers (curves)
            ell, phis, cos, sin = part.length, part.terms, part.cos, part.sin
            whole = self.cells
            I = ca.vertcat(ca.sum1(U * whole.dx[:, kl]) + part.dx,
                           ca.sum1(U * whole.dy[:, kl]) + part.dy)
            ws = ca.repmat(self.w, 1, n) * ca.repmat(ell, Q, 1)         # ℓ·w_q, Q × n
            dIx = ca.vertcat(*[ca.sum1(U * whole.ddx[c][:, kl]) - ca.sum1(ws * sin * phis[c])
                               for c in range(nc)])
            dIy = ca.vertcat(*[ca.sum1(U * whole.ddy[c][:, kl]) + ca.sum1(ws * cos * phis[c])
                               for c in range(nc)])
            self.sides.append((k, U, (ws, cos, sin, phis), I, dIx, dIy, X[:, kl]))
        PA, PB, Th = z[0:2, :], z[2:4, :], z[4, :]
        self.phiB = ca.vertcat(*basis_mx(ca.transpose(sB), L, t))          # nc × n
        theta_B = ca.sum1(self.phiB * A[:, kB.tolist()])
        lift = ca.vertcat(PA - self.sides[0][6] - self.sides[0][3],
                          PB - self.sides[1][6] - self.sides[1][3], Th - theta_B)
        self.lift_rows = ca.vec(lift)
        self.T = ca.vertcat(ca.cos(Th), ca.sin(Th))
        self.N = ca.vertcat(-ca.sin(Th), ca.cos(Th))
        self.d = PA - PB
        self.sigma = ca.transpose(sigma)
        self.gap = ca.vec(self.sigma * ca.sum1(self.d * self.N))


class _Cells:
    """Every loop's whole-cell increments ΔI_i = ∫ over cell i of (cos θ, sin θ) (M × N for
    x and y) and their derivatives by each coefficient (nc matrices M × N each): the cells'
    nodes are fixed, so φ there is a constant matrix and θ = Φ·A one product for all loops."""

    def __init__(self, A: ca.MX, L: float, t: int) -> None:
        self.phi, W = cell_weights(L, t)                               # M·Q × nc, M × M·Q
        self.rep = W.T                                                 # M·Q × M: h w_q
        self.cos, self.sin, self.dx, self.dy = rule_integrals(
            ca.DM(self.phi), ca.DM(W), A, ca.cos, ca.sin, ca.mtimes)  # as the numbers (curves)
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


def _repeat_rows(v: ca.MX, nodes: int) -> ca.MX:
    """``curves.partial_cell``'s ``rows`` for CasADi (which does not broadcast): the row v at
    each of the nodes."""
    return ca.repmat(v, nodes, 1)


def basis_mx(u: ca.MX, L: float, t: int) -> list[ca.MX]:
    """φ_c(u) of eq. (15) elementwise on a CasADi matrix u, one matrix per basis function
    (``basis.basis_terms``, the definition the numbers use too)."""
    return basis_terms(u, L, t, ca.sin, ca.cos, ca.MX.ones(u.shape))


def _derivatives(base: FullNLP, geo: _Geometry, x, p, g, nx0: int, ng0: int, n: int) -> dict:
    """``jac_g`` and ``hess_lag`` of the whole NLP: the base parts from derivatives.py, the
    contact parts in closed form (module docstring)."""
    nx, ngc = nx0 + VARS * n, LIFT * n + n
    base_d = closed_form_derivatives(base)
    xb, pb = x[:nx0], p[:base.p.size]
    g_b, J_b = base_d["jac_g"](xb, pb)
    J_c = _contact_jacobian(base, geo, nx0, nx)
    J = ca.vertcat(ca.horzcat(J_b, ca.MX(ng0, nx - nx0)), ROW_SCALE * J_c)
    jac_g = ca.Function("nlp_jac_g", [x, p], [g, J], ["x", "p"], ["g", "jac_g_x"])
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", ng0 + ngc)
    H_b = base_d["hess_lag"](xb, pb, lam_f, lam_g[:ng0])
    H = ca.diagcat(H_b, ca.MX(nx - nx0, nx - nx0)) + ROW_SCALE * _contact_hessian(
        base, geo, lam_g[ng0:ng0 + LIFT * n], lam_g[ng0 + LIFT * n:], nx0, nx)
    hess_lag = ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [H],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    return {"jac_g": jac_g, "hess_lag": hess_lag}


def _contact_jacobian(base: FullNLP, geo: _Geometry, nx0: int, nx: int) -> ca.MX:
    """Rows of the contact block (lifting rows, then gap rows) by columns of x."""
    n, nc = geo.n, geo.nc
    coeff0, start0 = base.x.slice("coeffs").start, base.x.slice("starts").start
    slot = np.arange(n)
    rows, cols, vals = [], [], []

    def put(r, c, v):
        rows.append(np.asarray(r).ravel())
        cols.append(np.asarray(c).ravel())
        vals.append(v)

    lift0 = LIFT * slot                       # first lifting row of each slot (vec of 5 × n)
    for side, (k, s, _, _, dIx, dIy, _) in enumerate(geo.sides):
        for d, dI in enumerate((dIx, dIy)):
            r = lift0 + 2 * side + d
            put(r, nx0 + VARS * slot + 2 * side + d, ca.DM.ones(1, n))           # +P
            put(r, start0 + 2 * k + d, -ca.DM.ones(1, n))                        # −X_k
            for c in range(nc):
                put(r, coeff0 + nc * k + c, -dI[c, :])                           # −∂I/∂a
    r = lift0 + 4
    put(r, nx0 + VARS * slot + 4, ca.DM.ones(1, n))
    for c in range(nc):
        put(r, coeff0 + nc * geo.kB + c, -geo.phiB[c, :])
    r = LIFT * n + slot
    sig2 = ca.repmat(geo.sigma, 2, 1)
    sN, sT = sig2 * geo.N, sig2 * geo.T
    for d in range(2):
        put(r, nx0 + VARS * slot + d, sN[d, :])
        put(r, nx0 + VARS * slot + 2 + d, -sN[d, :])
    put(r, nx0 + VARS * slot + 4, -ca.sum1(geo.d * sT))
    return _assemble(rows, cols, vals, LIFT * n + n, nx)


def _contact_hessian(base: FullNLP, geo: _Geometry, lam_lift: ca.MX, lam_gap: ca.MX,
                     nx0: int, nx: int) -> ca.MX:
    """Upper triangle of Σ λ·∇²(contact rows): loop coefficient blocks and the slots' 5 × 5."""
    pr = base.problem
    n, nc, N = geo.n, geo.nc, pr.n_loops
    coeff0 = base.x.slice("coeffs").start
    lam = ca.reshape(lam_lift, LIFT, n)
    iu, ju = triu_pairs(nc)
    blocks = ca.MX(len(iu), N)
    M = geo.cells.dx.shape[0]
    omega_x, omega_y = ca.MX(M, N), ca.MX(M, N)
    for side, (k, U, (ws, cos, sin, phis), *_rest) in enumerate(geo.sides):
        Q = ws.shape[0]
        lx, ly = lam[2 * side, :], lam[2 * side + 1, :]
        omega = ws * (ca.repmat(lx, Q, 1) * cos + ca.repmat(ly, Q, 1) * sin)   # Q × n
        per_point = ca.vertcat(*[ca.sum1(omega * phis[i] * phis[j]) for i, j in zip(iu, ju)])
        scatter = _scatter(k, N)
        blocks += ca.mtimes(per_point, scatter)                        # sum points per loop
        omega_x += ca.mtimes(U * ca.repmat(lx, M, 1), scatter)          # Ω per loop and cell
        omega_y += ca.mtimes(U * ca.repmat(ly, M, 1), scatter)
    blocks += geo.cells.hessian_blocks(omega_x, omega_y, iu, ju)
    H_blocks = ca.MX(block_triu_sparsity(N, nc, coeff0, nx), ca.vec(blocks))
    slot = np.arange(n)
    th = nx0 + VARS * slot + 4
    lg = ca.transpose(lam_gap)
    sT = ca.repmat(geo.sigma, 2, 1) * geo.T
    rows = [nx0 + VARS * slot + d for d in range(4)] + [th]
    vals = [-lg * sT[0, :], -lg * sT[1, :], lg * sT[0, :], lg * sT[1, :],
            -lg * ca.transpose(ca.vec(geo.gap))]
    H_gap = _assemble(rows, [th] * 5, vals, nx, nx)
    return H_blocks + H_gap


def _scatter(k: np.ndarray, N: int) -> ca.DM:
    """The sparse n × N matrix adding each point's block into its loop's."""
    sp = ca.Sparsity.triplet(len(k), N, np.arange(len(k)).tolist(), np.asarray(k).tolist())
    return ca.DM(sp, 1.0)


def _assemble(rows, cols, vals, nrow: int, ncol: int) -> ca.MX:
    """A sparse MX from triplet blocks (rows, cols index arrays; vals 1 × len row vectors)."""
    r = np.concatenate([np.asarray(a).ravel() for a in rows]).astype(int)
    c = np.concatenate([np.asarray(a).ravel() for a in cols]).astype(int)
    v = ca.vertcat(*[ca.vec(ca.MX(val) if isinstance(val, ca.DM) else val) for val in vals])
    sp, mapping = ca.Sparsity.triplet(nrow, ncol, r.tolist(), c.tolist(), False)
    if sp.nnz() != len(r):
        raise ValueError("contact derivative entries overlap")
    return ca.MX(sp, v[mapping])
