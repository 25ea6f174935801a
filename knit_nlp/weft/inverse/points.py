"""Material points of a weft solution as a CasADi Function of the decision vector (eq. 1).

A point (loop k, s) sits at the loop's start plus ∫₀ˢ(cos θ, sin θ) of that loop; with loop
starts and coefficients both decision variables this is a per-loop Function, so goals, openings
and observations need no extra lifted variables in the forward NLP.
"""
from __future__ import annotations

from typing import Sequence

import casadi as ca
import numpy as np

from ..model.basis import n_coeffs
from ..model.kinematics import loop_displacements
from ..transcription.full import FullNLP


def point_function(wnlp: FullNLP, points: Sequence[tuple[tuple[int, int], float]]) -> ca.Function:
    """Function x -> positions (2 × P) of material points ((course, wale), s) of the full
    model (the inverse problems' forward model)."""
    pr = wnlp.problem
    x = ca.MX.sym("x", wnlp.n_variables)
    A = ca.reshape(x[wnlp.x.slice("coeffs")], n_coeffs(pr.t), pr.n_loops)
    X = ca.reshape(x[wnlp.x.slice("starts")], 2, pr.n_loops)
    cols = []
    for s in sorted({s for _, s in points}):
        disp = loop_displacements(pr.L, pr.t, np.array([s]), pr.quadrature_nodes)
        for q, ((i, j), sq) in enumerate(points):
            if sq == s:
                k = (i - 1) * pr.wales + (j - 1)
                cols.append((q, X[:, k] + disp(A[:, k])))
    cols.sort(key=lambda c: c[0])
    out = ca.horzcat(*[c for _, c in cols]) if cols else ca.MX(2, 0)
    return ca.Function("points", [x], [out], ["x"], ["P"])


def point_jacobian(fn: ca.Function) -> ca.Function:
    """Function x -> (positions 2 × P, Jacobian of vec(positions) wrt x)."""
    x = ca.MX.sym("x", fn.size1_in(0))
    P = fn(x)
    return ca.Function("points_jac", [x], [P, ca.jacobian(ca.vec(P), x)])
