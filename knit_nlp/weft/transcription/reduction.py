"""The interpolation reduction of eqs. (22)-(27) as a linear map from reduced to full parameters,
held course by course (``course_maps``: the condensed model never forms it densely).

Representative courses i_1 = 1 < … < i_p = m and wales j_1 = 1 < … < j_q = n (the paper's corner
form is p = q = 2). Reduced parameters z, in this order: the sub-loop parameters â (2t each) of
every representative loop, course-major; then (a^{2t+1}, a^{2t+2}) of the representative loops in
wale 1. Then
- â_ij is piecewise bilinear over the representative grid (eq. 22; the paper's λ_i, μ_j of eq. 24
  on each cell);
- the last two coefficients of a_i1 are piecewise linear over the representative courses (eq. 23);
- the last two coefficients of every other loop follow from the continuity recursion (20)-(21)
  (eqs. 25-27 are this recursion with eq. 22 substituted), so continuity holds by construction.
Count: p·q·2t + 2p representative parameters (+ 2m course starts, which stay free).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..model.parametrisation import Reduced
from ..model.problem import WeftProblem


def hat_weights(index: int, reps: tuple[int, ...]) -> np.ndarray:
    """Piecewise-linear interpolation weights of 1-based ``index`` over representatives ``reps``."""
    if len(reps) == 1:
        return np.ones(1)
    eye = np.eye(len(reps))
    return np.array([np.interp(index, reps, eye[r]) for r in range(len(reps))])


@dataclass(frozen=True)
class CourseMap:
    """One course's share of the map: a_ij = T[j − 1] · z[cols] for every loop j of course i.

    ``cols`` are the reduced parameters the course can depend on (those of the representative
    courses whose hat weight at i is nonzero), so the blocks hold N·(2t+2)·|cols| numbers in all
    and the map is never formed densely.
    """

    cols: np.ndarray
    T: np.ndarray                                   # (n, 2t+2, len(cols))


def n_reduced(red: Reduced, t: int) -> int:
    """Number of reduced parameters z: p·q·2t + 2p."""
    return len(red.courses) * len(red.wales) * 2 * t + 2 * len(red.courses)


def course_map(i: int, red: Reduced, n: int, t: int, L: float,
               V: np.ndarray | None = None) -> CourseMap:
    """The rows of T for the loops of 1-based course ``i`` (eqs. 20-23; see the module docstring)."""
    p, q, h = len(red.courses), len(red.wales), 2 * t
    wi = hat_weights(i, red.courses)
    rs = np.flatnonzero(wi)
    hat_cols = np.arange(p * q * h).reshape(p, q, h)
    lin_cols = p * q * h + np.arange(2 * p).reshape(p, 2)
    cols = np.concatenate([hat_cols[rs].ravel(), lin_cols[rs].ravel()])
    nh = rs.size * q * h
    V = wale_weights(red, n) if V is None else V                                 # n × q
    T = np.zeros((n, h + 2, cols.size))
    T[:, :h, :nh] = np.einsum("r,jc,kl->jkrcl", wi[rs], V, np.eye(h)).reshape(n, h, nh)
    T[0, h, nh + 2 * np.arange(rs.size)] = wi[rs]                               # eq. (23)
    T[0, h + 1, nh + 2 * np.arange(rs.size) + 1] = wi[rs]
    kdiff = np.concatenate([2 * np.pi * np.arange(1, t + 1) / L, np.zeros(t)])
    cos_sum = np.concatenate([np.zeros(t), np.ones(t)])
    for j in range(1, n):
        dhat = T[j - 1, :h] - T[j, :h]                                  # â_i,j−1 − â_ij
        T[j, h] = kdiff @ dhat + T[j - 1, h]                            # eq. (21)
        T[j, h + 1] = cos_sum @ dhat + T[j - 1, h] * L + T[j - 1, h + 1]  # eq. (20)
    return CourseMap(cols, T)


def wale_weights(red: Reduced, n: int) -> np.ndarray:
    """Hat weights (n × q) of every wale over the representative wales (eq. 22's μ_j)."""
    return np.array([hat_weights(j, red.wales) for j in range(1, n + 1)])


def course_maps(pr: WeftProblem, reduced: Reduced) -> list[CourseMap]:
    """Every course's block of the map, course 1 first."""
    red = reduced.resolve(pr.courses, pr.wales)
    V = wale_weights(red, pr.wales)
    return [course_map(i, red, pr.wales, pr.t, pr.L, V) for i in range(1, pr.courses + 1)]


def clamped_loops(pr: WeftProblem) -> list[tuple[int, int]]:
    """The 1-based (course, wale) of every clamped loop: point clamps and rigid-clamp points."""
    return [c.loop for c in pr.clamps] + [loop for rc in pr.rigid_clamps
                                          for loop, _, _ in rc.points]


def with_clamped(red: Reduced, pr: WeftProblem) -> Reduced:
    """``red`` (resolved) with the course and the wale of every clamped loop made representative.

    Why: a clamp on an interpolated course (wale) constrains a shape the representatives fix.
    Where several do (the course pull holds both ends of every course), their constraint rows
    are linear combinations of each other at the natural state (every loop alike; measured on
    the 20 × 20 course pull with an even 6 × 6 grid: rank 27 of 41) and IPOPT, without LICQ,
    wanders for thousands of iterations (``condensed.nlp.build_condensed`` checks the rank)."""
    loops = clamped_loops(pr)
    return replace(red, courses=tuple(sorted(set(red.courses) | {i for i, _ in loops})),
                   wales=tuple(sorted(set(red.wales) | {j for _, j in loops})))
