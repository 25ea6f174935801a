"""The forward equilibrium, built once, with its first-order sensitivities and second-order check.

The forward problem (eq. 13) is equality constrained: min f(x, p) s.t. g(x, p) = 0, where p holds
clamp targets, rigid motions, stiffnesses and loads. Its first-order conditions are the smooth
system F(z, p) = (∇ₓL, g) = 0 with z = (x, λ), L = f + λᵀg (CasADi's sign convention). By the
implicit-function theorem dz/dp = −K⁻¹ ∂F/∂p with K = ∂F/∂z = [[∇²ₓₓL, Jᵀ], [J, 0]], the KKT
matrix: one sparse factorization (MUMPS) gives the sensitivities to every parameter.

Stability: the equilibrium is a strict local minimum when the Hessian of the Lagrangian reduced
to the null space of J, ZᵀHZ with Z orthonormal, is positive definite. Two ways, measured:
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
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..model.problem import WeftProblem
from ..model.params import WeftParams
from ..model.parametrisation import Full
from ..output.results import WeftResult
from ..solving.solve import SolveReport, WeftSolver, solve
from ..transcription.factory import transcribe
from ..transcription.full import FullNLP

try:    # with the module, not inside the first stability check: a one-time 0.15-0.5 s import,
    import scipy.sparse.linalg  # noqa: F401  (Python's, not a solve's cost; measured)
except ImportError:             # pragma: no cover  (scipy is optional: the dense check then)
    pass

SHIFT = -1e-6               # σ of the shift-invert Lanczos: just below zero
RHO = 1e3                   # first penalty of the inertia test, times max|H| / max|JᵀJ|
RHO_MAX = 1e9               # largest penalty tried (same scaling) before declaring a saddle
DENSE_FALLBACK = 4000       # variables; without scipy the dense method runs up to this size


@dataclass
class Stability:
    """The second-order check: smallest eigenvalue of the reduced Hessian and how it was found."""

    min_eigenvalue: float
    method: str

    @property
    def stable(self) -> bool:
        return bool(self.min_eigenvalue > 0.0)


class Equilibrium:
    """A weft problem's forward NLP and IPOPT instance (built once), plus the KKT Functions."""

    def __init__(self, problem: WeftProblem) -> None:
        if problem.yarn is not None and not self.contact_ready:
            # its solves and sensitivities would ignore the yarn's thickness
            raise ValueError(f"{problem.source}: Equilibrium ignores [yarn] radius; build it "
                             "with contact_equilibrium.equilibrium_for(problem)")
        t0 = time.perf_counter()
        self.problem = problem
        self.wnlp: FullNLP = transcribe(problem, Full())
        self.solver = WeftSolver(self.wnlp)
        nlp = self.wnlp.nlp
        x, p, g = nlp["x"], nlp["p"], nlp["g"]
        lam = ca.MX.sym("lam", g.numel())
        F = ca.vertcat(ca.gradient(nlp["f"] + ca.dot(lam, g), x), g)
        self._dFdp = ca.Function("dFdp", [x, lam, p], [ca.jacobian(F, p)])
        # K from the IPOPT instance's own Hessian and Jacobian Functions (built with it), not
        # a second symbolic Jacobian: 0.14 s less per build at 10 x 10, same matrix to 7e-15
        self._hess = self.solver.solver.get_function("nlp_hess_l")
        self._jac_g = self.solver.solver.get_function("nlp_jac_g")
        self._linsol: ca.Linsol | None = None
        self.build_s = time.perf_counter() - t0
        self.forward_solves = 0

    contact_ready = False       # whether the KKT system holds active yarn contacts

    @property
    def n(self) -> int:
        return self.wnlp.n_variables

    def solve(self, p: np.ndarray, x0: np.ndarray | None = None,
              origin: tuple[np.ndarray, np.ndarray] | None = None) -> SolveReport:
        """The forward solve at parameters p (direct, then continuation; see weft.solve);
        ``origin`` (a solved state and its parameters) is for paths with contact only."""
        self.forward_solves += 1
        return solve(self.wnlp, self.solver, params=WeftParams.from_vector(self.problem, p), x0=x0)

    def result(self, report: SolveReport, p: np.ndarray) -> WeftResult:
        """The typed forward result of a solve at parameters p."""
        return WeftResult(self.wnlp, report, WeftParams.from_vector(self.problem, p), self.build_s,
                          self.solver.violation(report.x, p))

    def kkt(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray) -> tuple[ca.DM, ca.DM]:
        """The KKT matrix K = ∂F/∂(x, λ) = [[H, Jᵀ], [J, 0]] and ∂F/∂p at a solution."""
        H = self._hess(x, p, 1.0, lam)                       # upper triangle of ∇²ₓₓL
        J = self._jac_g(x, p)[1]
        H = H + H.T - ca.diag(ca.diag(H))
        K = ca.blockcat([[H, J.T], [J, ca.DM(J.shape[0], J.shape[0])]])
        return K, self._dFdp(x, lam, p)

    def sensitivity(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray,
                    dp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """dx/dθ and dλ/dθ (n × k, m × k) for parameter directions dp = ∂p/∂θ (size(p) × k),
        by the implicit-function theorem on F(z, p) = 0 (one factorization of K)."""
        K, Fp, nx = self.system(x, lam, p)
        if self._linsol is None or self._linsol.sparsity() != K.sparsity():
            self._linsol = ca.Linsol("kkt", "mumps", K.sparsity())
        self._linsol.sfact(K)
        self._linsol.nfact(K)
        rhs = -(Fp @ ca.DM(np.asarray(dp, dtype=float).reshape(Fp.shape[1], -1)))
        dz = np.asarray(self._linsol.solve(K, rhs))
        return dz[:self.n], dz[nx:]

    def system(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray) -> tuple[ca.DM, ca.DM, int]:
        """The KKT matrix, ∂F/∂p and the size of K's Hessian block (here: kkt, n)."""
        K, Fp = self.kkt(x, lam, p)
        return K, Fp, self.n

    def linear_system(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray
                      ) -> tuple["scipy.sparse.csc_matrix", np.ndarray, int]:
        """The sensitivities' linear system A dz = −Fp dp as SciPy/NumPy matrices, and where
        dλ starts in dz (dλ's first rows are the base constraints': clamp reactions read
        alike with and without contact). Here the KKT system ``kkt``; with contact, the
        active contacts' (``ContactEquilibrium.linear_system``)."""
        K, Fp = self.kkt(x, lam, p)
        return scipy_matrix(K), np.asarray(ca.DM(Fp)), self.n

    def stability(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray,
                  method: str = "sparse") -> Stability:
        """Smallest eigenvalue of the Lagrangian Hessian reduced to the null space of J."""
        K, _, n = self.system(x, lam, p)
        return reduced_stability(K, n, method)


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
    """A sparse CasADi matrix as SciPy's CSC (the one conversion the sensitivities, the
    stability check and contact_equilibrium use)."""
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
