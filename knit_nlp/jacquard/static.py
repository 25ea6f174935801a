"""The static equilibrium as a CasADi NLP solved with IPOPT (docs/jacquard.md, "Solvers", `static`).

Formulation (docs/jacquard.md, "Static NLP"): the variables are the particle positions ``x``
only. With ``d_s = x[b_s] + shift_s - x[a_s]`` (``d = B x + c``, ``B`` the sparse incidence
matrix) the energy is

    E(x) = sum_s 1/2 k_s (|d_s| - l0_s)+^2  (+ 1/2 eps max(k) |x - x_natural|^2)

(loop-width springs, an extension: ``1/2 k (l0 - |d|)+^2``), which is C1 and, for rope springs,
convex (a square of a non-negative convex function). The paper's constraints,

    1/2 |d_s|^2 <= 1/2 (lambda_max l_init_s)^2     (length limit, paper 3.4.2; convex)
    X(i+1,j) + offset - X(i,j) >= 0                 (order constraint, paper 3.4.1; linear)

are added by constraint generation: solve with none, add every violated (or nearly active) one,
re-solve warm, until the solution satisfies them all. A minimiser of a relaxation that
satisfies every constraint is a minimiser of the whole problem (globally, as the rope problem is
convex; locally in any case), so the loop ends at the constrained equilibrium; at the benchmark
designs no constraint is active and one solve suffices.

Derivatives (the reason for this shape): the Hessian of the Lagrangian is
``B^T blockdiag(H_s) B`` with one symmetric 2x2 block ``H_s`` per spring, so its nonzeros are
a fixed sparse linear map ``A`` of the 3 distinct entries of every block. ``hess_lag`` is given
to ``nlpsol`` in exactly that form (one small SX Function for the blocks, mapped over the
springs, then ``A``), so CasADi never has to discover the sparsity of, or colour, a
whole-fabric Hessian — that discovery took a minute at 500 x 500.

Boundary particles are fixed by equal bounds at their natural or pulled (``[[pull]]``) places
(IPOPT ``make_parameter``); each floating
component of the spring graph (a zero-energy mode, see springs.build_network) has its centroid
held at its natural centroid by two linear equalities, which is what the explicit dynamics
conserves. Springs that go slack can leave further flat directions; the tiny regularisation
(``[solver] regularization``, default eps = 1e-8) selects the equilibrium nearest the natural
grid.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import casadi as ca
import numpy as np

from ..ipopt import ipopt_options, succeeded
from ..outcome import OUT_OF_TIME, describe
from .problem import JacquardProblem
from .result import JacquardResult
from .springs import Network, SpringSet, build_network, spring_geometry

if TYPE_CHECKING:
    from .newton import NewtonOutcome

MAX_ROUNDS = 20          # constraint-generation rounds before giving up
NEAR_LIMIT = 1e-3        # also add length limits within this relative margin of binding


def merge_parallel(s: SpringSet) -> SpringSet:
    """Springs on the same particle pair with the same rest length, limit and law act as one
    spring of summed stiffness (exact: sum_i 1/2 k_i (l - l0)+^2 = 1/2 (sum k_i) (l - l0)+^2).
    With the default pretensions the pillar and the two systems' longitudinal springs merge.

    Groups are found by one stable lexicographic sort of the keys (a, b, shift, l0, limit,
    law): each merged spring keeps its group's first spring's attributes, in key order."""
    l0, limit = np.round(s.l0, 12), np.round(s.limit, 12)
    keys = (s.a, s.b, s.shift[:, 0], s.shift[:, 1], l0, limit, s.compress)
    order = np.lexsort(keys[::-1])
    starts = np.zeros(s.n, dtype=bool)
    starts[:1] = True
    for key in keys:
        sorted_key = key[order]
        starts[1:] |= sorted_key[1:] != sorted_key[:-1]
    first = order[starts]
    k = np.bincount(np.cumsum(starts) - 1, s.k[order], first.size)
    return SpringSet(s.a[first], s.b[first], s.shift[first], k, s.l_init[first], s.l0[first],
                     s.limit[first], s.compress[first], s.kind[first])


def _ccs(keys: np.ndarray, shape: tuple[int, int]) -> ca.Sparsity:
    """The casadi sparsity of sorted unique column-major keys ``col * nrow + row``."""
    nrow, ncol = shape
    colind = np.concatenate([[0], np.cumsum(np.bincount(keys // nrow, minlength=ncol))])
    return ca.Sparsity(nrow, ncol, colind.tolist(), (keys % nrow).tolist())


def _sparse(rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, shape: tuple[int, int],
            ) -> ca.DM:
    """A casadi DM from triplets, duplicates summed and exact zeros dropped."""
    key = cols.astype(np.int64) * shape[0] + rows          # column-major, as casadi stores
    uniq, inv = np.unique(key, return_inverse=True)
    v = np.bincount(inv.ravel(), vals, uniq.size)
    keep = v != 0.0
    return ca.DM(_ccs(uniq[keep], shape), v[keep])


def _spring_law() -> ca.Function:
    """Energy of one spring and the 3 entries (xx, xy, yy) of its Hessian in d.

    ``sign = +1``: rope, 1/2 k (|d| - l0)+^2; ``sign = -1``: loop-width, 1/2 k (l0 - |d|)+^2.
    A spring of zero length (an edge pushed onto the next course) has zero force, not NaN.
    """
    d, k, l0, sign = ca.SX.sym("d", 2), ca.SX.sym("k"), ca.SX.sym("l0"), ca.SX.sym("sign")
    length = ca.sqrt(ca.sumsqr(d) + 1e-300)    # not norm_2: its gradient is NaN at d = 0
    stretch = ca.fmax(sign * (length - l0), 0)
    energy = 0.5 * k * stretch ** 2
    hess = ca.hessian(energy, d)[0]
    return ca.Function("spring_law", [d, k, l0, sign],
                       [energy, ca.vertcat(hess[0, 0], hess[0, 1], hess[1, 1])],
                       ["d", "k", "l0", "sign"], ["energy", "hess"])


def pairwise_sum(row: ca.MX) -> ca.MX:
    """Sum of a 1 x n row by pairwise (tree) summation: rounding error O(eps log n) instead of
    O(eps n), so that IPOPT's line search can still see the energy decrease near the solution
    of a fabric with a million springs (a plain sum left it backtracking on rounding noise)."""
    n = row.size2()
    while n > 1:
        if n % 2:
            row, n = ca.horzcat(row, ca.MX.zeros(1, 1)), n + 1
        row, n = ca.sum1(ca.reshape(row, 2, n // 2)), n // 2
    return row


@dataclass(frozen=True)
class Incidence:
    """d = B x + c for every spring (rows 2s, 2s+1), and the Hessian's assembly map.

    ``hess_sparsity`` is the upper triangle of B^T blockdiag(H_s) B plus the diagonal;
    ``assemble`` (nnz x 3S+1) maps the stacked block entries ``[h_xx, h_xy, h_yy]_s`` and a
    final diagonal weight to its nonzeros.
    """

    B: ca.DM
    c: np.ndarray
    hess_sparsity: ca.Sparsity
    assemble: ca.DM


def incidence(s: SpringSet, n_particles: int) -> Incidence:
    """Build B, c and the Hessian assembly map for the springs ``s``."""
    nx, ns = 2 * n_particles, s.n
    srow = np.arange(ns)
    rows = np.concatenate([2 * srow, 2 * srow + 1] * 2)
    cols = np.concatenate([2 * s.b, 2 * s.b + 1, 2 * s.a, 2 * s.a + 1])
    vals = np.concatenate([np.ones(2 * ns), -np.ones(2 * ns)])
    B = _sparse(rows, cols, vals, (2 * ns, nx))
    # Hessian: block (r, c) of spring s is sigma_r sigma_c H_s, sigma_a = -1, sigma_b = +1.
    hr, hc, hcol, hval = [], [], [], []
    for end_r, sig_r in ((s.a, -1.0), (s.b, 1.0)):
        for end_c, sig_c in ((s.a, -1.0), (s.b, 1.0)):
            for al, be, m in ((0, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 2)):
                hr.append(2 * end_r + al)
                hc.append(2 * end_c + be)
                hcol.append(3 * srow + m)
                hval.append(np.full(ns, sig_r * sig_c))
    hr, hc = np.concatenate(hr + [np.arange(nx)]), np.concatenate(hc + [np.arange(nx)])
    hcol = np.concatenate(hcol + [np.full(nx, 3 * ns)])
    hval = np.concatenate(hval + [np.ones(nx)])
    upper = hr <= hc
    hr, hc, hcol, hval = hr[upper], hc[upper], hcol[upper], hval[upper]
    uniq, nz = np.unique(hc.astype(np.int64) * nx + hr, return_inverse=True)
    sp = _ccs(uniq, (nx, nx))
    A = _sparse(nz.ravel(), hcol, hval, (uniq.size, 3 * ns + 1))
    c = s.shift.ravel().astype(float)
    return Incidence(B, c, sp, A)


@dataclass(frozen=True)
class WorkingSet:
    """The constraints currently in the NLP: spring indices with a length limit, order pairs."""

    limits: np.ndarray
    orders: np.ndarray


def _centroid_rows(net: Network, nx: int) -> ca.DM:
    """Sparse rows holding the mean x and mean y of each floating component."""
    rows, cols, vals = [], [], []
    for c, idx in enumerate(net.floating):
        for ax in (0, 1):
            rows.append(np.full(idx.size, 2 * c + ax))
            cols.append(2 * idx + ax)
            vals.append(np.full(idx.size, 1.0 / idx.size))
    return _sparse(np.concatenate(rows), np.concatenate(cols), np.concatenate(vals),
                   (2 * len(net.floating), nx))


def _linear_rows(net: Network, work: WorkingSet, nx: int) -> tuple[ca.DM, np.ndarray,
                                                                   np.ndarray]:
    """Order constraints in the working set and centroid equalities: L x in [lo, hi]."""
    parts, lo, hi = [], [], []
    if work.orders.size:
        o = work.orders
        r = np.arange(o.size)
        parts.append(_sparse(np.concatenate([r, r]),
                             np.concatenate([2 * net.order_right[o], 2 * net.order_left[o]]),
                             np.concatenate([np.ones(o.size), -np.ones(o.size)]),
                             (o.size, nx)))
        lo.append(-net.order_offset[o])
        hi.append(np.full(o.size, np.inf))
    if net.floating:
        parts.append(_centroid_rows(net, nx))
        target = np.concatenate([net.natural[idx].mean(axis=0) for idx in net.floating])
        lo.append(target)
        hi.append(target)
    if not parts:
        return ca.DM(0, nx), np.zeros(0), np.zeros(0)
    return ca.vertcat(*parts), np.concatenate(lo), np.concatenate(hi)


def build_nlp(problem: JacquardProblem, net: Network, s: SpringSet, inc: Incidence,
              work: WorkingSet) -> tuple[dict, dict, dict]:
    """The NLP dict, its ``hess_lag`` option and bounds for the springs ``s`` and working set."""
    npart = net.natural.shape[0]
    nx, ns, nl = 2 * npart, s.n, work.limits.size
    x = ca.MX.sym("x", nx)
    d = ca.mtimes(inc.B, x) + ca.DM(inc.c)                   # every spring vector, stacked
    sign = ca.DM(np.where(s.compress, -1.0, 1.0)).T
    energy, h = _spring_law().map(ns)(ca.reshape(d, 2, ns), ca.DM(s.k).T, ca.DM(s.l0).T, sign)
    nat = ca.DM(net.natural.ravel())
    eps = problem.solver.regularization * float(np.max(s.k)) if ns else 0.0
    f = pairwise_sum(energy) + 0.5 * eps * ca.sumsqr(x - nat)
    L, lin_lo, lin_hi = _linear_rows(net, work, nx)
    g_parts, lbg, ubg = [ca.mtimes(L, x)], [lin_lo], [lin_hi]
    if nl:
        r = np.arange(nl)
        sel = _sparse(np.concatenate([2 * r, 2 * r + 1]),
                      np.concatenate([2 * work.limits, 2 * work.limits + 1]),
                      np.ones(2 * nl), (2 * nl, 2 * ns))
        d_lim = ca.reshape(ca.mtimes(sel, d), 2, nl)
        g_parts.append(0.5 * ca.sum1(d_lim ** 2).T)
        lbg.append(np.full(nl, -np.inf))
        ubg.append(0.5 * s.limit[work.limits] ** 2)
    g = ca.vertcat(*g_parts)

    # hess_lag = lam_f (sum_s B_s^T H_s B_s + eps I) + sum_limits lam_i B_i^T I B_i
    lam_f, lam_g, p = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.numel()), ca.MX.sym("p", 0)
    h = lam_f * h
    if nl:
        mu = ca.mtimes(_sparse(work.limits, L.size1() + np.arange(nl), np.ones(nl),
                               (ns, g.numel())), lam_g).T
        h = h + ca.vertcat(mu, ca.DM.zeros(1, ns), mu)
    hnz = ca.mtimes(inc.assemble, ca.vertcat(ca.vec(h), lam_f * eps))
    hess_lag = ca.Function("hess_lag", [x, p, lam_f, lam_g], [ca.MX(inc.hess_sparsity, hnz)],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    fixed = np.repeat(net.fixed, 2)
    flat = net.held.ravel()                                   # pulled edges moved ([[pull]])
    bounds = {"lbx": np.where(fixed, flat, -np.inf), "ubx": np.where(fixed, flat, np.inf),
              "lbg": np.concatenate(lbg), "ubg": np.concatenate(ubg)}
    return {"x": x, "f": f, "g": g}, {"hess_lag": hess_lag}, bounds


def violations(x: np.ndarray, net: Network, s: SpringSet, work: WorkingSet,
               ) -> WorkingSet:
    """Constraints outside the working set that ``x`` violates; when there are any, the
    length limits within ``NEAR_LIMIT`` of binding join them (fewer rounds)."""
    _, length = spring_geometry(x, s)
    outside = np.ones(s.n, dtype=bool)
    outside[work.limits] = False
    gap = x[net.order_right, 0] + net.order_offset - x[net.order_left, 0]
    orders = np.setdiff1d(np.flatnonzero(gap < 0), work.orders)
    if not (outside & (length > s.limit)).any() and not orders.size:
        return WorkingSet(work.limits[:0], orders)
    return WorkingSet(np.flatnonzero(outside & (length > (1 - NEAR_LIMIT) * s.limit)), orders)


def _ipopt_options(problem: JacquardProblem, print_level: int, extra: dict | None) -> dict:
    opts = problem.solver
    return ipopt_options(opts.tol, opts.max_iter, print_level,
                         max_wall_time=opts.max_time,
                         mumps_pivot_order=5,             # METIS (see docs/jacquard.md)
                         hessian_approximation=opts.hessian,
                         fixed_variable_treatment="make_parameter", mu_strategy="adaptive",
                         **(extra or {}))


METHODS = ("auto", "newton", "ipopt")
# the status of a static solve that Newton's method finished (no constraint round needed); the
# message says how: max |dE/dx| against tol, steps, the linear solver
NEWTON_CONVERGED = "Converged"


def newton_applies(problem: JacquardProblem, net: Network, s: SpringSet) -> bool:
    """Whether the first (unconstrained) round can be solved by newton.py: rope springs only
    (convex energy), no floating component (no centroid equalities) and the exact Hessian
    (``[solver] hessian = "limited-memory"`` asks for IPOPT's quasi-Newton)."""
    return problem.solver.hessian == "exact" and not s.compress.any() and not net.floating


def _newton_round(problem: JacquardProblem, net: Network, s: SpringSet, eps: float,
                  deadline: float) -> tuple[np.ndarray, NewtonOutcome, float]:
    """The relaxation without constraints by Newton's method: positions, outcome, set-up s."""
    from .newton import SpringEnergy, minimise      # scipy only where a jacquard solve needs it
    t = time.perf_counter()
    free = ~net.fixed
    energy = SpringEnergy(s, free, net.held, net.natural, eps)
    setup = time.perf_counter() - t
    out = minimise(energy, net.held[free].ravel(), problem.solver.tol,
                   problem.solver.max_iter, deadline)
    return energy.positions(out.z).ravel(), out, setup


def solve_static(problem: JacquardProblem, network: Network | None = None, *,
                 method: str = "auto", print_level: int = 0,
                 extra_options: dict | None = None) -> JacquardResult:
    """Minimise the rope-spring energy under the order and length-limit constraints.

    ``method``: ``"auto"`` (default) solves the first, unconstrained round by Newton's method
    (newton.py) where it applies (``newton_applies``) and IPOPT otherwise; ``"ipopt"`` uses
    IPOPT for every round; ``"newton"`` insists on Newton for the first round. Later rounds
    of the constraint generation (active length limits or order constraints) are IPOPT's,
    warm-started from the previous round. A Newton round that does not converge is handed
    to IPOPT from where it stopped (the status then says so).
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")
    t0 = time.perf_counter()
    net = network or build_network(problem)
    s = merge_parallel(net.springs)
    use_newton = method == "newton" or (method == "auto" and newton_applies(problem, net, s))
    if method == "newton" and not newton_applies(problem, net, s):
        raise ValueError("Newton's method needs rope springs only, no floating component and "
                         "the exact Hessian (see newton_applies)")
    eps = problem.solver.regularization * float(np.max(s.k)) if s.n else 0.0
    work = WorkingSet(np.zeros(0, dtype=int), np.zeros(0, dtype=int))
    x = net.held.ravel().copy()
    timings: dict = {"build_s": time.perf_counter() - t0, "solve_s": 0.0}
    iterations, note = 0, ""
    deadline = t0 + problem.solver.max_time
    first = 1
    if use_newton:
        x, out, setup = _newton_round(problem, net, s, eps, deadline)
        timings["build_s"] += setup
        timings["solve_s"] += sum(out.timings.values())
        timings["profile"] = out.timings
        iterations = out.iterations
        message = f"{out.status} (Newton, {out.iterations} steps, {out.linear})"
        success = out.converged
        if not success and time.perf_counter() >= deadline:
            return _result(problem, net, x, False, OUT_OF_TIME,
                           describe(OUT_OF_TIME, problem.solver.max_time), iterations, timings,
                           1, work)
        new = violations(x.reshape(-1, 2), net, s, work) if success else work
        if success and new.limits.size == 0 and new.orders.size == 0:
            return _result(problem, net, x, True, NEWTON_CONVERGED, message, iterations,
                           timings, 1, work)
        work, first = (new, 2) if success else (work, 1)
        note = "Newton round not converged, IPOPT from its end: " if not success else ""
    return _ipopt_rounds(problem, net, s, x, work, first, timings, iterations, deadline, note,
                         _ipopt_options(problem, print_level, extra_options))


def _result(problem: JacquardProblem, net: Network, x: np.ndarray, success: bool, status: str,
            message: str, iterations: int, timings: dict, rounds: int,
            work: WorkingSet) -> JacquardResult:
    return JacquardResult(problem, net, "static", x.reshape(-1, 2), success, status, message,
                          iterations=iterations, timings=timings,
                          constraints={"rounds": rounds, "length_limits": int(work.limits.size),
                                       "order": int(work.orders.size)})


def _ipopt_rounds(problem: JacquardProblem, net: Network, s: SpringSet, x: np.ndarray,
                  work: WorkingSet, first: int, timings: dict, iterations: int,
                  deadline: float, note: str, ipopt: dict) -> JacquardResult:
    """Constraint generation with IPOPT from round ``first``, warm from ``x``."""
    tb = time.perf_counter()
    inc = incidence(s, net.natural.shape[0])
    timings["build_s"] += time.perf_counter() - tb
    status, success, rounds = "", False, first
    for rounds in range(first, MAX_ROUNDS + 1):
        tb = time.perf_counter()
        if tb >= deadline:
            status, success = OUT_OF_TIME, False
            break
        ipopt["ipopt"]["max_wall_time"] = min(ipopt["ipopt"]["max_wall_time"], deadline - tb)
        nlp, custom, bounds = build_nlp(problem, net, s, inc, work)
        solver = ca.nlpsol("jacquard_static", "ipopt", nlp, {**custom, **ipopt})
        ts = time.perf_counter()
        sol = solver(x0=x, **bounds)
        timings["build_s"] += ts - tb
        timings["solve_s"] += time.perf_counter() - ts
        stats = solver.stats()
        iterations += int(stats["iter_count"])
        status = str(stats["return_status"])
        success = succeeded(status)
        x = np.array(sol["x"]).ravel()
        new = violations(x.reshape(-1, 2), net, s, work)
        if not success or (new.limits.size == 0 and new.orders.size == 0):
            break
        work = WorkingSet(np.union1d(work.limits, new.limits),
                          np.union1d(work.orders, new.orders))
    else:
        status, success = "Constraints_Still_Violated", False
    message = (f"constraints still violated after {MAX_ROUNDS} rounds"
               if status == "Constraints_Still_Violated"
               else describe(status, problem.solver.max_time))
    return _result(problem, net, x, success, status, note + message, iterations, timings,
                   rounds, work)
