"""Try yarn contact as Incremental Potential Contact's barrier in IPOPT's objective, instead of
the package's gap rows (docs/contact.md, "Tried and not kept").

The energy of the pairs the package's search finds (``model/contact/pairs.py``; material points
fixed during a solve, as the rows' slots are) is added to the paper's objective:

    E_c(x) = κ Σ b(g − required + ε),   b(d) = −(d − d̂)² ln(d / d̂) for d < d̂, else 0

(Li et al. 2020), g = σ (P_A − P_B)·N_B the signed normal gap of ``transcription/contact.py``
written in the two loops' variables (eq. 1 by the cell rule of ``curves.py``), κ = force / d̂.
No contact variables and no rows: the KKT system keeps the paper's size, and its Hessian gains
the blocks between the loops of a pair. Gradient and Hessian are closed form (numpy, only the
pairs within d̂; ``--check`` compares them with finite differences). E_c is NaN where d ≤ 0,
so IPOPT's line search cuts a step back before yarns touch (CasADi warns of each NaN on
stderr, IPOPT "cuts back alpha"); a pair already at d <= 0 where a step starts gets its own ε
to start just inside. Each load step is solved for each d̂ of ``--dhat`` (× 2r) in turn, warm.

    OMP_NUM_THREADS=1 python scripts/try_barrier_contact.py [--size 6] [--steps 4] \
        [--dhat 0.1 0.01 0.001] [--force 0.1] [--first] [--budget 150] [--check]

prints each load step: pairs, IPOPT iterations per d̂, seconds, IPOPT's status, the rows'
largest violation at the end and at the start, whether the state is free of new crossings
(``crossings.judge``) and the gaps the search finds short of 2r(1 − 1e-3) there.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import casadi as ca
import numpy as np

RADIUS = 0.15


def barrier(d: np.ndarray, dhat: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """IPC's b(d) and its first two derivatives (zero from d̂ on; d > 0)."""
    d = np.asarray(d, dtype=float)
    on = d < dhat
    dd = np.where(on, d, dhat)
    lg, e = np.log(dd / dhat), dd - dhat
    return (np.where(on, -e * e * lg, 0.0), np.where(on, -2 * e * lg - e * e / dd, 0.0),
            np.where(on, -2 * lg - 4 * e / dd + e * e / (dd * dd), 0.0))


class Prefix:
    """Every loop's derivatives of I(a; s) = ∫₀ˢ (cos θ, sin θ) from 0 to each cell start, by
    the cell rule (the positions are ``Curves``'): ∂I/∂a (N, M+1, 2, nc) and, with ``second``,
    ∂²I/∂a² (N, M+1, 2, nc, nc)."""

    def __init__(self, coeffs: np.ndarray, L: float, t: int, second: bool) -> None:
        from knit_nlp.weft.model.basis import basis_at
        from knit_nlp.weft.model.contact.curves import cell_nodes
        u, hw = cell_nodes(L, t)
        phi = basis_at(u, L, t)                                       # (M, Q, nc)
        th = np.einsum("mqc,nc->nmq", phi, coeffs)
        c, s = np.cos(th), np.sin(th)

        def prefix(inc: np.ndarray) -> np.ndarray:
            return np.concatenate([np.zeros_like(inc[:, :1]), np.cumsum(inc, 1)], 1)

        self.second = second
        self.dI = prefix(np.stack([-np.einsum("nmq,q,mqc->nmc", s, hw, phi),
                                   np.einsum("nmq,q,mqc->nmc", c, hw, phi)], 2))
        if second:
            pp = phi[..., :, None] * phi[..., None, :]
            self.d2I = prefix(np.stack([-np.einsum("nmq,q,mqcd->nmcd", c, hw, pp),
                                        -np.einsum("nmq,q,mqcd->nmcd", s, hw, pp)], 2))


class Points:
    """Fixed material points (k, s): their cell, the partial cell's nodes and φ there."""

    def __init__(self, k: np.ndarray, s: np.ndarray, L: float, t: int) -> None:
        from knit_nlp.weft.model.basis import basis_at
        from knit_nlp.weft.model.contact.curves import cell_of, cell_rule
        M, xi, self.w = cell_rule(t)
        self.k, self.s = np.asarray(k), np.asarray(s, dtype=float)
        self.j = cell_of(self.s, L, t)
        self.ell = self.s - self.j * (L / M)
        self.phin = basis_at((self.j * (L / M))[:, None] + self.ell[:, None] * xi, L, t)
        self.phis = basis_at(self.s, L, t)

    def at(self, coeffs, pre: Prefix, sel, second: bool = False) -> list[np.ndarray]:
        """∂I/∂a and (``second``; ``pre`` must hold the second derivatives) ∂²I/∂a² of the
        points ``sel``."""
        k, j, ell, phin = self.k[sel], self.j[sel], self.ell[sel], self.phin[sel]
        th = np.einsum("pqc,pc->pq", phin, coeffs[k])
        lw = ell[:, None] * self.w
        c, s = np.cos(th) * lw, np.sin(th) * lw
        out = [pre.dI[k, j] + np.stack([-np.einsum("pq,pqc->pc", s, phin),
                                        np.einsum("pq,pqc->pc", c, phin)], 1)]
        if second:
            out.append(pre.d2I[k, j] - np.stack([np.einsum("pq,pqc,pqd->pcd", c, phin, phin),
                                                 np.einsum("pq,pqc,pqd->pcd", s, phin, phin)],
                                                1))
        return out


class BarrierEnergy:
    """E_c over fixed pairs with its gradient and the upper triangle of its Hessian."""

    def __init__(self, base, pairs, kappa: float, dhat: float, eps) -> None:
        from knit_nlp.weft.model.basis import n_coeffs
        pr = base.problem
        self.base, self.L, self.t, self.nc = base, pr.L, pr.t, n_coeffs(pr.t)
        self.sigma, self.req = pairs.sigma, pairs.required
        self.A, self.B = Points(pairs.kA, pairs.sA, pr.L, pr.t), Points(pairs.kB, pairs.sB,
                                                                          pr.L, pr.t)
        self.kappa, self.dhat, self.eps = kappa, dhat, eps
        self.profile = barrier           # b, b', b'' of d (check() puts b(d) = d here)
        c0, s0, nc = base.x.slice("coeffs").start, base.x.slice("starts").start, self.nc

        def loc(k: np.ndarray) -> np.ndarray:                # (a_k, X_k) columns of x
            return np.concatenate([c0 + nc * k[:, None] + np.arange(nc),
                                   s0 + 2 * k[:, None] + np.arange(2)], 1)

        self.gidx = np.concatenate([loc(pairs.kA), loc(pairs.kB)], 1)
        m2 = self.gidx.shape[1]
        gi = np.repeat(self.gidx[:, :, None], m2, 2)
        gj = np.repeat(self.gidx[:, None, :], m2, 1)
        keep = gi <= gj                                  # upper triangle, repeats summed
        self.e_pair, li, lj = np.nonzero(keep)
        self.e_loc = li * m2 + lj
        self.sp, pos = ca.Sparsity.triplet(base.x.size, base.x.size, gi[keep].tolist(),
                                           gj[keep].tolist(), True)
        self.e_pos = np.asarray(pos)
        self._x, self._st = None, {}

    def state(self, x: np.ndarray) -> dict:
        """Gaps of every pair at x (positions and angles by ``Curves``, the package's cell
        rule); the derivatives' tables come later, for the pairs within d̂ (:meth:`_first`)."""
        from knit_nlp.weft.model.contact.curves import Curves
        x = np.array(x, dtype=float)                     # a copy: CasADi reuses its buffers
        if self._x is not None and np.array_equal(x, self._x):
            return self._st
        base, N = self.base, self.base.problem.n_loops
        coeffs = base.x.get(x, "coeffs").T.reshape(N, -1)
        curves = Curves(coeffs, base.x.get(x, "starts").T.reshape(N, 2), self.L, self.t)
        dv = curves.points(self.A.k, self.A.s) - curves.points(self.B.k, self.B.s)
        thB = curves.angle(self.B.k, self.B.s)
        T = np.stack([np.cos(thB), np.sin(thB)], 1)
        Nn = np.stack([-np.sin(thB), np.cos(thB)], 1)
        g = self.sigma * np.sum(dv * Nn, 1)
        self._x = x
        self._st = dict(coeffs=coeffs, T=T, N=Nn, dT=np.sum(dv * T, 1), g=g,
                        d=g - self.req + self.eps, pre=None)
        return self._st

    def _first(self, st: dict, on: np.ndarray, second: bool = False) -> tuple:
        """∂I/∂a at A's and B's points of the pairs ``on``: (dI_A, dI_B), or with ``second``
        (dI_A, d²I_A, dI_B, d²I_B). The loops' table is kept for x."""
        pre = st["pre"]
        if pre is None or (second and not pre.second):
            pre = st["pre"] = Prefix(st["coeffs"], self.L, self.t, second)
        A = self.A.at(st["coeffs"], pre, on, second)
        B = self.B.at(st["coeffs"], pre, on, second)
        return (*A, *B) if second else (A[0], B[0])

    def energy(self, x: np.ndarray) -> float:
        d = self.state(x)["d"]
        return np.nan if np.any(d <= 0) else self.kappa * self.profile(d, self.dhat)[0].sum()

    def _grad_g(self, st: dict, on: np.ndarray, dIA: np.ndarray, dIB: np.ndarray) -> np.ndarray:
        """∂g/∂(a_A, X_A, a_B, X_B) of the pairs ``on`` (transcription/contact.py's)."""
        sg, Nn = self.sigma[on][:, None], st["N"][on]
        gA = sg * np.einsum("pdc,pd->pc", dIA, Nn)
        gB = -sg * np.einsum("pdc,pd->pc", dIB, Nn) \
            - sg * st["dT"][on][:, None] * self.B.phis[on]
        return np.concatenate([gA, sg * Nn, gB, -sg * Nn], 1)

    def gradient(self, x: np.ndarray) -> np.ndarray:
        st = self.state(x)
        out = np.zeros(self.base.x.size)
        on = st["d"] < self.dhat
        if on.any():
            b1 = self.profile(st["d"][on], self.dhat)[1]
            grad = self._grad_g(st, on, *self._first(st, on))
            np.add.at(out, self.gidx[on], grad * (self.kappa * b1)[:, None])
        return out

    def hessian(self, x: np.ndarray) -> np.ndarray:
        """Nonzeros of the upper triangle: κ (b'' ∇g ∇gᵀ + b' ∇²g) of the pairs within d̂."""
        st = self.state(x)
        on = np.flatnonzero(st["d"] < self.dhat)
        if len(on) == 0:
            return np.zeros(self.sp.nnz())
        nc, m = self.nc, self.nc + 2
        _, b1, b2 = self.profile(st["d"][on], self.dhat)
        dIA, d2A, dIB, d2B = self._first(st, on, second=True)
        grad = self._grad_g(st, on, dIA, dIB)
        sg = self.sigma[on][:, None, None]
        Nn, T, phB = st["N"][on], st["T"][on], self.B.phis[on]

        def outer(a, b):
            return a[:, :, None] * b[:, None, :]

        vA, vB = np.einsum("pdc,pd->pc", dIA, T), np.einsum("pdc,pd->pc", dIB, T)
        H = np.zeros((len(on), 2 * m, 2 * m))
        aA, XA, aB, XB = slice(0, nc), slice(nc, m), slice(m, m + nc), slice(m + nc, 2 * m)
        H[:, aA, aA] = sg * np.einsum("pdcf,pd->pcf", d2A, Nn)
        H[:, aB, aB] = (-sg * np.einsum("pdcf,pd->pcf", d2B, Nn)
                        + sg * (outer(vB, phB) + outer(phB, vB))
                        - st["g"][on][:, None, None] * outer(phB, phB))
        for rows, block in ((aA, -sg * outer(vA, phB)), (XA, -sg * outer(T, phB)),
                            (XB, sg * outer(T, phB))):
            H[:, rows, aB] = block
            H[:, aB, rows] = np.transpose(block, (0, 2, 1))
        H = self.kappa * (b2[:, None, None] * outer(grad, grad) + b1[:, None, None] * H)
        slot = np.full(len(self.req), -1)
        slot[on] = np.arange(len(on))
        sel = slot[self.e_pair] >= 0
        return np.bincount(self.e_pos[sel], minlength=self.sp.nnz(),
                           weights=H.reshape(len(on), -1)[slot[self.e_pair[sel]],
                                                          self.e_loc[sel]])


def solver(base, bar: BarrierEnergy, tol: float, budget: float, print_level: int = 0):
    """IPOPT on the paper's NLP with E_c added to its objective (gradient and Hessian: the
    paper's closed forms plus E_c's)."""
    from knit_nlp.ipopt import ipopt_options
    from knit_nlp.weft.transcription.condensed.glue import _NumericFunction
    from knit_nlp.weft.transcription.derivatives import closed_form_derivatives
    nx, npar = base.x.size, base.p.size
    dense = ca.Sparsity.dense
    x, p = base.nlp["x"], base.nlp["p"]

    def numeric(name, fn, sp, reverse=None):
        return _NumericFunction(name, lambda xv, pv: (fn(xv),), [dense(nx), dense(npar)], [sp],
                                ["x", "p"], ["o"], reverse)

    rev = lambda: _NumericFunction(                                        # noqa: E731
        "Ec_adj", lambda xv, pv, f, af: (float(af[0]) * bar.gradient(xv), np.zeros(npar)),
        [dense(nx), dense(npar), dense(1), dense(1)], [dense(nx), dense(npar)],
        ["x", "p", "out_o", "adj_o"], ["adj_x", "adj_p"])
    E = numeric("Ec", bar.energy, dense(1), rev)
    G, H = numeric("Gc", bar.gradient, dense(nx)), numeric("Hc", bar.hessian, bar.sp)
    d = closed_form_derivatives(base)
    f = base.nlp["f"] + E(x, p)
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", base.g.size)
    opts = ipopt_options(tol, 5000, print_level, mumps_scaling=0, mumps_permuting_scaling=0,
                         first_hessian_perturbation=1.0, max_wall_time=budget)
    opts.update(calc_lam_p=False, calc_lam_x=False, jac_g=d["jac_g"], grad_f=ca.Function(
        "grad_f", [x, p], [f, ca.gradient(base.nlp["f"], x) + G(x, p)], ["x", "p"],
        ["f", "grad_f_x"]), hess_lag=ca.Function(
        "hess_lag", [x, p, lam_f, lam_g], [d["hess_lag"](x, p, lam_f, lam_g) + lam_f * H(x, p)],
        ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]))
    nlp = ca.nlpsol("barrier", "ipopt", {"x": x, "p": p, "f": f, "g": base.nlp["g"]}, opts)
    return nlp, (E, G, H)                  # CasADi keeps no reference to the callbacks


def setup(n: int, budget: float):
    """The n x n diagonal pull with r = RADIUS: (problem, full NLP, the package's contact
    search for it)."""
    from knit_nlp.weft.model.cases import diagonal_pull
    from knit_nlp.weft.solving.contact.rounds import ContactSolver
    from knit_nlp.weft.solving.solve import WeftSolver
    from knit_nlp.weft.transcription.factory import transcribe
    from knit_nlp.weft.model.parametrisation import Full
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import bench_contact                 # the benchmark's problem: its radius, our budget
    pr = bench_contact._problem(diagonal_pull(n), RADIUS, budget)
    base = transcribe(pr, Full())
    return pr, base, ContactSolver(WeftSolver(base), RADIUS)


def check(n: int = 4, seed: int = 0) -> tuple[float, float]:
    """Largest errors of E_c's gradient and of ∇²g (b(d) = d) against central differences on
    a perturbed natural n x n fabric, relative to the largest entry."""
    _, base, search = setup(n, 60.0)
    x0 = base.x0.copy()
    pairs = search.pairs(x0)
    x = x0 + 1e-3 * np.random.default_rng(seed).standard_normal(x0.size)
    bar = BarrierEnergy(base, pairs, 1.0, 5.0, 0.0)
    bar.eps = 0.1 - min(0.0, bar.state(x)["d"].min())
    bar._x = None
    cols, h = np.unique(bar.gidx), 1e-6
    unit = np.eye(x.size)
    fd = np.array([(bar.energy(x + h * unit[i]) - bar.energy(x - h * unit[i])) / (2 * h)
                   for i in cols])
    G = bar.gradient(x)[cols]
    grad_err = np.max(np.abs(fd - G)) / np.max(np.abs(G))
    bar.profile = lambda d, dhat: (np.asarray(d), np.ones_like(d), np.zeros_like(d))
    bar._x = None                        # the Hessian is now ∇²g itself
    Hm = np.array(ca.DM(bar.sp, bar.hessian(x)).full())
    Hf = np.triu(Hm) + np.triu(Hm, 1).T
    err = max(np.max(np.abs((bar.gradient(x + h * unit[i]) - bar.gradient(x - h * unit[i]))
                            / (2 * h) - Hf[:, i])) for i in cols)
    return grad_err, err / np.abs(Hf).max()


def pull(n: int, steps: int, dhats: list[float], force: float, first: bool,
         budget: float) -> None:
    """Load steps from the natural fabric, halved where IPOPT fails or yarns cross."""
    from knit_nlp.weft.model.params import WeftParams
    pr, base, search = setup(n, budget)
    p0, p1 = WeftParams.natural(pr).vector(), base.params.vector()
    x, lam, step, t0 = base.x0.copy(), 0.0, 1.0 / steps, time.perf_counter()
    total = 0
    g = ca.Function("g", [base.nlp["x"], base.nlp["p"]], [base.nlp["g"]])

    def violation(xv: np.ndarray, load: float) -> float:
        return base.violation(np.asarray(g(xv, p0 + load * (p1 - p0))).ravel())

    while lam < 1 - 1e-12 and step > 1e-4:
        target = min(1.0, lam + step)
        pairs = search.pairs(x)
        eps = 5e-4 * 2 * RADIUS
        bar = BarrierEnergy(base, pairs, 0.0, 1.0, eps)
        d = bar.state(x)["d"]            # pairs a little short already start just inside
        bar.eps, bar._x = np.where(d > 0, eps, eps - d + 0.1 * min(dhats) * 2 * RADIUS), None
        nlp, _keep = solver(base, bar, pr.solver.tol, budget)
        ts, its, xs, status = time.perf_counter(), [], x, ""
        for dh in dhats:
            bar.dhat, bar.kappa, bar._x = dh * 2 * RADIUS, force / (dh * 2 * RADIUS), None
            sol = nlp(x0=xs, p=p0 + target * (p1 - p0), lbg=base.lbg, ubg=base.ubg)
            stats = nlp.stats()
            its.append(int(stats["iter_count"]))
            xs, status = np.asarray(sol["x"]).ravel(), str(stats["return_status"])
            if not stats["success"]:
                break
        total += sum(its)
        clean = search.look(xs).verdict.clean
        found = search.pairs(xs) if clean else None
        short = None if found is None else int(np.sum(found.gap < found.required * (1 - 1e-3)))
        print(f"load {target:.4f}: {len(pairs)} pairs, IPOPT iterations {its}, "
              f"{time.perf_counter() - ts:.1f} s, {status}, rows' largest violation "
              f"{violation(xs, target):.2e} (start {violation(x, target):.2e}), "
              f"no new crossing: {clean}, "
              f"gaps short of 2r(1-1e-3): {short}", flush=True)
        if first:
            break
        if status != "Solve_Succeeded" or not clean or short:
            step /= 2
            continue
        x, lam = xs, target
    if not first:
        print(f"{n} x {n}: load {lam:.4f} reached{'' if lam >= 1 - 1e-12 else ' (stalled)'}, "
              f"{total} IPOPT iterations, {time.perf_counter() - t0:.1f} s")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=6)
    ap.add_argument("--steps", type=int, default=4, help="first load steps")
    ap.add_argument("--dhat", type=float, nargs="+", default=[0.1, 0.01, 0.001],
                    help="barrier widths d̂ in turn, as fractions of 2r")
    ap.add_argument("--force", type=float, default=0.1, help="κ d̂: the barrier's force scale")
    ap.add_argument("--first", action="store_true", help="the first load step only")
    ap.add_argument("--budget", type=float, default=150.0, help="seconds per IPOPT solve")
    ap.add_argument("--check", action="store_true",
                    help="only compare the derivatives with finite differences (4 x 4)")
    a = ap.parse_args(argv)
    if a.check:
        g, h = check()
        print(f"gradient of E_c: {g:.1e}, Hessian of g: {h:.1e} (relative to the largest entry)")
        return
    pull(a.size, a.steps, a.dhat, a.force, a.first, a.budget)


if __name__ == "__main__":
    main()
