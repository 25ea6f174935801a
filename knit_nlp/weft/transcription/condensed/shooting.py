"""The condensed model's variables and state: the multiple-shooting space over the reduced map.

Variables w = (z, segment starts): the reduced parameters z of eqs. 22-27 (``reduction``) and
the start of every shooting segment of ``segment`` loops along each course. ``Shooting`` sets
up the space (course maps, segments, material points, the layouts of w and g, solver units)
and evaluates the state at w: the loop coefficients A = T·z, every loop's integrals D_k(a_k)
(eq. 1, ``kinematics.LoopIntegrals``) and the positions chained along each segment, with their
derivatives with respect to z on demand.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....layout import Layout
from ...model.basis import bending_diagonal, n_coeffs
from ...model.kinematics import LoopIntegrals
from ...model.params import WeftParams, param_layout
from ...model.parametrisation import Reduced
from ...model.problem import WeftProblem
from ..reduction import CourseMap, course_maps, n_reduced
from ..rows import (ClampTable, add_clamp_rows, eval_points, has_springs, n_parameters,
                    special_points)

SEGMENT = 12           # loops per shooting segment along a course (docs/measurements.md)


@dataclass
class _Point:
    """A material point of the model: 0-based course i, wale j and its column in D."""

    i: int
    j: int
    col: int


class Shooting:
    """The condensed model's space and its state at a point w (module docstring)."""

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
        specials, *indices = special_points(pr)
        evals = eval_points(pr, specials)
        self.P, col = len(evals), {s: q for q, s in enumerate(evals)}
        self.pL = col[pr.L]
        self.springs = has_springs(pr)
        self.spring_z = self._spring_columns() if self.springs else []
        if self.springs:
            c = pr.crossings
            self.pB, self.pE, self.pR, self.pH = (col[c.s[k]] for k in ("B", "E", "R", "H"))
        self.sp_points = [_Point(*divmod(sp.k, n), col[sp.s]) for sp in specials]
        self.x = Layout()
        self.x.add("coeffs", self.nz, 1)
        self.x.add("segment_starts", 2, m * self.n_seg)
        self.p = param_layout(pr)
        self.params = WeftParams.of(pr)
        self.g = Layout()
        self.clamp_table = ClampTable(specials, *indices, *add_clamp_rows(self.g, pr))
        if self.n_seg > 1:               # each segment starts where the last one ends (eq. 1)
            self.g.add("chain", 2 * (self.n_seg - 1), m)
        self.lbg = self.ubg = np.zeros(self.g.size)
        self.n_parameters = n_parameters(pr, self.reduction)
        self.integrals = LoopIntegrals(pr.L, pr.t, np.array(evals), pr.quadrature_nodes)
        self.bend_diag = bending_diagonal(pr.L, pr.t)
        self._cache: dict[str, object] = {}
        self.unit = self._units()

    def _spring_columns(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per pair of neighbouring courses (i−1, i): the union of their z columns and where
        each course's columns sit in it (set-up, used by every Hessian evaluation)."""
        out = []
        for below, above in zip(self.maps[:-1], self.maps[1:]):
            zcols = np.union1d(below.cols, above.cols)
            out.append((zcols, np.searchsorted(zcols, below.cols),
                        np.searchsorted(zcols, above.cols)))
        return out

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
