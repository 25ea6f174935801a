"""The forward equilibrium's first-order sensitivities and second-order check, with or without
yarn contact (``Equilibrium.sensitivity`` and ``stability``: control, fit and calibrate).

The forward problem (eq. 13) is equality constrained: min f(x, p) s.t. g(x, p) = 0, where p holds
clamp targets, rigid motions, stiffnesses and loads. Its first-order conditions are the smooth
system F(z, p) = (∇ₓL, g) = 0 with z = (x, λ), L = f + λᵀg (CasADi's sign convention). By the
implicit-function theorem dz/dp = −K⁻¹ ∂F/∂p with K = ∂F/∂z = [[∇²ₓₓL, Jᵀ], [J, 0]], the KKT
matrix: one sparse factorization (MUMPS) gives the sensitivities to every parameter.

With yarn contact (``[yarn] radius``) the KKT system is that of the contact NLP at its solution
(:class:`ContactState`), with the lifting rows as equalities, the active gap rows
(``contact.active.active_gaps``: pushing, and nearer their bound than they push, as the result's
``contact`` block lists them) as equalities and the inactive gap rows dropped — the standard
sensitivity of an inequality-constrained minimum under strict complementarity, valid while the
active set does not change. The parameters of control (clamp targets, rigid motions) enter only
the base rows, so ∂F/∂p is the base NLP's, padded with zeros for the slots' rows. The active
slots' material points s_A, s_B are unknowns too, held at closest points
((P_A − P_B)·T_A = (P_A − P_B)·T_B = 0): the gap's gradient is the same with them fixed
(envelope theorem), but its curvature, times the contact force, enters K — fixed points give
dx/dp 7 % off central differences on the squeezed loop, sliding ones 4e-5
(:func:`sliding_system`).

Stability: the equilibrium is a strict local minimum when the Hessian of the Lagrangian reduced
to the null space of J, ZᵀHZ with Z orthonormal, is positive definite (with contact: the contact
NLP's Hessian, points held, reduced to the null space of the base equalities, the lifting rows
and the active gap rows). Two ways, measured:
- ``sparse`` (default with scipy): positive definiteness from the inertia of H + ρJᵀJ (CasADi's
  sparse LDLᵀ; for z ∈ ker J, zᵀ(H + ρJᵀJ)z = zᵀHz, so no negative pivot proves ZᵀHZ ≻ 0, and
  for ρ large enough the converse holds: ρ grows ×100 up to ``RHO_MAX`` before a saddle is
  declared); then the smallest eigenvalue by Lanczos (scipy ``eigsh``) on the shift-inverted
  operator v ↦ top block of (K − σ·diag(I, 0))⁻¹(v, 0), whose eigenvalues are 1/(μᵢ − σ) for the
  reduced eigenvalues μᵢ (and 0 on range Jᵀ); with every μᵢ > 0 > σ the largest is 1/(μ_min − σ).
  30 × 30: 3 s for the LDLᵀ, 2.3 s for the LU and the Lanczos (21 solves), on a loaded machine.
- ``dense``: Z from a complete QR of Jᵀ and the eigenvalues of ZᵀHZ (exact, O(n³): 0.2-2 s at
  10 × 10, out of reach at 30 × 30); the independent check in the tests, and the fallback
  without scipy.
scipy is imported where these run (the command line starts without it: tests/test_imports.py);
the inverse problems import it with their module (``inverse/forward.py``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from ..model.basis import n_coeffs
from ..transcription.contact import VARS, ContactNLP, basis_mx
from ..transcription.protocol import WeftNLP
from .blocks import ContactBlock

SHIFT = -1e-6               # σ of the shift-invert Lanczos: just below zero
RHO = 1e3                   # first penalty of the inertia test, times max|H| / max|JᵀJ|
RHO_MAX = 1e9               # largest penalty tried (same scaling) before declaring a saddle
DENSE_FALLBACK = 4000       # variables; without scipy the dense method runs up to this size
RESIDUAL = 1e-9             # relative residual of a KKT solve accepted (``checked_solve``)


@dataclass
class Stability:
    """The second-order check: smallest eigenvalue of the reduced Hessian and how it was found."""

    min_eigenvalue: float
    method: str

    @property
    def stable(self) -> bool:
        return bool(self.min_eigenvalue > 0.0)


@dataclass
class ContactState:
    """An accepted solve of the contact NLP behind a base solution: the NLP, its parameters
    (base p, s_A, s_B, σ, cell masks), solution, multipliers, which gap rows are active (per
    slot), and the result JSON's ``contact`` block of that solve."""

    cnlp: ContactNLP
    p: np.ndarray
    x: np.ndarray
    lam: np.ndarray
    active: np.ndarray
    block: ContactBlock

    @property
    def n_active(self) -> int:
        return int(self.active.sum())


class KKT:
    """The KKT system of one forward NLP at its solutions (module docstring), built on first
    use from the IPOPT instance's own Hessian and Jacobian Functions (not a second symbolic
    Jacobian: 0.14 s less per build at 10 x 10, same matrix to 7e-15). ``state`` gives the
    contact solve behind a base solution (None: none, or no contact: the base system)."""

    def __init__(self, wnlp: WeftNLP, nlpsol: ca.Function,
                 state: Callable[[np.ndarray], ContactState | None] | None = None) -> None:
        nlp = wnlp.nlp
        x, p, g = nlp["x"], nlp["p"], nlp["g"]
        lam = ca.MX.sym("lam", g.numel())
        F = ca.vertcat(ca.gradient(nlp["f"] + ca.dot(lam, g), x), g)
        self.wnlp, self.n, self.state = wnlp, wnlp.n_variables, state
        self.dFdp = ca.Function("dFdp", [x, lam, p], [ca.jacobian(F, p)])
        self._hess = nlpsol.get_function("nlp_hess_l")
        self._jac_g = nlpsol.get_function("nlp_jac_g")
        self._linsol: ca.Linsol | None = None
        self._slide: tuple[ContactNLP, ca.Function] | None = None

    def _contact(self, x: np.ndarray) -> ContactState | None:
        """The contact solve behind x when it has active contacts, else None."""
        st = None if self.state is None else self.state(x)
        return st if st is not None and st.active.any() else None

    def kkt(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray) -> tuple[ca.DM, ca.DM]:
        """The base NLP's KKT matrix K = ∂F/∂(x, λ) = [[H, Jᵀ], [J, 0]] and ∂F/∂p."""
        H = self._hess(x, p, 1.0, lam)                       # upper triangle of ∇²ₓₓL
        J = self._jac_g(x, p)[1]
        H = H + H.T - ca.diag(ca.diag(H))
        K = ca.blockcat([[H, J.T], [J, ca.DM(J.shape[0], J.shape[0])]])
        return K, self.dFdp(x, lam, p)

    def sensitivity(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray, dp: np.ndarray,
                    sliding: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """dx/dθ and dλ/dθ (n × k, m × k; with contact, the kept rows' λ) for parameter
        directions dp = ∂p/∂θ (size(p) × k), by the implicit-function theorem on
        F(z, p) = 0 (one factorization). With active contacts their points slide along the
        yarns as closest points (:func:`sliding_system`), or with ``sliding`` False stay where
        the solve put them (:meth:`system`: the test that shows sliding matters)."""
        if sliding and self._contact(x) is not None:
            from scipy.sparse.linalg import splu
            A, rhs, nz = self.linear_system(x, lam, p)
            dp = np.asarray(dp, dtype=float).reshape(rhs.shape[1], -1)
            dz = splu(A).solve(np.asarray(-(rhs @ dp)))
            return dz[:self.n], dz[nz:]
        K, Fp, nx = self.system(x, lam, p)
        if self._linsol is None or self._linsol.sparsity() != K.sparsity():
            self._linsol = ca.Linsol("kkt", "mumps", K.sparsity())
        self._linsol.sfact(K)
        self._linsol.nfact(K)
        rhs = -(Fp @ ca.DM(np.asarray(dp, dtype=float).reshape(Fp.shape[1], -1)))
        dz = checked_solve(K, rhs, np.asarray(self._linsol.solve(K, rhs)))
        return dz[:self.n], dz[nx:]

    def system(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray) -> tuple[ca.DM, ca.DM, int]:
        """The KKT matrix, ∂F/∂p and the size of K's Hessian block: the base NLP's, or with
        active contacts the contact NLP's on the base rows, the lifting rows and the active
        gap rows (:func:`contact_system`)."""
        st = self._contact(x)
        if st is None:
            K, Fp = self.kkt(x, lam, p)
            return K, Fp, self.n
        return contact_system(st, self.dFdp(x, st.lam[:self.wnlp.n_constraints], p), self.n)

    def linear_system(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray, contact: bool = True
                      ) -> tuple["scipy.sparse.csc_matrix", np.ndarray, int]:
        """The sensitivities' linear system A dz = −Fp dp as SciPy/NumPy matrices, and where
        dλ starts in dz (dλ's first rows are the base constraints': clamp reactions read
        alike with and without contact): the KKT system, or with active contacts
        :func:`sliding_system` (unknowns x, the active slots' s, the kept rows' λ) unless
        ``contact`` is False (the paper's model's system at the same state)."""
        st = self._contact(x) if contact else None
        if st is None:
            K, Fp = self.kkt(x, lam, p)
            return scipy_matrix(K), np.asarray(ca.DM(Fp)), self.n
        if self._slide is None or self._slide[0] is not st.cnlp:
            self._slide = st.cnlp, sliding_function(st.cnlp)
        return sliding_system(st, self.dFdp(x, st.lam[:self.wnlp.n_constraints], p), self.n,
                              self._slide[1])

    def stability(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray,
                  method: str = "sparse") -> Stability:
        """Smallest eigenvalue of the Lagrangian Hessian reduced to the null space of J."""
        K, _, n = self.system(x, lam, p)
        return reduced_stability(K, n, method)


def checked_solve(K: ca.DM, rhs: ca.DM, dz: np.ndarray) -> np.ndarray:
    """dz = K⁻¹ rhs as a factorization returned it, kept when its residual is within
    ``RESIDUAL`` (relative to |K| |dz| + |rhs|, max norms), else solved again by SciPy's sparse
    LU. Measured: on the 3-D model's KKT matrix (2 × 2 acrylic pull, 340 rows) CasADi's MUMPS
    returned, without an error, a dz with residual 1.0-3.7 (zero dx for a clamp target), where
    SciPy's LU and CasADi's QR solve to 1e-15 and agree with finite differences of the forward
    solves; the planar KKT matrices solve to 1e-14. Raises when neither solves the system."""
    b = np.asarray(ca.DM(rhs))
    if _residual_ok(K, dz, b):
        return dz
    from scipy.sparse.linalg import splu
    dz = splu(scipy_matrix(K).tocsc()).solve(b)
    if not _residual_ok(K, dz, b):
        raise RuntimeError("the KKT system of the forward solution is singular: its "
                           "sensitivities are not defined there")
    return dz


def _residual_ok(K: ca.DM, dz: np.ndarray, b: np.ndarray) -> bool:
    """Whether |K dz − b| ≤ RESIDUAL (|K| |dz| + |b|) (max norms), NaN never."""
    res = float(np.max(np.abs(np.asarray(K @ ca.DM(dz)) - b), initial=0.0))
    scale = (float(ca.mmax(ca.fabs(K))) * float(np.max(np.abs(dz), initial=0.0))
             + float(np.max(np.abs(b), initial=0.0)))
    return bool(np.isfinite(res) and res <= RESIDUAL * scale)


def reduced_stability(K: ca.DM, n: int, method: str = "sparse") -> Stability:
    """Smallest eigenvalue of K's Hessian block (n × n) reduced to the null space of its
    constraint block (module docstring: ``sparse`` or ``dense``)."""
    if method == "sparse":
        try:
            import scipy  # noqa: F401
        except ImportError:                                     # pragma: no cover
            method = "dense"
            if n > DENSE_FALLBACK:
                raise RuntimeError(f"the stability check above {DENSE_FALLBACK} variables "
                                   "needs scipy (pip install scipy)") from None
    if method == "dense":
        return _dense_reduced_min(_dense(K), n)
    negative, rho = _penalised_inertia(K, n)
    if negative:
        if n <= DENSE_FALLBACK:
            found = _dense_reduced_min(_dense(K), n)
            return Stability(found.min_eigenvalue, f"inertia of H + rho J^T J (rho = {rho:.3g}): "
                             f"{negative} negative; value from {found.method}")
        return Stability(float("nan"), f"inertia of H + rho J^T J (rho = {rho:.3g}): "
                         f"{negative} negative eigenvalues (value not computed)")
    mu = _lanczos_smallest(K, n)
    return Stability(mu, f"no negative pivot in LDL^T of H + rho J^T J (rho = {rho:.3g}); "
                     f"smallest by shift-invert Lanczos on the KKT matrix (sigma = {SHIFT:g})")


def _penalised_inertia(K: ca.DM, n: int) -> tuple[int, float]:
    """Negative eigenvalues of H + ρJᵀJ (CasADi's sparse LDLᵀ; H, J the blocks of K), ρ raised
    ×100 until none or RHO_MAX; returns the count at the last ρ and that ρ."""
    H, J = K[:n, :n], K[n:, :n]
    JtJ = ca.mtimes(J.T, J)
    scale = float(ca.mmax(ca.fabs(H))) / max(float(ca.mmax(ca.fabs(JtJ))), 1e-300)
    factor, negative = RHO, -1
    while factor <= RHO_MAX:
        A = H + factor * scale * JtJ
        ls = ca.Linsol("penalised", "ldl", A.sparsity())
        ls.sfact(A)
        ls.nfact(A)
        negative = int(ls.neig(A))
        if negative == 0:
            break
        factor *= 100
    return negative, min(factor, RHO_MAX) * scale


def scipy_matrix(M: ca.DM) -> "scipy.sparse.csc_matrix":
    """A sparse CasADi matrix as SciPy's CSC (the one conversion the sensitivities and the
    stability check use)."""
    import scipy.sparse as sp
    rows, cols = M.sparsity().get_triplet()
    return sp.csc_matrix((np.asarray(M.nonzeros()).ravel(), (rows, cols)), shape=M.shape)


def _dense(K: ca.DM) -> np.ndarray:
    rows, cols = K.sparsity().get_triplet()
    out = np.zeros(K.shape)
    out[rows, cols] = np.asarray(K.nonzeros())
    return out


def _dense_reduced_min(K: np.ndarray, n: int) -> Stability:
    """ZᵀHZ with Z an orthonormal null-space basis of J from a complete QR of Jᵀ."""
    H, J = K[:n, :n], K[n:, :n]
    q, _ = np.linalg.qr(J.T, mode="complete")
    Z = q[:, J.shape[0]:]
    return Stability(float(np.linalg.eigvalsh(Z.T @ H @ Z)[0]), "dense null-space basis (QR of J^T)")


def _lanczos_smallest(K: ca.DM, n: int, sigma: float = SHIFT) -> float:
    """μ_min = σ + 1/ν_max for v ↦ top of (K − σM)⁻¹(v, 0), valid when every μ > σ."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import LinearOperator, eigsh, splu

    size = K.shape[0]
    mat = scipy_matrix(K)
    lu = splu((mat - sp.diags(np.r_[np.full(n, sigma), np.zeros(size - n)])).tocsc())

    def apply(v: np.ndarray) -> np.ndarray:
        return lu.solve(np.r_[np.ravel(v), np.zeros(size - n)])[:n]

    nu = eigsh(LinearOperator((n, n), matvec=apply, dtype=float), k=1, which="LA",
               return_eigenvectors=False, tol=1e-10)
    return float(sigma + 1.0 / nu.max())


def contact_system(st: ContactState, Fp_base: ca.DM, nb: int,
                   keep_active: bool = True) -> tuple[ca.DM, ca.DM, int]:
    """K = [[H, Jᵀ], [J, 0]] of the contact NLP with the inactive gap rows dropped (and, with
    ``keep_active`` False, the active ones too: the test that shows they matter), ∂F/∂p for the
    base parameters, and the Hessian block's size."""
    c = st.cnlp
    H = c.nlpsol_options["hess_lag"](st.x, st.p, 1.0, st.lam)
    H = H + H.T - ca.diag(ca.diag(H))
    J = c.jacobian(st.x, st.p)[1]
    gap = np.arange(c.n_constraints)[c.gap_rows]
    rows = np.r_[np.arange(gap[0]), gap[st.active]] if keep_active else np.arange(gap[0])
    J = J[rows.tolist(), :]
    m, nx = J.shape[0], c.n_variables
    K = ca.blockcat([[H, J.T], [J, ca.DM(m, m)]])
    ngb = c.base.n_constraints
    Fp = ca.vertcat(Fp_base[:nb, :], ca.DM(nx - nb, Fp_base.shape[1]), Fp_base[nb:, :],
                    ca.DM(m - ngb, Fp_base.shape[1]))
    return K, Fp, nx


def sliding_function(c: ContactNLP) -> ca.Function:
    """(x, λ, p) ↦ the slots' closest-point conditions C = ((P_A − P_B)·T_A, (P_A − P_B)·T_B)
    (2 per slot, T_A at s_A on loop k_A, T_B = T(Θ)), their Jacobians by x and by p, and the
    Jacobian by p of (∇ₓ(λ_cᵀ g_c), g_c) over the contact rows g_c (only they hold s_A, s_B)."""
    base, n = c.base, c.n_slots
    pr = base.problem
    x, p = c.nlp["x"], c.nlp["p"]
    nc, N, nb = n_coeffs(pr.t), pr.n_loops, base.n_variables
    A = ca.reshape(x[base.x.slice("coeffs")], nc, N)
    z = ca.reshape(x[nb:], VARS, n)
    sA = p[base.p.size:base.p.size + n]
    phis = basis_mx(ca.transpose(sA), pr.L, pr.t)
    theta_A = sum(phis[k] * A[k, c.kA.tolist()] for k in range(nc))
    d = z[0:2, :] - z[2:4, :]
    C = ca.vec(ca.vertcat(d[0, :] * ca.cos(theta_A) + d[1, :] * ca.sin(theta_A),
                          d[0, :] * ca.cos(z[4, :]) + d[1, :] * ca.sin(z[4, :])))
    gc = c.nlp["g"][base.n_constraints:]
    lam = ca.MX.sym("lam_c", gc.numel())
    Fc = ca.vertcat(ca.gradient(ca.dot(lam, gc), x), gc)
    return ca.Function("sliding", [x, lam, p],
                       [ca.jacobian(C, x), ca.jacobian(C, p), ca.jacobian(Fc, p)])


def sliding_system(st: ContactState, Fp_base: ca.DM, nb: int, fn: ca.Function
                   ) -> tuple["scipy.sparse.csc_matrix", np.ndarray, int]:
    """The KKT system of :func:`contact_system` extended by the active slots' material points
    s_A, s_B as unknowns, held at closest points by C = 0 (:func:`sliding_function`): the gap
    of the true distance between the yarns, not of two points fixed on them (measured on the
    squeezed loop: dx/dp of the fixed points is 7 % off central differences of the forward
    solves, 4e-5 of the sliding ones). Unknowns (x, s, λ_kept); returns the matrix, ∂F/∂p and
    where λ starts."""
    import scipy.sparse as sp
    c = st.cnlp
    K, Fp, nx = contact_system(st, Fp_base, nb)
    n, ngb = c.n_slots, c.base.n_constraints
    npb = c.base.p.size
    act = np.nonzero(st.active)[0]
    scol = np.r_[npb + act, npb + n + act]                   # s_A, s_B of the active slots
    crow = np.r_[2 * act, 2 * act + 1]
    gap = np.arange(c.n_constraints)[c.gap_rows]
    kept = np.r_[np.arange(gap[0]), gap[st.active]]
    Cx, Cp, Fcp = fn(st.x, st.lam[ngb:], st.p)
    Fcp = scipy_matrix(Fcp)[:, scol]
    Fxs = Fcp[:nx]
    gs = sp.vstack([sp.csr_matrix((ngb, len(scol))), Fcp[nx:]]).tocsr()[kept]
    Cx, Cs = scipy_matrix(Cx)[crow], scipy_matrix(Cp)[crow][:, scol]
    Kd = scipy_matrix(K)
    m = Kd.shape[0] - nx
    top = sp.hstack([Kd[:nx, :nx], Fxs, Kd[:nx, nx:]])
    mid = sp.hstack([Cx, Cs, sp.csr_matrix((len(crow), m))])
    bot = sp.hstack([Kd[nx:, :nx], gs, sp.csr_matrix((m, m))])
    Fpd = scipy_matrix(Fp).toarray()
    rhs = np.vstack([Fpd[:nx], np.zeros((len(crow), Fpd.shape[1])), Fpd[nx:]])
    return sp.vstack([top, mid, bot]).tocsc(), rhs, nx + len(scol)
