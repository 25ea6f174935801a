"""The condensed model's values: energy, constraints and the gradient of the Lagrangian.

Every nonlinear term is one loop's integral D_k(a_k) with a_k = T_k·z, so the gradient is
assembled from per-loop blocks, never by differentiating through the map: point adjoints ψ
(spring forces, loads, multipliers) → μ_k = ψ_k plus, at s = L, the sum of the later adjoints in
the segment (the transpose of the prefix sum) → ∂/∂a_k = J_kᵀμ_k + bending → ∂/∂z = Σ_k T_kᵀ
∂/∂a_k.
"""
from __future__ import annotations

import numpy as np

from ...model.basis import phi
from ..rows import held_dims, rigid_natural_points, rigid_targets
from .shooting import Shooting


class Lagrangian(Shooting):
    """f, g and ∂ℒ/∂w of the condensed model (module docstring)."""

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
        for q, (ld, sp) in enumerate(zip(pr.loads, self.clamp_table.load_points)):
            pt = self.sp_points[sp]
            work += par["forces"][:, q] @ (st["pos"][pt.i, pt.j, pt.col]
                                           - pr.natural_position(ld.loop, ld.s))
            work += par["moments"][q, 0] * float(phi(ld.s, pr.L, pr.t)[0]
                                                 @ dA[pt.i, pt.j])
        return float(spring), bend, float(work)

    def objective(self, w: np.ndarray, p: np.ndarray) -> float:
        spring, bend, work = self._energy(w, p)
        return spring + bend - work

    def constraints(self, w: np.ndarray, p: np.ndarray) -> np.ndarray:
        """g in layout order: the clamp rows (``rows.add_clamp_rows``), then the chaining of
        the segments."""
        pr, par = self.problem, self._params(p)
        st = self._state(w)
        out, n_angle = [], 0
        for q, (c, sp) in enumerate(zip(pr.clamps, self.clamp_table.clamp_points)):
            pt = self.sp_points[sp]
            dims = list(held_dims(c.fix))
            out.append(st["pos"][pt.i, pt.j, pt.col][dims] - par["targets"][dims, q])
            if c.angle is not None:
                out.append([phi(c.s, pr.L, pr.t)[0] @ st["A"][pt.i, pt.j]
                            - par["angles"][n_angle, 0]])
                n_angle += 1
        for q, (rc, idx, p0) in enumerate(zip(pr.rigid_clamps, self.clamp_table.rigid_points,
                                              rigid_natural_points(pr))):
            target = np.asarray(rigid_targets(rc, p0, *par["rigid"][:, q]))
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
        for q, (ld, sp) in enumerate(zip(pr.loads, self.clamp_table.load_points)):
            pt = self.sp_points[sp]
            psi[pt.i, pt.j, pt.col] -= sigma * par["forces"][:, q]
            dA[pt.i, pt.j] -= sigma * par["moments"][q, 0] * phi(ld.s, pr.L, pr.t)[0]
        r = 0
        for c, sp in zip(pr.clamps, self.clamp_table.clamp_points):
            pt = self.sp_points[sp]
            for d in held_dims(c.fix):
                psi[pt.i, pt.j, pt.col, d] += lam[r]
                r += 1
            if c.angle is not None:
                dA[pt.i, pt.j] += lam[r] * phi(c.s, pr.L, pr.t)[0]
                r += 1
        for idx in self.clamp_table.rigid_points:
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
