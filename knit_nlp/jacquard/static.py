"""The static equilibrium as a CasADi NLP solved with IPOPT (spec "Solvers", `static`).

Formulation (docs/jacquard.md, "Static NLP"): variables are all particle positions and one
slack ``e_s`` per spring. For a rope spring

    minimise  sum_s 1/2 k_s e_s^2
    s.t.      e_s - |x_b + shift - x_a| >= -l0_s        (e_s >= l - l0: epigraph of (l - l0)+)
              0 <= e_s <= lambda_max l_init_s - l0_s     (the bound gives l <= lambda_max l_init)
              X(i+1,j) - X(i,j) >= 0                     (order constraint, paper 3.4.1)

which is smooth and convex (|.| is convex), so its minimiser is the equilibrium of the rope
springs. At the optimum e_s = (l - l0)+. Loop-width springs (extension, compression only) use
e_s + l >= l0, e_s >= 0. Boundary particles are fixed by equal bounds; each floating component
of the spring graph (a zero-energy mode, see springs.build_network) gets its centroid held at
its natural centroid by two linear equalities, which is exactly what the explicit dynamics
conserves (internal forces carry no net momentum). Springs that go slack at the equilibrium can
leave further flat directions (e.g. a thick stripe beside net contracts until its underlaps are
slack); a tiny regularisation ``1/2 eps max(k) |x - x_natural|^2`` (``[solver] regularization``,
default eps = 1e-8) then selects the equilibrium nearest the natural grid.

The NLP is assembled from one small casadi Function per spring kind, mapped over the springs of
that kind (``Function.map``), so the expression graph size does not grow with the fabric.
"""
from __future__ import annotations

import time

import casadi as ca
import numpy as np

from .problem import JacquardProblem
from .result import JacquardResult
from .springs import KINDS, Network, SpringSet, build_network


def _spring_function(kind: str, compress: bool) -> ca.Function:
    """g(p, q, e) for one spring: e - |q - p| (rope) or e + |q - p| (loop-width)."""
    p, q, e = ca.SX.sym("p", 2), ca.SX.sym("q", 2), ca.SX.sym("e")
    d = q - p
    length = ca.sqrt(d[0] ** 2 + d[1] ** 2)
    return ca.Function(f"spring_{kind}", [p, q, e], [e + length if compress else e - length])


def _centroid_rows(net: Network, nvar: int) -> ca.DM:
    """Sparse rows holding the mean x and mean y of each floating component."""
    rows, cols, vals = [], [], []
    for c, idx in enumerate(net.floating):
        for ax in (0, 1):
            rows += [2 * c + ax] * idx.size
            cols += (2 * idx + ax).tolist()
            vals += [1.0 / idx.size] * idx.size
    return ca.DM.triplet(rows, cols, ca.DM(vals), 2 * len(net.floating), nvar)


def merge_parallel(s: SpringSet) -> SpringSet:
    """Springs on the same particle pair with the same rest length, limit and law act as one
    spring of summed stiffness (exact: sum_i 1/2 k_i (l - l0)+^2 = 1/2 (sum k_i) (l - l0)+^2).
    With the default pretensions the pillar and the two systems' longitudinal springs merge."""
    key = np.column_stack([s.a, s.b, s.shift, np.round(s.l0, 12), np.round(s.limit, 12),
                           s.compress])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    k = np.bincount(inverse, s.k, first.size)
    return SpringSet(s.a[first], s.b[first], s.shift[first], k, s.l_init[first], s.l0[first],
                     s.limit[first], s.compress[first], s.kind[first])


def build_nlp(problem: JacquardProblem, net: Network) -> tuple[dict, dict]:
    """The NLP dict for ``nlpsol`` and its bounds / initial guess (numpy arrays)."""
    s, npart = merge_parallel(net.springs), net.natural.shape[0]
    nx, ns = 2 * npart, s.n
    z = ca.MX.sym("z", nx + ns)
    pos = ca.reshape(z[:nx], 2, npart)
    slack = z[nx:]
    g_parts, lbg, ubg, order_idx = [], [], [], np.zeros(0, dtype=int)
    perm = []
    for kind_id, kind in enumerate(KINDS):
        sel = np.flatnonzero(s.kind == kind_id)
        if sel.size == 0:
            continue
        perm.append(sel)
        fn = _spring_function(kind, bool(s.compress[sel[0]])).map(int(sel.size))
        q = pos[:, s.b[sel].tolist()] + ca.DM(s.shift[sel].T)
        g_parts.append(fn(pos[:, s.a[sel].tolist()], q, slack[sel.tolist()].T).T)
        lo = np.where(s.compress[sel], s.l0[sel], -s.l0[sel])
        lbg.append(lo)
        ubg.append(np.full(sel.size, np.inf))
    if net.order_left.size:
        gap = pos[0, net.order_right.tolist()] + ca.DM(net.order_offset).T \
            - pos[0, net.order_left.tolist()]
        g_parts.append(gap.T)
        lbg.append(np.zeros(net.order_left.size))
        ubg.append(np.full(net.order_left.size, np.inf))
        order_idx = np.arange(net.order_left.size)
    if net.floating:
        c = _centroid_rows(net, nx + ns)
        g_parts.append(ca.mtimes(c, z))
        target = np.concatenate([net.natural[idx].mean(axis=0) for idx in net.floating])
        lbg.append(target)
        ubg.append(target)
    f = 0.5 * ca.dot(ca.DM(s.k), slack ** 2)
    nat = net.natural.ravel()
    eps = problem.solver.regularization * float(np.max(s.k)) if s.n else 0.0
    if eps > 0:
        f = f + 0.5 * eps * ca.sumsqr(z[:nx] - ca.DM(nat))
    lbx = np.concatenate([np.where(np.repeat(net.fixed, 2), nat, -np.inf), np.zeros(ns)])
    ubx = np.concatenate([np.where(np.repeat(net.fixed, 2), nat, np.inf),
                          np.where(s.compress, np.inf, s.limit - s.l0)])
    e0 = np.where(s.compress, 0.0, np.maximum(s.l_init - s.l0, 0.0))
    data = {"x0": np.concatenate([nat, e0]), "lbx": lbx, "ubx": ubx,
            "lbg": np.concatenate(lbg), "ubg": np.concatenate(ubg), "n_order": order_idx.size}
    return {"x": z, "f": f, "g": ca.vertcat(*g_parts)}, data


def solve_static(problem: JacquardProblem, network: Network | None = None, *,
                 print_level: int = 0, extra_options: dict | None = None) -> JacquardResult:
    """Minimise the rope-spring energy under the order and length-limit constraints (IPOPT)."""
    t0 = time.perf_counter()
    net = network or build_network(problem)
    nlp, data = build_nlp(problem, net)
    opts = problem.solver
    ipopt = {"tol": opts.tol, "max_iter": opts.max_iter, "print_level": print_level,
             "sb": "yes",
             "linear_solver": "mumps", "mumps_pivot_order": 5,   # METIS: 8 % faster, 100 x 100
             "hessian_approximation": opts.hessian,
             "fixed_variable_treatment": "make_parameter", "mu_strategy": "adaptive",
             "acceptable_iter": 0}
    ipopt.update(extra_options or {})
    solver = ca.nlpsol("jacquard_static", "ipopt", nlp,
                       {"ipopt": ipopt, "print_time": False, "expand": False})
    t1 = time.perf_counter()
    sol = solver(x0=data["x0"], lbx=data["lbx"], ubx=data["ubx"], lbg=data["lbg"],
                 ubg=data["ubg"])
    t2 = time.perf_counter()
    stats = solver.stats()
    x = np.array(sol["x"]).ravel()[: 2 * net.natural.shape[0]].reshape(-1, 2)
    return JacquardResult(problem, net, "static", x, bool(stats["success"]),
                          str(stats["return_status"]), iterations=int(stats["iter_count"]),
                          timings={"build_s": t1 - t0, "solve_s": t2 - t1})
