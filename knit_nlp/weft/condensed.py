"""The reduced model condensed to the paper's variables, with derivatives assembled by hand.

Variables: the reduced parameters z (eqs. 22-27, ``reduction.course_map``) and the course starts
(x_i^0, y_i^0): p·q·2t + 2p + 2m numbers, the paper's count. Loop starts are not variables: the
start of loop (i, j) is the course start plus the end displacements of loops (i, 1..j−1) (eq. 1),
so every position is course start + a prefix sum of per-loop integrals + the loop's own integral.

Every nonlinear term is one loop's integral D_k(a_k) (2 × P displacements at the material points
the model needs) with a_k = T_k·z. The derivatives are assembled from per-loop blocks, never by
differentiating through the map:

- gradient: point adjoints ψ (spring forces, loads, multipliers) → μ_k = ψ_k plus, at s = L, the
  suffix sum of the course's later adjoints (the transpose of the prefix sum) → ∂/∂a_k =
  J_kᵀμ_k + bending → ∂/∂z = Σ_k T_kᵀ ∂/∂a_k;
- Jacobian rows of the clamps: ∂P/∂w = e(course start) + Σ_{j'<j} J_{(i,j'),L}T_{(i,j')} + J_{k,p}T_k;
- Hessian of the Lagrangian: Σ_k T_kᵀ(Σ_p μ_kp·∇²D_kp + σ R_f diag(D))T_k + σ Σ_springs QᵀMQ with
  Q = ∂(spring vector)/∂w and M = Fᵀdiag(k_a, k_b)F (eqs. 6-10: the springs are quadratic in
  the positions, so this is exact, not Gauss-Newton).

D_k, J_k and Σ_p μ_kp∇²D_kp are closed forms over all loops at once (``kinematics.LoopIntegrals``,
the full model's quadrature; measured faster than mapped CasADi Functions); the rest is numpy over
course blocks of width |cols_i| ≤ 2·q·2t + 4, so set-up and each evaluation are linear in the
loops. IPOPT sees f, g and these derivatives through ``casadi.Callback`` objects given to
``nlpsol`` as ``grad_f``, ``jac_g`` and ``hess_lag``; the Hessian's sparsity is structural
(courses couple only with their neighbours through the springs).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from ..layout import Layout
from .basis import bending_diagonal, n_coeffs, phi
from .kinematics import LoopIntegrals
from .nlp import (ClampRows, NLPSizes, eval_points, n_parameters, rigid_natural_points,
                  special_points)
from .params import WeftParams, param_layout
from .parametrisation import Reduced
from .problem import WeftProblem
from .reduction import CourseMap, course_maps, n_reduced, with_clamped


class _NumericFunction(ca.Callback):
    """A CasADi Function whose outputs a Python callable computes from numpy inputs."""

    def __init__(self, name: str, fn: Callable, sp_in: list[ca.Sparsity],
                 sp_out: list[ca.Sparsity], names_in: list[str], names_out: list[str],
                 reverse: Callable[[], ca.Function] | None = None) -> None:
        ca.Callback.__init__(self)
        self.fn, self.sp_in, self.sp_out, self.reverse = fn, sp_in, sp_out, reverse
        self.names_in, self.names_out = names_in, names_out
        self.construct(name, {})

    def get_n_in(self) -> int:
        return len(self.sp_in)

    def get_n_out(self) -> int:
        return len(self.sp_out)

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return self.sp_in[i]

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return self.sp_out[i]

    def get_name_in(self, i: int) -> str:
        return self.names_in[i]

    def get_name_out(self, i: int) -> str:
        return self.names_out[i]

    def has_reverse(self, nadj: int) -> bool:
        return self.reverse is not None and nadj == 1

    def get_reverse(self, nadj: int, name: str, inames, onames, opts) -> ca.Function:
        self._reverse = self.reverse()                  # CasADi keeps no reference
        return self._reverse

    def eval(self, arg):
        outs = self.fn(*[np.asarray(a.full()).ravel() for a in arg])
        return [ca.DM(sp, np.asarray(o, dtype=float).ravel().tolist()) if not sp.is_dense()
                else ca.DM(np.asarray(o, dtype=float).reshape(sp.size1(), sp.size2(), order="F"))
                for sp, o in zip(self.sp_out, outs)]


@dataclass
class _Point:
    """A material point of the model: 0-based course i, wale j and its column in D."""

    i: int
    j: int
    col: int


RANK_TOL = 1e-8        # singular values below this fraction of the largest count as zero


class CondensedNLP(NLPSizes):
    """The condensed reduced NLP; exposes what ``WeftSolver``, ``solve`` and ``WeftResult`` use
    of ``WeftNLP`` (nlp, layouts x, p, g, x0, params, p0, specials, clamp/load/rigid points and
    rows, energy, coefficients, starts, lift, special_positions, n_parameters, model)."""

    model = "reduced"
    extended_from: Reduced | None = None   # the representatives asked for, if build_condensed
    #                                        added the clamped courses and wales

    def __init__(self, pr: WeftProblem, reduced: Reduced) -> None:
        self.problem = pr
        m, n, t = pr.courses, pr.wales, pr.t
        self.parametrisation = self.reduction = reduced.resolve(m, n)
        self.nc, self.nz = n_coeffs(t), n_reduced(self.reduction, t)
        self.maps: list[CourseMap] = course_maps(pr, self.reduction)
        # columns of w = (z, course starts) each course depends on
        self.cw = [np.concatenate([cm.cols, self.nz + 2 * i + np.arange(2)])
                   for i, cm in enumerate(self.maps)]
        self.specials, self.clamp_points, self.load_points, self.rigid_points = special_points(pr)
        evals = eval_points(pr, self.specials)
        self.P, col = len(evals), {s: q for q, s in enumerate(evals)}
        self.pL = col[pr.L]
        self.springs = pr.courses > 1 and pr.crossings is not None
        if self.springs:
            c = pr.crossings
            self.pB, self.pE, self.pR, self.pH = (col[c.s[k]] for k in ("B", "E", "R", "H"))
        self.sp_points = [_Point(*divmod(sp.k, n), col[sp.s]) for sp in self.specials]
        self.x = Layout()
        self.x.add("coeffs", self.nz, 1)
        self.x.add("course_starts", 2, m)
        self.p = param_layout(pr)
        self.params = WeftParams.of(pr)
        self.g, self.clamp_rows, self.rigid_rows = self._g_layout()
        self.n_parameters = n_parameters(pr, self.reduction)
        self._loop_functions()
        self._cache: dict[str, object] = {}
        self._sparsities()
        self.unit = self._units()
        self.nlp, self.nlpsol_options = self._oracles()
        self.x0 = self.lift(np.broadcast_to(pr.natural.coeffs, (m, n, self.nc)).copy(),
                            pr.natural_starts())

    # ----------------------------------------------------------------- set-up

    def _g_layout(self) -> tuple[Layout, list[ClampRows], list[slice]]:
        """Constraint rows: clamp positions and angles, then rigid-clamp points."""
        gl, clamp_rows, rigid_rows = Layout(), [], []
        for q, c in enumerate(self.problem.clamps):
            dims = tuple(d for d in range(2) if c.fix[d])
            pos = angle = None
            if dims:
                gl.add(f"clamp{q}_pos", len(dims), 1)
                pos = gl.slice(f"clamp{q}_pos")
            if c.angle is not None:
                gl.add(f"clamp{q}_angle", 1, 1)
                angle = gl.slice(f"clamp{q}_angle")
            clamp_rows.append(ClampRows(pos, dims, angle))
        for q, idx in enumerate(self.rigid_points):
            gl.add(f"rigid{q}", 2 * len(idx), 1)
            rigid_rows.append(gl.slice(f"rigid{q}"))
        return gl, clamp_rows, rigid_rows

    def _loop_functions(self) -> None:
        """Per-loop D, its Jacobian and Σ_p μ_p·∇²D_p in closed form (``LoopIntegrals``)."""
        pr = self.problem
        self.integrals = LoopIntegrals(pr.L, pr.t, np.array(eval_points(pr, self.specials)),
                                       pr.quadrature_nodes)
        self.bend_diag = bending_diagonal(pr.L, pr.t)

    def _row_columns(self) -> list[np.ndarray]:
        """Columns of w each constraint row depends on, in g order."""
        pr, rows = self.problem, []
        for q, (c, sp) in enumerate(zip(pr.clamps, self.clamp_points)):
            rows += [self.cw[self.sp_points[sp].i]] * sum(c.fix)
            if c.angle is not None:
                rows.append(self.maps[(c.loop[0] - 1)].cols)
        for idx in self.rigid_points:
            for sp in idx:
                rows += [self.cw[self.sp_points[sp].i]] * 2
        return rows

    def _sparsities(self) -> None:
        nw = self.x.size
        rows = self._row_columns()
        mask = np.zeros((len(rows), nw), dtype=bool)
        for r, cols in enumerate(rows):
            mask[r, cols] = True
        self.jac_sp = _sparsity(mask)
        self.jac_mask = mask
        h = np.zeros((nw, nw), dtype=bool)
        for i, cw in enumerate(self.cw):
            block = np.union1d(cw, self.cw[i - 1]) if i and self.springs else cw
            h[np.ix_(block, block)] = True
        self.hess_mask = np.triu(h)
        self.hess_sp = _sparsity(self.hess_mask)

    # ------------------------------------------------------------ evaluation
    def _coeffs(self, w: np.ndarray) -> np.ndarray:
        """Loop coefficients A (m, n, nc) = T·z."""
        z = w[:self.nz]
        return np.stack([np.einsum("jcl,l->jc", cm.T, z[cm.cols]) for cm in self.maps])

    def _state(self, w: np.ndarray, derivatives: bool = False) -> dict:
        """A, per-loop displacements Y (m, n, P, 2), positions, and J (m, n, P, 2, nc) on demand."""
        key = w.tobytes()
        st = self._cache.get("state")
        m, n = self.problem.courses, self.problem.wales
        if st is None or st["key"] != key:
            A = self._coeffs(w)
            theta, D = self.integrals.values(A.reshape(-1, self.nc))
            Y = D.reshape(m, n, self.P, 2)
            X0 = w[self.nz:].reshape(m, 2)
            offsets = np.cumsum(Y[:, :, self.pL], axis=1) - Y[:, :, self.pL]
            st = {"key": key, "A": A, "theta": theta, "Y": Y,
                  "pos": X0[:, None, None, :] + offsets[:, :, None, :] + Y}
            self._cache["state"] = st
        if derivatives and "J" not in st:
            st["J"] = self.integrals.jacobians(st["theta"]).reshape(m, n, self.P, 2, self.nc)
        return st

    def _spring_vectors(self, pos: np.ndarray) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """(vector − rest, frame, (upper col, lower col)) for the BE and RH springs."""
        if not self.springs:
            return []
        c = self.problem.crossings
        return [(pos[:-1, :, self.pE] - pos[1:, :, self.pB] - c.rest_left, c.frame_left,
                 (self.pB, self.pE)),
                (pos[:-1, :, self.pH] - pos[1:, :, self.pR] - c.rest_right, c.frame_right,
                 (self.pR, self.pH))]

    @staticmethod
    def _spring_matrix(frame: np.ndarray, par: dict) -> np.ndarray:
        """M = Fᵀ diag(k_a, k_b) F: U = ½ (v − r)ᵀ M (v − r) (eqs. 6-8)."""
        return frame.T @ np.diag([par["k_a"], par["k_b"]]) @ frame

    def _params(self, p: np.ndarray) -> dict:
        return {name: self.p.get(p, name) for name in self.p.blocks} | {
            k: float(self.p.get(p, k)[0, 0]) for k in ("k_a", "k_b", "R_f")}

    def energy(self, x: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
        """(U_spring, U_bend, W_loads) of a solver vector x (eqs. 6-12 and the loads' work)."""
        return self._energy(self.w(x), np.asarray(p, dtype=float).ravel())

    def _energy(self, w: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
        pr, par = self.problem, self._params(p)
        st = self._state(w)
        spring = sum(0.5 * np.einsum("ijd,de,ije->", v, self._spring_matrix(F, par), v)
                     for v, F, _ in self._spring_vectors(st["pos"]))
        dA = st["A"] - pr.natural.coeffs
        bend = 0.5 * par["R_f"] * float(np.einsum("ijc,c,ijc->", dA, self.bend_diag, dA))
        work = 0.0
        for q, (ld, sp) in enumerate(zip(pr.loads, self.load_points)):
            pt = self.sp_points[sp]
            work += par["forces"][:, q] @ (st["pos"][pt.i, pt.j, pt.col]
                                           - pr.natural_position(ld.loop, ld.s))
            work += par["moments"][q, 0] * float(phi(ld.s, pr.L, pr.t)[0]
                                                 @ dA[pt.i, pt.j])
        return float(spring), bend, float(work)

    def _f(self, w: np.ndarray, p: np.ndarray) -> float:
        spring, bend, work = self._energy(w, p)
        return spring + bend - work

    def _constraints(self, w: np.ndarray, p: np.ndarray) -> np.ndarray:
        """g in layout order: clamp positions and angles, rigid-clamp points."""
        pr, par = self.problem, self._params(p)
        st = self._state(w)
        out, n_angle = [], 0
        for q, (c, sp) in enumerate(zip(pr.clamps, self.clamp_points)):
            pt = self.sp_points[sp]
            dims = [d for d in range(2) if c.fix[d]]
            out.append(st["pos"][pt.i, pt.j, pt.col][dims] - par["targets"][dims, q])
            if c.angle is not None:
                out.append([phi(c.s, pr.L, pr.t)[0] @ st["A"][pt.i, pt.j]
                            - par["angles"][n_angle, 0]])
                n_angle += 1
        for q, (rc, idx, p0) in enumerate(zip(pr.rigid_clamps, self.rigid_points,
                                              rigid_natural_points(pr))):
            tx, ty, rot = par["rigid"][:, q]
            R = np.array([[np.cos(rot), -np.sin(rot)], [np.sin(rot), np.cos(rot)]])
            target = rc.centre[:, None] + R @ (p0 - rc.centre).T + np.array([[tx], [ty]])
            pts = np.array([st["pos"][self.sp_points[s].i, self.sp_points[s].j,
                                      self.sp_points[s].col] for s in idx]).T
            out.append((pts - target).ravel(order="F"))
        return np.concatenate([np.ravel(o) for o in out]) if out else np.zeros(0)

    def _adjoints(self, w: np.ndarray, p: np.ndarray, sigma: float, lam: np.ndarray,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Point adjoints ψ = ∂ℒ/∂(positions) (m, n, P, 2), ∂ℒ/∂A directly (angles, moments),
        and the spring matrices M."""
        pr, par = self.problem, self._params(p)
        st = self._state(w)
        psi = np.zeros_like(st["pos"])
        dA = np.zeros_like(st["A"])
        for v, F, (up, low) in self._spring_vectors(st["pos"]):
            gv = sigma * v @ self._spring_matrix(F, par)
            psi[:-1, :, low] += gv
            psi[1:, :, up] -= gv
        for q, (ld, sp) in enumerate(zip(pr.loads, self.load_points)):
            pt = self.sp_points[sp]
            psi[pt.i, pt.j, pt.col] -= sigma * par["forces"][:, q]
            dA[pt.i, pt.j] -= sigma * par["moments"][q, 0] * phi(ld.s, pr.L, pr.t)[0]
        r = 0
        for c, sp in zip(pr.clamps, self.clamp_points):
            pt = self.sp_points[sp]
            for d in [d for d in range(2) if c.fix[d]]:
                psi[pt.i, pt.j, pt.col, d] += lam[r]
                r += 1
            if c.angle is not None:
                dA[pt.i, pt.j] += lam[r] * phi(c.s, pr.L, pr.t)[0]
                r += 1
        for idx in self.rigid_points:
            for s in idx:
                pt = self.sp_points[s]
                psi[pt.i, pt.j, pt.col] += lam[r:r + 2]
                r += 2
        return psi, dA, par

    def _loop_adjoints(self, psi: np.ndarray) -> np.ndarray:
        """μ = ∂ℒ/∂D per loop: ψ plus, at s = L, the course's later loops' total (the transpose
        of the prefix sum that chains loop starts, eq. 1)."""
        tot = psi.sum(axis=2)
        suffix = np.cumsum(tot[:, ::-1], axis=1)[:, ::-1] - tot
        mu = psi.copy()
        mu[:, :, self.pL] += suffix
        return mu

    def gradient(self, w: np.ndarray, p: np.ndarray, sigma: float = 1.0,
                 lam: np.ndarray | None = None) -> np.ndarray:
        """∂ℒ/∂w for ℒ = σ f + λᵀg, by adjoints through the per-loop blocks."""
        lam = np.zeros(self.g.size) if lam is None else lam
        ga, gX0 = self.coefficient_gradient(w, p, sigma, lam)
        gz = np.zeros(self.nz)
        for i, cm in enumerate(self.maps):
            np.add.at(gz, cm.cols, np.einsum("jc,jcl->l", ga[i], cm.T))
        return np.concatenate([gz, gX0.ravel()])

    def coefficient_gradient(self, w: np.ndarray, p: np.ndarray, sigma: float,
                             lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """∂ℒ/∂a_k for every loop (m, n, nc) and ∂ℒ/∂(course starts) (m, 2), with the
        positions chained along courses (the full model's gradient with loop starts
        eliminated)."""
        st = self._state(w, derivatives=True)
        psi, dA, par = self._adjoints(w, p, sigma, lam)
        mu = self._loop_adjoints(psi)
        ga = (np.einsum("ijpd,ijpdc->ijc", mu, st["J"])
              + sigma * par["R_f"] * self.bend_diag * (st["A"] - self.problem.natural.coeffs) + dA)
        return ga, psi.sum(axis=(1, 2))

    def _dpos(self, i: int, J: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(∂D_(i,j),p/∂w_local (n, P, 2, |cw_i|) without the chain, chain prefix (n, 2, |cw_i|))
        for course i: positions' derivatives are own + prefix + e(course start)."""
        cm = self.maps[i]
        n, P = J.shape[1], J.shape[2]
        own = np.matmul(J[i].reshape(n, 2 * P, self.nc), cm.T).reshape(n, P, 2, -1)
        ends = own[:, self.pL]
        prefix = np.cumsum(ends, axis=0) - ends
        pad = np.zeros(own.shape[:-1] + (2,))
        own = np.concatenate([own, pad], axis=-1)
        prefix = np.concatenate([prefix, np.broadcast_to(np.eye(2), (prefix.shape[0], 2, 2))],
                                axis=-1)
        return own, prefix

    def jacobian(self, w: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Dense ∂g/∂w (rows × nw) from the per-loop Jacobians and the chain."""
        pr = self.problem
        st = self._state(w, derivatives=True)
        jac = np.zeros((self.g.size, self.x.size))
        cache: dict[int, tuple[np.ndarray, np.ndarray]] = {}

        def dpos(sp: int) -> tuple[np.ndarray, np.ndarray]:
            pt = self.sp_points[sp]
            if pt.i not in cache:
                cache[pt.i] = self._dpos(pt.i, st["J"])
            own, prefix = cache[pt.i]
            return own[pt.j, pt.col] + prefix[pt.j], self.cw[pt.i]

        r = 0
        for c, sp in zip(pr.clamps, self.clamp_points):
            d_, cols = dpos(sp)
            for d in [d for d in range(2) if c.fix[d]]:
                jac[r, cols] = d_[d]
                r += 1
            if c.angle is not None:
                pt, cm = self.sp_points[sp], self.maps[self.sp_points[sp].i]
                jac[r, cm.cols] = phi(c.s, pr.L, pr.t)[0] @ cm.T[pt.j]
                r += 1
        for idx in self.rigid_points:
            for s in idx:
                d_, cols = dpos(s)
                jac[r:r + 2, cols] = d_
                r += 2
        return jac

    def hessian(self, w: np.ndarray, p: np.ndarray, sigma: float, lam: np.ndarray) -> np.ndarray:
        """Dense ∇²_w ℒ: Σ_k T_kᵀ(μ_k·∇²D_k + σ R_f diag(D))T_k + σ Σ_springs QᵀMQ."""
        pr = self.problem
        m, n = pr.courses, pr.wales
        st = self._state(w, derivatives=True)
        psi, _, par = self._adjoints(w, p, sigma, lam)
        mu = self._loop_adjoints(psi)
        Hloop = (self.integrals.weighted_hessians(st["theta"], mu.reshape(m * n, self.P, 2))
                 .reshape(m, n, self.nc, self.nc) + sigma * par["R_f"] * np.diag(self.bend_diag))
        H = np.zeros((self.x.size, self.x.size))
        for i, cm in enumerate(self.maps):
            Ti = cm.T.reshape(n * self.nc, -1)
            HT = np.matmul(Hloop[i], cm.T).reshape(n * self.nc, -1)
            H[np.ix_(cm.cols, cm.cols)] += Ti.T @ HT
        if self.springs and sigma != 0.0:
            mats = [self._spring_matrix(F, par) for F in (pr.crossings.frame_left,
                                                           pr.crossings.frame_right)]
            below = self._dpos(0, st["J"])
            for i in range(1, m):
                above = self._dpos(i, st["J"])
                cols = np.union1d(self.cw[i - 1], self.cw[i])
                lo, up = np.searchsorted(cols, self.cw[i - 1]), np.searchsorted(cols, self.cw[i])
                for M, (pu, pl) in zip(mats, ((self.pB, self.pE), (self.pR, self.pH))):
                    Q = np.zeros((n, 2, cols.size))
                    Q[:, :, lo] += below[0][:, pl] + below[1]
                    Q[:, :, up] -= above[0][:, pu] + above[1]
                    MQ = np.matmul(M, Q).reshape(2 * n, -1)
                    H[np.ix_(cols, cols)] += sigma * (Q.reshape(2 * n, -1).T @ MQ)
                below = above
        return H

    # ------------------------------------------------------------- IPOPT glue
    def w(self, x: np.ndarray) -> np.ndarray:
        """Model variables w = (z, course starts) of a solver vector x: w = unit ⊙ x."""
        return self.unit * np.asarray(x, dtype=float).ravel()

    def _units(self) -> np.ndarray:
        """Solver units: z_r in units of 1/‖T e_r‖ (a unit step moves the loop coefficients by 1
        in RMS over the fabric), course starts in length units. Measured: without it the
        gradient in z, a sum over every loop a parameter moves, cannot get below IPOPT's
        tolerance on 50 × 50 (rounding), and more iterations are needed."""
        norms = np.zeros(self.nz)
        for cm in self.maps:
            np.add.at(norms, cm.cols, np.einsum("jcl,jcl->l", cm.T, cm.T))
        return np.concatenate([1.0 / np.sqrt(norms), np.ones(self.x.size - self.nz)])

    def _oracles(self) -> tuple[dict, dict]:
        nw, ng, npar = self.x.size, self.g.size, self.p.size
        dense = ca.Sparsity.dense
        u = self.unit
        uu = np.outer(u, u)
        # nlpsol builds the Lagrangian's gradient for its multiplier outputs from the reverse
        # derivative of (f, g); only its x part is provided (lam_p is not computed)
        adjoint = lambda: _NumericFunction(                                   # noqa: E731
            "condensed_fg_adj",
            lambda x, p, f, g, sf, lg: (u * self.gradient(u * x, p, float(sf[0]), lg),
                                        np.zeros(npar)),
            [dense(nw), dense(npar), dense(1), dense(ng), dense(1), dense(ng)],
            [dense(nw), dense(npar)], ["x", "p", "out_f", "out_g", "adj_f", "adj_g"],
            ["adj_x", "adj_p"])
        fg = _NumericFunction(
            "condensed_fg", lambda x, p: (self._f(u * x, p), self._constraints(u * x, p)),
            [dense(nw), dense(npar)], [dense(1), dense(ng)], ["x", "p"], ["f", "g"], adjoint)
        grad = _NumericFunction(
            "condensed_grad_f", lambda x, p: (self._f(u * x, p), u * self.gradient(u * x, p)),
            [dense(nw), dense(npar)], [dense(1), dense(nw)], ["x", "p"], ["f", "grad_f_x"])
        jac = _NumericFunction(
            "condensed_jac_g", lambda x, p: (self._constraints(u * x, p),
                                             _nonzeros(self.jacobian(u * x, p) * u, self.jac_sp)),
            [dense(nw), dense(npar)], [dense(ng), self.jac_sp], ["x", "p"], ["g", "jac_g_x"])
        hess = _NumericFunction(
            "condensed_hess_lag",
            lambda x, p, sf, lg: (_nonzeros(self.hessian(u * x, p, float(sf[0]), lg) * uu,
                                            self.hess_sp),),
            [dense(nw), dense(npar), dense(1), dense(ng)], [self.hess_sp],
            ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
        self._callbacks = (fg, grad, jac, hess)             # CasADi keeps no reference
        x, p = ca.MX.sym("x", nw), ca.MX.sym("p", npar)
        f, g = fg(x, p)
        return ({"x": x, "p": p, "f": f, "g": g},
                {"grad_f": grad, "jac_g": jac, "hess_lag": hess, "calc_lam_p": False,
                 "calc_lam_x": False})

    def clamp_rank(self) -> tuple[int, int]:
        """(rank, rows) of the constraint Jacobian at the natural start: rank < rows means the
        clamps are not independent in this reduced space (no LICQ; see ``with_clamped``)."""
        jac = self.jacobian(self.w(self.x0), self.p0)
        if jac.size == 0:
            return 0, jac.shape[0]
        sv = np.linalg.svd(jac, compute_uv=False)
        return int(np.sum(sv > RANK_TOL * sv[0])), jac.shape[0]

    # --------------------------------------------------------------- reading
    def coefficients(self, x: np.ndarray) -> np.ndarray:
        """Loop coefficients (m, n, 2t+2) of a solver vector."""
        return self._coeffs(self.w(x))

    def starts(self, x: np.ndarray) -> np.ndarray:
        """Loop start points (m, n, 2): course starts plus the chained end displacements."""
        st = self._state(self.w(x))
        return st["pos"][:, :, self.pL] - st["Y"][:, :, self.pL]

    def special_positions(self, x: np.ndarray) -> np.ndarray:
        """Positions (2 × specials) of the clamped and loaded material points."""
        st = self._state(self.w(x))
        return np.array([st["pos"][q.i, q.j, q.col] for q in self.sp_points]).T.reshape(2, -1)

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """The solver vector whose loops are closest (least squares in the coefficients) to
        ``coeffs`` (m, n, 2t+2), with the course starts of ``starts`` (m, n, 2)."""
        normal = np.zeros((self.nz, self.nz))
        rhs = np.zeros(self.nz)
        for i, cm in enumerate(self.maps):
            Ti = cm.T.reshape(-1, cm.cols.size)
            normal[np.ix_(cm.cols, cm.cols)] += Ti.T @ Ti
            rhs[cm.cols] += Ti.T @ coeffs[i].ravel()
        z = np.linalg.lstsq(normal, rhs, rcond=None)[0]
        return np.concatenate([z, starts[:, 0, :].ravel()]) / self.unit


def _sparsity(mask: np.ndarray) -> ca.Sparsity:
    """CasADi sparsity of a boolean mask."""
    cols, rows = np.nonzero(mask.T)
    return ca.Sparsity.triplet(mask.shape[0], mask.shape[1], rows.tolist(), cols.tolist())


def _nonzeros(dense: np.ndarray, sp: ca.Sparsity) -> np.ndarray:
    """The entries of ``dense`` at the nonzeros of ``sp``, in CasADi's (column-major) order."""
    rows, cols = sp.get_triplet()
    return dense[np.asarray(rows, dtype=int), np.asarray(cols, dtype=int)]


def build_condensed(pr: WeftProblem, reduced: Reduced = Reduced()) -> CondensedNLP:
    """The condensed reduced model of a problem over ``reduced`` (default: the corner form).

    Where the clamps' constraints are dependent at the natural start (``clamp_rank``), the
    courses and wales of the clamped loops are made representative (``reduction.with_clamped``)
    and ``extended_from`` records the representatives asked for. Measured: the 20 × 20 course
    pull over an even 6 × 6 grid took 8 905 iterations to a "solved to acceptable level" and the
    corner form on 30 × 30 converged to a state with every course alike; extended, 19 and 6
    iterations, 0.06 and 0.11 RMS from the full model (README, "Large fabrics")."""
    cnlp = CondensedNLP(pr, reduced)
    rank, rows = cnlp.clamp_rank()
    if rank < rows:
        wider = with_clamped(cnlp.reduction, pr)
        if wider != cnlp.reduction:
            asked = cnlp.reduction
            cnlp = CondensedNLP(pr, wider)
            cnlp.extended_from = asked
    return cnlp
