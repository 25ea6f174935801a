"""The condensed model's Jacobian and Lagrangian Hessian, assembled block by block.

- Jacobian rows of clamps and chains: ∂P/∂w = e(segment start) + Σ_{earlier j' in the segment}
  J_{(i,j'),L}T_{(i,j')} + J_{k,p}T_k;
- Hessian of the Lagrangian: Σ_k T_kᵀ(Σ_p μ_kp·∇²D_kp + σ R_f diag(D))T_k + σ Σ_springs QᵀMQ with
  Q = ∂(spring vector)/∂w and M = Fᵀdiag(k_a, k_b)F (eqs. 6-10: the springs are quadratic in
  the positions, so this is exact, not Gauss-Newton).

Both are assembled as nonzeros of a structural block pattern (never as dense matrices): per
course numpy over its loops, so set-up and each evaluation are linear in the loops.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ...model.basis import phi
from ..rows import held_dims
from .lagrangian import Lagrangian


def block_pattern(shape: tuple[int, int], blocks: list[tuple[np.ndarray, np.ndarray]],
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

def scatter(nnz: int, idx: list[np.ndarray], values: list[np.ndarray]) -> np.ndarray:
    """Nonzeros from non-overlapping dense blocks (``block_pattern`` indices)."""
    out = np.zeros(nnz + 1)
    for i, v in zip(idx, values):
        out[i] = v
    return out[:-1]

def dense_matrix(sp: ca.Sparsity, nonzeros: np.ndarray) -> np.ndarray:
    """The dense matrix of a sparsity's nonzeros."""
    rows, cols = sp.get_triplet()
    out = np.zeros((sp.size1(), sp.size2()), dtype=nonzeros.dtype)
    out[np.asarray(rows, dtype=int), np.asarray(cols, dtype=int)] = nonzeros
    return out


class Assembly(Lagrangian):
    """The sparsity patterns and nonzeros of ∂g/∂w and ∇²_w ℒ (module docstring)."""

    def _jacobian_blocks(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """(rows, columns of w) of every dense block of ∂g/∂w, in the order ``_jacobian_values``
        fills them: a clamp's held coordinates (columns of its course), its angle (the course's
        z only), each rigid-clamp point, and per course its chaining rows."""
        pr, blocks, r = self.problem, [], 0
        for c, sp in zip(pr.clamps, self.clamp_table.clamp_points):
            i = self.sp_points[sp].i
            if sum(c.fix):
                blocks.append((r + np.arange(sum(c.fix)), self.cw[i]))
                r += sum(c.fix)
            if c.angle is not None:
                blocks.append((np.array([r]), self.maps[i].cols))
                r += 1
        for idx in self.clamp_table.rigid_points:
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

    def _sparsities(self) -> None:
        nw = self.x.size
        self.jac_sp, self.jac_idx = block_pattern((self.g.size, nw), self._jacobian_blocks())
        self.hess_sp, self.hess_idx = block_pattern((nw, nw), self._hessian_blocks(), upper=True)
        u = self.unit
        rows, cols = (np.asarray(v, dtype=int) for v in self.jac_sp.get_triplet())
        self.jac_scale = u[cols]
        rows, cols = (np.asarray(v, dtype=int) for v in self.hess_sp.get_triplet())
        self.hess_scale = u[rows] * u[cols]

    @property
    def jac_mask(self) -> np.ndarray:
        """The Jacobian's structural pattern as a dense boolean array (for checks)."""
        return dense_matrix(self.jac_sp, np.ones(self.jac_sp.nnz(), dtype=bool))

    @property
    def hess_mask(self) -> np.ndarray:
        """The Hessian's structural upper triangle as a dense boolean array (for checks)."""
        return dense_matrix(self.hess_sp, np.ones(self.hess_sp.nnz(), dtype=bool))

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
        for c, sp in zip(pr.clamps, self.clamp_table.clamp_points):
            if sum(c.fix):
                vals.append(dpos(sp)[list(held_dims(c.fix))])
            if c.angle is not None:
                pt, cm = self.sp_points[sp], self.maps[self.sp_points[sp].i]
                vals.append((phi(c.s, pr.L, pr.t)[0] @ cm.T[pt.j])[None])
        for idx in self.clamp_table.rigid_points:
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
        return scatter(self.jac_sp.nnz(), self.jac_idx, self._jacobian_values(w, p))

    def jacobian(self, w: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Dense ∂g/∂w (rows × nw), for checks and the rank test."""
        return dense_matrix(self.jac_sp, self.jacobian_nonzeros(w, p))

    def clamp_jacobian(self, w: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Dense ∂(clamp rows)/∂w of single shooting (rows × nw): every clamped point chained
        from its course start (the first segment's start column), as with one segment."""
        vals = self._jacobian_values(w, p, whole_courses=True)
        rows = self.g.slice("chain").start if "chain" in self.g.blocks else self.g.size
        return dense_matrix(self.jac_sp, scatter(self.jac_sp.nnz(), self.jac_idx[:len(vals)],
                                            vals))[:rows]

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
        upper = dense_matrix(self.hess_sp, self.hessian_nonzeros(w, p, sigma, lam))
        return upper + np.triu(upper, 1).T
