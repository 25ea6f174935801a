"""The forward equilibrium with yarn contact (``[yarn] radius``) for control, fit and
calibrate (``equilibrium_for`` chooses it): its solve, its implicit-function sensitivities and
its stability check hold the active contacts.

Forward solve: ``solving.contact.solve_with_contact`` (the paper's model first, then contact
rounds or load steps with contact), or, inside the control iteration, one load step with contact
from the last solved state (``origin``) to the new actuation, halved where yarns would cross —
the path the clamps actually travel. The contact solver keeps (``ContactSolver.last``) the
last accepted solve of the contact NLP: its slots (material points s_A, s_B and sides σ), its
full solution (base variables and the slots' lifted P_A, P_B, Θ) and multipliers.

Sensitivities: the KKT system of that contact NLP at its solution, with the lifting rows as
equalities, the active gap rows (``solving.contact.active.active_gaps``: pushing, and nearer
their bound than they push, as the result's ``contact`` block lists them) as equalities and the
inactive gap rows dropped — the standard sensitivity of an inequality-constrained minimum
under strict complementarity, valid while the active set does not change. The parameters of
control (clamp targets, rigid motions) enter only the base rows, so ∂F/∂p is the base NLP's,
padded with zeros for the slots' rows. The active slots' material points s_A, s_B are
unknowns too, held at closest points ((P_A − P_B)·T_A = (P_A − P_B)·T_B = 0): the gap's
gradient is the same with them fixed (envelope theorem), but its curvature, times the contact
force, enters K — fixed points give dx/dp 7 % off central differences on the squeezed loop,
sliding ones 4e-5 (``sliding_system``).

Stability: the Lagrangian Hessian of the contact NLP (points held) reduced to the null space of
the Jacobian of the base equalities, the lifting rows and the active gap rows
(``reduced_stability``).
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..model.params import WeftParams
from ..model.problem import WeftProblem
from ..output.results import WeftResult
from ..solving.contact.rounds import ContactRun, ContactSolver, Warm
from ..solving.contact.active import active_gaps
from ..solving.contact.solve import contact_block, solve_with_contact
from ..solving.solve import SolveReport
from ..model.basis import n_coeffs
from ..transcription.contact import VARS, ContactNLP, _basis
from .equilibrium import Equilibrium, scipy_matrix

KEEP = 16                  # solved contact states remembered (by base solution) for the KKT
# ... for a calibration curve, whose nodes' sensitivities are taken after the whole pull (up to
# curve.NODES x 10 steps, each possibly halved): every state of a pull must stay
CURVE_KEEP = 1024
# re-solves with the pairs searched on a forward solution: with 2, place_stitch_yarn's forward
# check ended 1.64e-3 from the control's state (over its radius / 100), the forward solve less
# settled (its energy 6.6e-7 higher, measured on a variant of the rows); with 4, 1.42e-4
POLISH = 4


@dataclass
class ContactState:
    """An accepted solve of the contact NLP: the NLP, its parameters (base p, s_A, s_B, σ),
    solution, multipliers, and which gap rows are active."""

    cnlp: ContactNLP
    p: np.ndarray
    x: np.ndarray
    lam: np.ndarray
    active: np.ndarray          # per slot
    block: dict

    @property
    def n_active(self) -> int:
        return int(self.active.sum())


class ContactEquilibrium(Equilibrium):
    """:class:`Equilibrium` of a problem with ``[yarn] radius`` (module docstring)."""

    contact_ready = True

    def __init__(self, problem: WeftProblem, keep: int = KEEP) -> None:
        super().__init__(problem)
        self.contact = ContactSolver(self.solver, problem.yarn.radius)
        self.keep = keep
        self.states: OrderedDict[bytes, ContactState | None] = OrderedDict()
        self.blocks: dict[bytes, dict] = {}

    def solve(self, p: np.ndarray, x0: np.ndarray | None = None,
              origin: tuple[np.ndarray, np.ndarray] | None = None) -> SolveReport:
        """Solve with contact at p: one load step from ``origin`` (state, parameters) when given
        and it succeeds, else ``solve_with_contact`` from x0 (or the usual start)."""
        self.forward_solves += 1
        self.contact.last = None
        rep = self._from_origin(p, origin) if origin is not None else None
        if rep is None:
            rep, block = solve_with_contact(self.wnlp, self.solver, self.contact,
                                            WeftParams.from_vector(self.problem, p), x_start=x0)
        else:
            block = self._block(rep, "one load step with contact from the last solved state")
        if rep.success and self.contact.last is not None and self._polish(p, rep):
            last = self.contact.last
            run = ContactRun(rep, last.pairs, last.lam)
            block = contact_block(self.problem, self.contact, run, block["route"] + ", polished",
                                  self.problem.solver.tol)
        self._remember(rep, block)
        return rep

    def _polish(self, p: np.ndarray, rep: SolveReport) -> bool:
        """Solve again (warm) with the pairs searched on the solution, ``POLISH`` times: the
        rounds accept contact points that moved less than half a sample, so two paths to the
        same parameters end up to ~1e-3 apart; the re-solves make x(p) smooth enough for the
        outer iteration and its forward check (measured: tests/test_contact_control.py)."""
        c, polished = self.contact, False
        for _ in range(POLISH):
            kept = c.last
            found = c.pairs(rep.x)
            out, _ = c.solve_once(p, rep.x, found, Warm(rep.lam_g, kept.pairs, kept.lam), rep, [],
                                  "polish")
            xn = out.x[:self.wnlp.n_variables]
            if not out.success or c.crossed(xn, found, c.pairs(xn)):
                c.last = kept
                break
            rep.x, rep.lam_g, rep.objective = xn, out.lam_g[:self.wnlp.n_constraints], out.objective
            polished = True
        return polished

    def _from_origin(self, p: np.ndarray, origin) -> SolveReport | None:
        """contact.run from a solved, uncrossed state to p in one load step (halved as needed)."""
        x, p_from = origin
        if not self.contact.clean(x):
            return None
        self.solver.start_clock()           # the contact solves share its clock
        report = SolveReport(False, "", x, np.zeros(self.wnlp.n_constraints), np.nan, 0, 0.0)
        self._run = self.contact.run(p, p_from, x, 1, report)
        return self._run.report if self._run.report.success else None

    def _block(self, rep: SolveReport, route: str) -> dict:
        return contact_block(self.problem, self.contact, self._run, route,
                             self.problem.solver.tol)

    def _remember(self, rep: SolveReport, block: dict) -> None:
        """Keep the contact NLP's solution that belongs to the base solution rep.x."""
        key = np.asarray(rep.x).tobytes()
        state = None
        if rep.success and self.contact.solved_at(rep.x):
            last = self.contact.last
            cnlp = last.cnlp
            active = active_gaps(cnlp.gaps(last.x, last.sigma), last.required,
                                 cnlp.gap_multipliers(last.lam_g), last.used,
                                 self.problem.solver.tol, 2 * self.contact.radius)
            state = ContactState(cnlp, last.params, last.x, last.lam_g, active, block)
        self.states[key] = state
        self.blocks[key] = block
        while len(self.states) > self.keep:
            old, _ = self.states.popitem(last=False)
            self.blocks.pop(old, None)

    def state(self, x: np.ndarray) -> ContactState | None:
        """The contact solve behind base solution x (None: no contact solve, none active).
        A ValueError for an x this equilibrium did not solve (or forgot: ``keep``): its
        sensitivities would silently miss the contacts."""
        key = np.asarray(x).tobytes()
        if key not in self.states:
            raise ValueError(f"no contact solve of this equilibrium ends at this state (it "
                             f"keeps the last {self.keep}): solve it here first")
        return self.states[key]

    def result(self, report: SolveReport, p: np.ndarray) -> WeftResult:
        """The forward result with its ``contact`` block (as ``knit-nlp solve`` writes it)."""
        res = super().result(report, p)
        res.build_s += self.contact.build_s
        res.extra["contact"] = self.blocks.get(np.asarray(report.x).tobytes(), {})
        return res

    def sensitivity(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray,
                    dp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """dx/dθ (and the kept rows' dλ/dθ) with the active contacts' points sliding along the
        yarns as closest points (``sliding_system``); without active contacts, the base one."""
        st = self.state(x)
        if st is None or not st.active.any():
            return super().sensitivity(x, lam, p, dp)
        A, rhs, nz = self.linear_system(x, lam, p)
        dp = np.asarray(dp, dtype=float).reshape(rhs.shape[1], -1)
        dz = splu(A).solve(np.asarray(-(rhs @ dp)))
        return dz[:self.n], dz[nz:]

    def linear_system(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray
                      ) -> tuple["sp.csc_matrix", np.ndarray, int]:
        """The system ``sensitivity`` solves (``sliding_system``: unknowns x, the active
        slots' s, the kept rows' λ, base constraints first), ∂F/∂p and where λ starts;
        without active contacts, the base one."""
        st = self.state(x)
        if st is None or not st.active.any():
            return super().linear_system(x, lam, p)
        return sliding_system(st, self._dFdp(x, st.lam[:self.wnlp.n_constraints], p), self.n,
                              self._sliding(st.cnlp))

    def _sliding(self, cnlp: ContactNLP) -> ca.Function:
        if getattr(self, "_slide_for", None) is not cnlp:
            self._slide_fn, self._slide_for = sliding_function(cnlp), cnlp
        return self._slide_fn

    def system(self, x: np.ndarray, lam: np.ndarray, p: np.ndarray) -> tuple[ca.DM, ca.DM, int]:
        """The contact NLP's KKT matrix on the base rows, the lifting rows and the active gap
        rows; ∂F/∂p (base parameters) and the size of its Hessian block. Without a contact
        solve behind x (the paper's solution had no contact), the base system."""
        st = self.state(x)
        if st is None or not st.active.any():
            return super().system(x, lam, p)
        return contact_system(st, self._dFdp(x, st.lam[:self.wnlp.n_constraints], p),
                              self.n)


def equilibrium_for(problem: WeftProblem, keep: int = KEEP) -> Equilibrium:
    """The forward equilibrium of a problem: with ``[yarn] radius`` a
    :class:`ContactEquilibrium` (remembering ``keep`` contact states), else the paper's
    :class:`Equilibrium` — the one choice control, fit and calibrate share."""
    return Equilibrium(problem) if problem.yarn is None else ContactEquilibrium(problem, keep)


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
    phis = _basis(ca.transpose(sA), pr.L, pr.t)
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
                   ) -> tuple["sp.csc_matrix", np.ndarray, int]:
    """The KKT system of ``contact_system`` extended by the active slots' material points
    s_A, s_B as unknowns, held at closest points by C = 0 (``sliding_function``): the gap of
    the true distance between the yarns, not of two points fixed on them (measured on the
    squeezed loop: dx/dp of the fixed points is 7 % off central differences of the forward
    solves, 4e-5 of the sliding ones). Unknowns (x, s, λ_kept); returns the matrix, ∂F/∂p and
    where λ starts."""
    c = st.cnlp
    K, Fp, nx = contact_system(st, Fp_base, nb)
    n, npb, ngb = c.n_slots, c.base.p.size, c.base.n_constraints
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
