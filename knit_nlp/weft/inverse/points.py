"""Material points of a weft solution as a CasADi Function of the decision vector (eq. 1).

A point (loop k, s) sits at the loop's start plus ∫₀ˢ(cos θ, sin θ) of that loop; with loop
starts and coefficients both decision variables this is a per-loop Function, so goals, openings
and observations need no extra lifted variables in the forward NLP. In the 3-D model
(``transcription.spatial``) a point is the start plus ∫₀ˢ T(θ, φ) ds (docs/weft3d.md, S2) and
goals, openings and observations are of its plan position (x, y): what a photograph from above
sees and where a gripper moves.
"""
from __future__ import annotations

from typing import Callable, Sequence

import casadi as ca
import numpy as np

from ..model.basis import n_coeffs
from ..model.kinematics import loop_displacements
from ..model.spatial.curve3d import loop_displacements3d
from ..transcription.full import FullNLP


def point_function(wnlp: FullNLP, points: Sequence[tuple[tuple[int, int], float]]) -> ca.Function:
    """Function x -> positions (2 × P) of material points ((course, wale), s) of the full
    model (the inverse problems' forward model)."""
    pr = wnlp.problem
    x = ca.MX.sym("x", wnlp.n_variables)
    A = ca.reshape(x[wnlp.x.slice("coeffs")], n_coeffs(pr.t), pr.n_loops)
    dims = wnlp.x.blocks["starts"][2][0]                     # 2, or 3 in the 3-D model
    X = ca.reshape(x[wnlp.x.slice("starts")], dims, pr.n_loops)[:2, :]
    cols = []
    for s in sorted({s for _, s in points}):
        disp = _displacement(wnlp, x, s)
        for q, ((i, j), sq) in enumerate(points):
            if sq == s:
                k = (i - 1) * pr.wales + (j - 1)
                cols.append((q, X[:, k] + disp(A[:, k], k)))
    cols.sort(key=lambda c: c[0])
    out = ca.horzcat(*[c for _, c in cols]) if cols else ca.MX(2, 0)
    return ca.Function("points", [x], [out], ["x"], ["P"])


def _displacement(wnlp: FullNLP, x: ca.MX, s: float) -> Callable[[ca.MX, int], ca.MX]:
    """(a, k) -> the plan displacement (2) from loop k's start to its material point s: eq. (1)
    with the loop's coefficients a, or in the 3-D model (S2) with its elevation φ too."""
    pr = wnlp.problem
    if "elev" not in wnlp.x.blocks:
        disp = loop_displacements(pr.L, pr.t, np.array([s]), pr.quadrature_nodes)
        if wnlp.x.blocks["starts"][2][0] == 2:
            return lambda a, k: disp(a)
        return lambda a, k: disp(a)[:2]            # the 3-D model with φ frozen at 0
    q = wnlp.shape.modes
    B = ca.reshape(x[wnlp.x.slice("elev")], n_coeffs(q), pr.n_loops)
    disp3 = loop_displacements3d(pr.L, pr.t, q, np.array([s]), pr.quadrature_nodes)
    return lambda a, k: disp3(a, B[:, k])[:2, :]


def point_jacobian(fn: ca.Function) -> ca.Function:
    """Function x -> (positions 2 × P, Jacobian of vec(positions) wrt x)."""
    x = ca.MX.sym("x", fn.size1_in(0))
    P = fn(x)
    return ca.Function("points_jac", [x], [P, ca.jacobian(ca.vec(P), x)])
