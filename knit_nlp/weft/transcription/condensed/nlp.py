"""The reduced model condensed to the paper's variables, with derivatives assembled by hand.

Variables: the reduced parameters z (eqs. 22-27, ``reduction.course_map``) and the start of
every shooting segment of ``segment`` loops along each course (the first is the course start
(x_i^0, y_i^0)); with one segment per course this is the paper's count p·q·2t + 2p + 2m. Inside
a segment loop starts are not variables: the start of loop (i, j) is its segment's start plus
the end displacements of the segment's earlier loops (eq. 1); between segments the chaining
of eq. (1) is a constraint ("chain" rows: the next segment starts where this one ends).
Multiple shooting, because single shooting along whole courses made IPOPT take 42-89
iterations on diagonal pulls (the chained positions are far more nonlinear in z than each
segment's), against 8-12 in segments of 12 loops, to the same minimum (README, "Large
fabrics").

Every nonlinear term is one loop's integral D_k(a_k) (2 × P displacements at the material points
the model needs) with a_k = T_k·z. The derivatives are assembled from per-loop blocks, never by
differentiating through the map:

- gradient: point adjoints ψ (spring forces, loads, multipliers) → μ_k = ψ_k plus, at s = L, the
  sum of the later adjoints in the segment (the transpose of the prefix sum) → ∂/∂a_k =
  J_kᵀμ_k + bending → ∂/∂z = Σ_k T_kᵀ ∂/∂a_k;
- Jacobian rows of clamps and chains: ∂P/∂w = e(segment start) + Σ_{earlier j' in the segment}
  J_{(i,j'),L}T_{(i,j')} + J_{k,p}T_k;
- Hessian of the Lagrangian: Σ_k T_kᵀ(Σ_p μ_kp·∇²D_kp + σ R_f diag(D))T_k + σ Σ_springs QᵀMQ with
  Q = ∂(spring vector)/∂w and M = Fᵀdiag(k_a, k_b)F (eqs. 6-10: the springs are quadratic in
  the positions, so this is exact, not Gauss-Newton).

D_k, J_k and Σ_p μ_kp∇²D_kp are closed forms over all loops at once (``kinematics.LoopIntegrals``,
the full model's quadrature; measured faster than mapped CasADi Functions); the rest is numpy over
course blocks, so set-up and each evaluation are linear in the loops. Jacobian and Hessian are
assembled as nonzeros of a structural block pattern (never as dense matrices) and handed to
IPOPT through ``casadi.Callback`` objects (``grad_f``, ``jac_g``, ``hess_lag``) that write into
CasADi's buffers.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import casadi as ca
import numpy as np

from ....layout import Layout
from ...model.basis import bending_diagonal, n_coeffs, phi
from ...model.kinematics import LoopIntegrals
from ..full import (ClampRows, NLPSizes, eval_points, n_parameters, rigid_natural_points,
                  special_points)
from ...model.params import WeftParams, param_layout
from ...model.parametrisation import Reduced
from ...model.problem import WeftProblem
from ..reduction import CourseMap, course_maps, n_reduced, with_clamped


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

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg, res) -> int:
        """Read the inputs' and write the outputs' nonzeros in place (measured: converting a
        million Hessian nonzeros to a DM through a list cost about 0.1 s per evaluation)."""
        outs = self.fn(*[np.frombuffer(a, dtype=np.float64) for a in arg])
        for r, o in zip(res, outs):
            if r is not None and len(r):
                np.frombuffer(r, dtype=np.float64)[:] = np.ravel(o)
        return 0


@dataclass
class _Point:
    """A material point of the model: 0-based course i, wale j and its column in D."""

    i: int
    j: int
    col: int


RANK_TOL = 1e-8        # singular values below this fraction of the largest count as zero
SEGMENT = 12           # loops per shooting segment along a course (README, "Large fabrics")


class CondensedNLP(NLPSizes):
    """The condensed reduced NLP; exposes what ``WeftSolver``, ``solve`` and ``WeftResult`` use
    of ``WeftNLP`` (nlp, layouts x, p, g, x0, params, p0, specials, clamp/load/rigid points and
    rows, energy, coefficients, starts, lift, special_positions, n_parameters, model)."""

    model = "reduced"
    extended_from: Reduced | None = None   # the representatives asked for, if build_condensed
    #                                        added the clamped courses and wales

    def __init__(self, pr: WeftProblem, reduced: Reduced, segment: int | None = None) -> None:
        self.problem = pr
        m, n, t = pr.courses, pr.wales, pr.t
        self.parametrisation = self.reduction = reduced.resolve(m, n)
        # shooting segments along every course: loop j (0-based) is in segment j // segment
        self.segment = max(1, min(int(segment or SEGMENT), n))
        self.n_seg = -(-n // self.segment)
        self.seg_of = np.arange(n) // self.segment
        self.seg_first = np.arange(self.n_seg) * self.segment
        self.seg_last = np.minimum(self.seg_first + self.segment, n) - 1
        self.nc, self.nz = n_coeffs(t), n_reduced(self.reduction, t)
        self.maps: list[CourseMap] = course_maps(pr, self.reduction)
        # columns of w = (z, segment starts) each course depends on
        S = self.n_seg
        self.cw = [np.concatenate([cm.cols, self.nz + 2 * S * i + np.arange(2 * S)])
                   for i, cm in enumerate(self.maps)]
        self.specials, self.clamp_points, self.load_points, self.rigid_points = special_points(pr)
        evals = eval_points(pr, self.specials)
        self.P, col = len(evals), {s: q for q, s in enumerate(evals)}
        self.pL = col[pr.L]
        self.springs = pr.courses > 1 and pr.crossings is not None
        self.spring_z = self._spring_columns() if self.springs else []
        if self.springs:
            c = pr.crossings
            self.pB, self.pE, self.pR, self.pH = (col[c.s[k]] for k in ("B", "E", "R", "H"))
        self.sp_points = [_Point(*divmod(sp.k, n), col[sp.s]) for sp in self.specials]
        self.x = Layout()
        self.x.add("coeffs", self.nz, 1)
        self.x.add("segment_starts", 2, m * self.n_seg)
        self.p = param_layout(pr)
        self.params = WeftParams.of(pr)
        self.g, self.clamp_rows, self.rigid_rows = self._g_layout()
        self.n_parameters = n_parameters(pr, self.reduction)
        self._loop_functions()
        self._cache: dict[str, object] = {}
        self.unit = self._units()
        self._sparsities()
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
        if self.n_seg > 1:
            gl.add("chain", 2 * (self.n_seg - 1), self.problem.courses)
        return gl, clamp_rows, rigid_rows

    def _loop_functions(self) -> None:
        """Per-loop D, its Jacobian and Σ_p μ_p·∇²D_p in closed form (``LoopIntegrals``)."""
        pr = self.problem
        self.integrals = LoopIntegrals(pr.L, pr.t, np.array(eval_points(pr, self.specials)),
                                       pr.quadrature_nodes)
        self.bend_diag = bending_diagonal(pr.L, pr.t)

    def _jacobian_blocks(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(rows, columns of w) of every dense block of ∂g/∂w, in the order ``_jacobian_values``
        fills them: a clamp's held coordinates (columns of its course), its angle (the course's
        z only), each rigid-clamp point, and per course its chaining rows."""
        pr, blocks, r = self.problem, [], 0
        for c, sp in zip(pr.clamps, self.clamp_points):
            i = self.sp_points[sp].i
            if sum(c.fix):
                blocks.append((r + np.arange(sum(c.fix)), self.cw[i]))
                r += sum(c.fix)
            if c.angle is not None:
                blocks.append((np.array([r]), self.maps[i].cols))
                r += 1
        for idx in self.rigid_points:
            for sp in idx:
                blocks.append((r + np.arange(2), self.cw[self.sp_points[sp].i]))
                r += 2
        k = 2 * (self.n_seg - 1)
        for i in range(pr.courses if k else 0):
            blocks.append((r + k * i + np.arange(k), self.cw[i]))
        return blocks

    def _hessian_blocks(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Dense blocks of ∇²ℒ: per course its loops' (z of the course), then per pair of
        neighbouring courses their springs' (both courses' columns)."""
        blocks = [(cm.cols, cm.cols) for cm in self.maps]
        if self.springs:
            S2 = 2 * self.n_seg
            for i, (zcols, _, _) in enumerate(self.spring_z, start=1):
                # = union(cw[i−1], cw[i]): z columns, then course i−1's and i's segment starts
                cols = np.concatenate([zcols, self.cw[i - 1][-S2:], self.cw[i][-S2:]])
                blocks.append((cols, cols))
        return blocks

    def _spring_columns(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per pair of neighbouring courses (i−1, i): the union of their z columns and where
        each course's columns sit in it (set-up, used by every Hessian evaluation)."""
        out = []
        for below, above in zip(self.maps[:-1], self.maps[1:]):
            zcols = np.union1d(below.cols, above.cols)
            out.append((zcols, np.searchsorted(zcols, below.cols),
                        np.searchsorted(zcols, above.cols)))
        return out

    def _sparsities(self) -> None:
        nw = self.x.size
        self.jac_sp, self.jac_idx = _block_pattern((self.g.size, nw), self._jacobian_blocks())
        self.hess_sp, self.hess_idx = _block_pattern((nw, nw), self._hessian_blocks(), upper=True)
        u = self.unit
        rows, cols = (np.asarray(v, dtype=int) for v in self.jac_sp.get_triplet())
        self.jac_scale = u[cols]
        rows, cols = (np.asarray(v, dtype=int) for v in self.hess_sp.get_triplet())
        self.hess_scale = u[rows] * u[cols]

    @property
    def jac_mask(self) -> np.ndarray:
        """The Jacobian's structural pattern as a dense boolean array (for checks)."""
        return _dense(self.jac_sp, np.ones(self.jac_sp.nnz(), dtype=bool))

    @property
    def hess_mask(self) -> np.ndarray:
        """The Hessian's structural upper triangle as a dense boolean array (for checks)."""
        return _dense(self.hess_sp, np.ones(self.hess_sp.nnz(), dtype=bool))

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
            X0 = w[self.nz:].reshape(m, self.n_seg, 2)
            offsets = self._within_segment(np.cumsum(Y[:, :, self.pL], axis=1)
                                           - Y[:, :, self.pL])
            st = {"key": key, "A": A, "theta": theta, "Y": Y, "X0": X0,
                  "pos": X0[:, self.seg_of, None, :] + offsets[:, :, None, :] + Y}
            self._cache["state"] = st
        if derivatives and "J" not in st:
            st["J"] = self.integrals.jacobians(st["theta"]).reshape(m, n, self.P, 2, self.nc)
        return st

    def _within_segment(self, exclusive: np.ndarray) -> np.ndarray:
        """Exclusive prefix sums along courses (axis 1) restarted at every segment's first
        loop: each loop's offset from its segment's start."""
        return exclusive - exclusive[:, self.seg_first][:, self.seg_of]

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
        if self.n_seg > 1:               # each segment starts where the last one ends (eq. 1)
            ends = st["pos"][:, self.seg_last[:-1], self.pL]            # (m, S−1, 2)
            out.append(np.ravel(st["X0"][:, 1:] - ends))
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
        if self.n_seg > 1:
            psi[:, self.seg_last[:-1], self.pL] -= self._chain_multipliers(lam)
        return psi, dA, par

    def _chain_multipliers(self, lam: np.ndarray) -> np.ndarray:
        """The multipliers of the segment chaining rows, (m, S−1, 2)."""
        return lam[self.g.slice("chain")].reshape(self.problem.courses, self.n_seg - 1, 2)

    def _loop_adjoints(self, psi: np.ndarray) -> np.ndarray:
        """μ = ∂ℒ/∂D per loop: ψ plus, at s = L, the total of the later loops of its segment
        (the transpose of the prefix sum that chains loop starts, eq. 1)."""
        tot = psi.sum(axis=2)
        suffix = np.cumsum(tot[:, ::-1], axis=1)[:, ::-1] - tot        # loops after j
        mu = psi.copy()
        mu[:, :, self.pL] += suffix - suffix[:, self.seg_last][:, self.seg_of]
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
        """∂ℒ/∂a_k for every loop (m, n, nc) and ∂ℒ/∂(segment starts) (m, S, 2), with the
        positions chained along each segment (the full model's gradient with the loop starts
        inside segments eliminated; the chaining rows' multipliers included)."""
        st = self._state(w, derivatives=True)
        psi, dA, par = self._adjoints(w, p, sigma, lam)
        mu = self._loop_adjoints(psi)
        ga = (np.einsum("ijpd,ijpdc->ijc", mu, st["J"])
              + sigma * par["R_f"] * self.bend_diag * (st["A"] - self.problem.natural.coeffs) + dA)
        gX0 = np.add.reduceat(psi.sum(axis=2), self.seg_first, axis=1)      # (m, S, 2)
        if self.n_seg > 1:
            gX0[:, 1:] += self._chain_multipliers(lam)
        return ga, gX0

    def _dpos(self, st: dict, i: int) -> tuple[np.ndarray, np.ndarray]:
        """For course i, with respect to its z columns (``maps[i].cols``): every point's own
        ∂D (n, P, 2, |cols_i|) and the within-segment prefix of the earlier loops' ends
        (n, 2, |cols_i|); a position's derivative is own + prefix + e(its segment's start).
        Kept with the state: the Jacobian and the Hessian at one point share it."""
        cache = st.setdefault("dpos", {})
        if i not in cache:
            J, cm, n = st["J"], self.maps[i], self.problem.wales
            own = np.matmul(J[i].reshape(n, -1, self.nc), cm.T).reshape(n, self.P, 2, -1)
            ends = own[:, self.pL]
            cache[i] = own, self._within_segment((np.cumsum(ends, axis=0) - ends)[None])[0]
        return cache[i]

    def _with_start(self, i: int, dz: np.ndarray, seg: np.ndarray) -> np.ndarray:
        """Rows (k, 2, |cols_i|) of ∂(position)/∂z of course i's points in segments ``seg``
        extended to all of ``cw[i]`` with e(the segment's start) (k, 2, |cw_i|)."""
        S, k = self.n_seg, dz.shape[0]
        start = np.zeros((k, 2, 2 * S))
        start[np.arange(k), 0, 2 * seg] = 1.0
        start[np.arange(k), 1, 2 * seg + 1] = 1.0
        return np.concatenate([dz, start], axis=-1)

    def _jacobian_values(self, w: np.ndarray, p: np.ndarray,
                         whole_courses: bool = False) -> list[np.ndarray]:
        """The dense blocks of ∂g/∂w (``_jacobian_blocks``) from the per-loop Jacobians and
        the chain: ∂(position) = own + prefix within the segment + e(segment start). With
        ``whole_courses`` the clamp rows only, as single shooting has them: the prefix over all
        of the course's earlier loops and e(the course start), the chaining rows eliminated."""
        pr = self.problem
        st = self._state(w, derivatives=True)

        def dpos(sp: int) -> np.ndarray:
            pt = self.sp_points[sp]
            own, prefix = self._dpos(st, pt.i)
            if whole_courses:
                before = own[:pt.j, self.pL].sum(axis=0)
                return self._with_start(pt.i, (own[pt.j, pt.col] + before)[None],
                                        np.zeros(1, int))[0]
            return self._with_start(pt.i, (own[pt.j, pt.col] + prefix[pt.j])[None],
                                    self.seg_of[[pt.j]])[0]

        vals = []
        for c, sp in zip(pr.clamps, self.clamp_points):
            if sum(c.fix):
                vals.append(dpos(sp)[[d for d in range(2) if c.fix[d]]])
            if c.angle is not None:
                pt, cm = self.sp_points[sp], self.maps[self.sp_points[sp].i]
                vals.append((phi(c.s, pr.L, pr.t)[0] @ cm.T[pt.j])[None])
        for idx in self.rigid_points:
            vals += [dpos(sp) for sp in idx]
        S = self.n_seg
        for i in range(pr.courses if S > 1 and not whole_courses else 0):
            own, prefix = self._dpos(st, i)
            last = self.seg_last[:-1]
            # X0[s+1] − end of segment s
            block = -self._with_start(i, own[last, self.pL] + prefix[last], np.arange(S - 1))
            off = self.maps[i].cols.size
            for s in range(S - 1):
                block[s, :, off + 2 * (s + 1):off + 2 * (s + 2)] += np.eye(2)
            vals.append(block.reshape(2 * (S - 1), -1))
        return vals

    def jacobian_nonzeros(self, w: np.ndarray, p: np.ndarray) -> np.ndarray:
        """∂g/∂w at the nonzeros of ``jac_sp`` (CasADi's order)."""
        return _scatter(self.jac_sp.nnz(), self.jac_idx, self._jacobian_values(w, p))

    def jacobian(self, w: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Dense ∂g/∂w (rows × nw), for checks and the rank test."""
        return _dense(self.jac_sp, self.jacobian_nonzeros(w, p))

    def hessian_nonzeros(self, w: np.ndarray, p: np.ndarray, sigma: float,
                         lam: np.ndarray) -> np.ndarray:
        """The upper triangle of ∇²_w ℒ at the nonzeros of ``hess_sp``:
        Σ_k T_kᵀ(μ_k·∇²D_k + σ R_f diag(D))T_k + σ Σ_springs QᵀMQ, block by block."""
        pr = self.problem
        m, n = pr.courses, pr.wales
        st = self._state(w, derivatives=True)
        psi, _, par = self._adjoints(w, p, sigma, lam)
        mu = self._loop_adjoints(psi)
        Hloop = (self.integrals.weighted_hessians(st["theta"], mu.reshape(m * n, self.P, 2))
                 .reshape(m, n, self.nc, self.nc) + sigma * par["R_f"] * np.diag(self.bend_diag))
        out = np.zeros(self.hess_sp.nnz() + 1)          # the last slot takes the lower triangle
        for i, cm in enumerate(self.maps):
            Ti = cm.T.reshape(n * self.nc, -1)
            HT = np.matmul(Hloop[i], cm.T).reshape(n * self.nc, -1)
            out[self.hess_idx[i]] += Ti.T @ HT
        if self.springs and sigma != 0.0:
            mats = [self._spring_matrix(F, par) for F in (pr.crossings.frame_left,
                                                           pr.crossings.frame_right)]
            MM = self._start_blocks(mats)
            for i in range(1, m):
                out[self.hess_idx[m + i - 1]] += sigma * self._spring_block(st, i, mats, MM)
        return out[:-1]

    def _spring_block(self, st: dict, i: int, mats: list[np.ndarray],
                      MM: np.ndarray) -> np.ndarray:
        """Σ QᵀMQ over the springs between courses i−1 and i, on union(cw[i−1], cw[i]) =
        (z columns of both, segment starts of course i−1, of course i). The spring vector is
        v_j = Qz_j·z + X_(i−1,s(j)) − X_(i,s(j)) + const, so only the z part needs a product:
        zz = Σ Qz_jᵀMQz_j, z–start = ±Σ_(j∈s) (MQz_j)ᵀ, start–start = ±MM (``_start_blocks``)."""
        n, S = self.problem.wales, self.n_seg
        zcols, lo, up = self.spring_z[i - 1]
        cz = zcols.size
        (own_lo, pre_lo), (own_up, pre_up) = self._dpos(st, i - 1), self._dpos(st, i)
        Qz = np.zeros((2, n, 2, cz))                     # per spring family
        MQ = np.empty_like(Qz)
        for f, (M, (pu, pl)) in enumerate(zip(mats, ((self.pB, self.pE), (self.pR, self.pH)))):
            Qz[f][:, :, lo] += own_lo[:, pl] + pre_lo
            Qz[f][:, :, up] -= own_up[:, pu] + pre_up
            MQ[f] = np.matmul(M, Qz[f])
        H = np.zeros((cz + 4 * S, cz + 4 * S))
        H[:cz, :cz] = Qz.reshape(4 * n, cz).T @ MQ.reshape(4 * n, cz)
        R = np.add.reduceat(MQ.sum(axis=0), self.seg_first, axis=0).reshape(2 * S, cz).T
        H[:cz, cz:cz + 2 * S] = R
        H[:cz, cz + 2 * S:] = -R
        H[cz:cz + 2 * S, cz:cz + 2 * S] = MM
        H[cz + 2 * S:, cz + 2 * S:] = MM
        H[cz:cz + 2 * S, cz + 2 * S:] = -MM
        return H                     # its upper triangle is read (hess_idx)

    def _start_blocks(self, mats: list[np.ndarray]) -> np.ndarray:
        """blockdiag((loops in segment s)·(M_left + M_right)) over the segments (2S × 2S)."""
        count = np.diff(np.r_[self.seg_first, self.problem.wales])
        return np.kron(np.diag(count), mats[0] + mats[1])

    def hessian(self, w: np.ndarray, p: np.ndarray, sigma: float, lam: np.ndarray) -> np.ndarray:
        """Dense symmetric ∇²_w ℒ, for checks."""
        upper = _dense(self.hess_sp, self.hessian_nonzeros(w, p, sigma, lam))
        return upper + np.triu(upper, 1).T

    # ------------------------------------------------------------- IPOPT glue
    def w(self, x: np.ndarray) -> np.ndarray:
        """Model variables w = (z, segment starts) of a solver vector x: w = unit ⊙ x."""
        return self.unit * np.asarray(x, dtype=float).ravel()

    def _units(self) -> np.ndarray:
        """Solver units: z_r in units of 1/‖T e_r‖ (a unit step moves the loop coefficients by 1
        in RMS over the fabric), segment starts in length units. Measured: without it the
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
                                             self.jacobian_nonzeros(u * x, p) * self.jac_scale),
            [dense(nw), dense(npar)], [dense(ng), self.jac_sp], ["x", "p"], ["g", "jac_g_x"])
        hess = _NumericFunction(
            "condensed_hess_lag",
            lambda x, p, sf, lg: (self.hessian_nonzeros(u * x, p, float(sf[0]), lg)
                                  * self.hess_scale,),
            [dense(nw), dense(npar), dense(1), dense(ng)], [self.hess_sp],
            ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
        self._callbacks = (fg, grad, jac, hess)             # CasADi keeps no reference
        x, p = ca.MX.sym("x", nw), ca.MX.sym("p", npar)
        f, g = fg(x, p)
        return ({"x": x, "p": p, "f": f, "g": g},
                {"grad_f": grad, "jac_g": jac, "hess_lag": hess, "calc_lam_p": False,
                 "calc_lam_x": False})

    def clamp_rank(self) -> tuple[int, int]:
        """(rank, rows) of the clamps' rows of the single-shooting Jacobian at the natural
        start (the chaining rows eliminated, so it does not depend on the segments): rank <
        rows means the clamps are not independent in this reduced space (no LICQ; see
        ``with_clamped``)."""
        jac = self.clamp_jacobian(self.w(self.x0), self.p0)
        if jac.size == 0:
            return 0, jac.shape[0]
        sv = np.linalg.svd(jac, compute_uv=False)
        return int(np.sum(sv > RANK_TOL * sv[0])), jac.shape[0]

    def clamp_jacobian(self, w: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Dense ∂(clamp rows)/∂w of single shooting (rows × nw): every clamped point chained
        from its course start (the first segment's start column), as with one segment."""
        vals = self._jacobian_values(w, p, whole_courses=True)
        rows = self.g.slice("chain").start if "chain" in self.g.blocks else self.g.size
        return _dense(self.jac_sp, _scatter(self.jac_sp.nnz(), self.jac_idx[:len(vals)],
                                            vals))[:rows]

    # --------------------------------------------------------------- reading
    def coefficients(self, x: np.ndarray) -> np.ndarray:
        """Loop coefficients (m, n, 2t+2) of a solver vector."""
        return self._coeffs(self.w(x))

    def starts(self, x: np.ndarray) -> np.ndarray:
        """Loop start points (m, n, 2): segment starts plus the chained end displacements."""
        st = self._state(self.w(x))
        return st["pos"][:, :, self.pL] - st["Y"][:, :, self.pL]

    def special_positions(self, x: np.ndarray) -> np.ndarray:
        """Positions (2 × specials) of the clamped and loaded material points."""
        st = self._state(self.w(x))
        return np.array([st["pos"][q.i, q.j, q.col] for q in self.sp_points]).T.reshape(2, -1)

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """The solver vector whose loops are closest (least squares in the coefficients) to
        ``coeffs`` (m, n, 2t+2), with the segment starts of ``starts`` (m, n, 2). The normal
        matrix Σ T_iᵀT_i couples only representative courses that share a course, so it is
        solved sparse (CasADi's csparse; measured: a dense least-squares solve took 28 s for
        the 5 000 parameters of the 100 × 100 course pull)."""
        sp, idx = self._normal_pattern()
        values, rhs = np.zeros(sp.nnz() + 1), np.zeros(self.nz)
        for i, (cm, ix) in enumerate(zip(self.maps, idx)):
            Ti = cm.T.reshape(-1, cm.cols.size)
            values[ix] += Ti.T @ Ti
            rhs[cm.cols] += Ti.T @ coeffs[i].ravel()
        z = np.asarray(ca.solve(ca.DM(sp, values[:-1]), ca.DM(rhs), "csparse")).ravel()
        return np.concatenate([z, starts[:, self.seg_first, :].ravel()]) / self.unit

    def _normal_pattern(self) -> tuple[ca.Sparsity, list[np.ndarray]]:
        if "normal" not in self._cache:
            self._cache["normal"] = _block_pattern((self.nz, self.nz),
                                                   [(cm.cols, cm.cols) for cm in self.maps])
        return self._cache["normal"]


def _block_pattern(shape: tuple[int, int], blocks: list[tuple[np.ndarray, np.ndarray]],
                   upper: bool = False) -> tuple[ca.Sparsity, list[np.ndarray]]:
    """The sparsity covering dense blocks (rows, cols) of a matrix (their upper triangle only
    if ``upper``), and per block the index of each entry among the nonzeros in CasADi's
    column-major order (entries left out: index nnz, a slot to drop)."""
    keys = []
    for rows, cols in blocks:
        R, C = np.meshgrid(rows, cols, indexing="ij")
        k = C.astype(np.int64) * shape[0] + R
        keys.append(np.where(R <= C, k, -1) if upper else k)
    mark = np.zeros(shape[0] * shape[1] + 1, dtype=bool)   # the last entry takes the −1s
    for k in keys:
        mark[k] = True
    uniq = np.flatnonzero(mark[:-1])
    sp = ca.Sparsity.triplet(shape[0], shape[1], (uniq % shape[0]).tolist(),
                             (uniq // shape[0]).tolist())
    return sp, [np.where(k >= 0, np.searchsorted(uniq, k), uniq.size) for k in keys]


def _scatter(nnz: int, idx: list[np.ndarray], values: list[np.ndarray]) -> np.ndarray:
    """Nonzeros from non-overlapping dense blocks (``_block_pattern`` indices)."""
    out = np.zeros(nnz + 1)
    for i, v in zip(idx, values):
        out[i] = v
    return out[:-1]


def _dense(sp: ca.Sparsity, nonzeros: np.ndarray) -> np.ndarray:
    """The dense matrix of a sparsity's nonzeros."""
    rows, cols = sp.get_triplet()
    out = np.zeros((sp.size1(), sp.size2()), dtype=nonzeros.dtype)
    out[np.asarray(rows, dtype=int), np.asarray(cols, dtype=int)] = nonzeros
    return out


def build_condensed(pr: WeftProblem, reduced: Reduced = Reduced(),
                    segment: int | None = None) -> CondensedNLP:
    """The condensed reduced model of a problem over ``reduced`` (default: the corner form),
    with shooting segments of ``segment`` loops (default ``SEGMENT``).

    Where the clamps' constraints are dependent at the natural start (``clamp_rank``: the
    clamp rows of single shooting), the courses and wales of the
    clamped loops are made representative (``reduction.with_clamped``) and ``extended_from``
    records the representatives asked for. Measured: the 20 × 20 course pull over an even
    6 × 6 grid took 8 905 iterations to a "solved to acceptable level" and the corner form on
    30 × 30 converged to a state with every course alike; extended, 19 and 6 iterations, 0.06
    and 0.11 RMS from the full model (README, "Large fabrics")."""
    cnlp = CondensedNLP(pr, reduced, segment=segment)
    rank, rows = cnlp.clamp_rank()
    wider = with_clamped(cnlp.reduction, pr) if rank < rows else cnlp.reduction
    if wider != cnlp.reduction:
        asked = cnlp.reduction
        cnlp = CondensedNLP(pr, wider, segment=segment)
        cnlp.extended_from = asked
    return cnlp
