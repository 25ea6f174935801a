"""Lifting loops into the condensed model: the solver vector whose loops are closest to given ones.

The loops' coefficients are A = T·z; the closest z in the least-squares sense solves the normal
equations (Σ_i T_iᵀT_i) z = Σ_i T_iᵀ a_i. The normal matrix couples only representative courses
that share a course, so it is solved sparse (CasADi's csparse; measured: a dense
least-squares solve took 28 s for the 5 000 parameters of the 100 × 100 course pull).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from .assembly import block_pattern
from .shooting import Shooting


Pattern = tuple[ca.Sparsity, list[np.ndarray]]


def normal_pattern(model: Shooting) -> Pattern:
    """The sparsity of the normal matrix Σ_i T_iᵀT_i (course i's block on its z columns) and
    per course the index of each block entry among its nonzeros (``block_pattern``): set-up,
    kept by the NLP (``CondensedNLP.normal_pattern``) for every lift."""
    return block_pattern((model.nz, model.nz), [(cm.cols, cm.cols) for cm in model.maps])


def lift(model: Shooting, pattern: Pattern, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """The solver vector of ``model`` whose loops are closest to ``coeffs`` (m, n, 2t+2), with
    the segment starts of ``starts`` (m, n, 2); ``pattern``: ``normal_pattern(model)``."""
    sp, idx = pattern
    values, rhs = np.zeros(sp.nnz() + 1), np.zeros(model.nz)
    for i, (cm, ix) in enumerate(zip(model.maps, idx)):
        Ti = cm.T.reshape(-1, cm.cols.size)
        values[ix] += Ti.T @ Ti
        rhs[cm.cols] += Ti.T @ coeffs[i].ravel()
    z = np.asarray(ca.solve(ca.DM(sp, values[:-1]), ca.DM(rhs), "csparse")).ravel()
    return np.concatenate([z, starts[:, model.seg_first, :].ravel()]) / model.unit
