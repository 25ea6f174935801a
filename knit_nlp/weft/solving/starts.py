"""Starting points for the full weft NLP.

The natural configuration violates a moved clamp by the whole pull (182 units on the 100 × 100
diagonal pull) and IPOPT's filter line search then takes 1/128 of its first steps.
``rigid_start`` removes the rigid part of that violation: it turns and moves the natural fabric
by the rigid motion that best fits the clamp targets (2-D Kabsch over the fully clamped
points). Every loop's angle gains the turn (θ → θ + φ, the constant basis coefficient of
eq. 15), loop starts are turned and moved with it, and the lifted spring vectors and points are
recomputed from those (``WeftNLP.lift``), so chaining (eq. 1), continuity (18)-(19) and all
lifted constraints hold exactly; only the clamps (and angle clamps) keep a residual.
"""
from __future__ import annotations

import numpy as np

from dataclasses import replace

from ..model.basis import n_coeffs
from ..transcription.full import WeftNLP, build_nlp, rigid_natural_points
from ..model.params import WeftParams
from ..model.quadrature import positions
from ..model.problem import Clamp, RigidClamp, WeftProblem, canonical_point

STARTS = ("multilevel", "rigid", "natural")
COARSEST = 12          # the multilevel start solves cold once a side is at most this many loops
# a cold solve of the coarsest fabric in at most this many iterations marks a pull the natural
# start handles well (measured: course pulls take 5 iterations at every size from 8 x 8 to
# 100 x 100, where the coarse solves cost more than they save; diagonal pulls 9 on 8 x 8 and
# 13-39 on larger fabrics)
EASY_ITERATIONS = 6


def clamp_pairs(wnlp: WeftNLP, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Natural positions (k × 2) and targets (k × 2) of every point held in both coordinates at
    parameters p: point clamps fixing x and y, and every point of every rigid clamp."""
    pr = wnlp.problem
    params = WeftParams.from_vector(pr, p)
    nat, tgt = [], []
    for c, target in zip(pr.clamps, params.targets):
        if all(c.fix):
            nat.append(pr.natural_position(c.loop, c.s))
            tgt.append(target)
    for rc, P0, (tx, ty, rot) in zip(pr.rigid_clamps, rigid_natural_points(pr), params.rigid):
        R = _rotation(rot)
        for X in P0:
            nat.append(X)
            tgt.append(rc.centre + R @ (X - rc.centre) + np.array([tx, ty]))
    return np.reshape(nat, (-1, 2)), np.reshape(tgt, (-1, 2))


def best_rigid_motion(nat: np.ndarray, tgt: np.ndarray) -> tuple[float, np.ndarray]:
    """Angle φ and translation b minimising Σ|R(φ)X + b − x|² (2-D Kabsch); φ = 0 for fewer
    than two points, b = 0 for none."""
    if len(nat) == 0:
        return 0.0, np.zeros(2)
    cn, ct = nat.mean(axis=0), tgt.mean(axis=0)
    u, v = nat - cn, tgt - ct
    phi = float(np.arctan2(np.sum(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]), np.sum(u * v))) \
        if len(nat) > 1 else 0.0
    return phi, ct - _rotation(phi) @ cn


def rigid_start(wnlp: WeftNLP, p: np.ndarray) -> np.ndarray:
    """The natural fabric turned by φ and moved by b, the best rigid fit to the clamp targets."""
    pr = wnlp.problem
    phi, b = best_rigid_motion(*clamp_pairs(wnlp, p))
    coeffs = np.broadcast_to(pr.natural.coeffs, (pr.courses, pr.wales, n_coeffs(pr.t))).copy()
    coeffs[..., -1] += phi
    return wnlp.lift(coeffs, pr.natural_starts() @ _rotation(phi).T + b)


def start_point(wnlp: WeftNLP, p: np.ndarray, start: str,
                log: list[str] | None = None) -> np.ndarray:
    """The decision vector a solve starts from: ``natural``, ``rigid`` (full model only) or
    ``multilevel``: coarser fabrics first for the full model (:func:`multilevel_start`), the
    corner form first for a finer reduced grid (:func:`corner_start`)."""
    if start not in STARTS:
        raise ValueError(f"unknown start {start!r}; use one of {', '.join(STARTS)}")
    if start == "natural" or (wnlp.model != "full" and start == "rigid"):
        return wnlp.x0
    if start == "rigid":
        return rigid_start(wnlp, p)
    x = multilevel_start(wnlp, p, log) if wnlp.model == "full" else corner_start(wnlp, p, log)
    return wnlp.x0 if x is None else x


def corner_start(cnlp, p: np.ndarray, log: list[str] | None = None) -> np.ndarray | None:
    """For the condensed reduced model over a grid finer than the corners: solve the corner form
    (``build_condensed(problem, Reduced())``, the coarsest grid, contained in every grid) at
    the same parameters from its natural state and lift its loops into this grid. None for the
    corner form itself, the lifted reduced model, or a failed corner solve. Measured
    (diagonal pulls, corner then grid against the grid from its natural state): 16 × 16 over
    8 × 8, 9 + 13 against 45 iterations; 30 × 30 over 15 × 15, 8 + 15 against 103, where the
    natural start ends in another minimum (energy 114.47 against 55.29); 24 × 24 over 12 × 12,
    87.98 against 36.33; 100 × 100 over 6 × 6, 11 + 6 against 11, the same minimum."""
    from ..transcription.condensed.nlp import CondensedNLP, build_condensed
    from ..model.parametrisation import Reduced
    from .solve import WeftSolver, solve
    if not isinstance(cnlp, CondensedNLP):
        return None
    pr = cnlp.problem
    corner = build_condensed(pr, Reduced())
    if corner.reduction == cnlp.reduction:
        return None
    rep = solve(corner, WeftSolver(corner), params=WeftParams.from_vector(pr, p),
                start="natural")
    if log is not None:
        log.append(f"corner start: {rep.status} ({rep.iterations} it, {rep.solve_s:.2f} s)")
    if not rep.success:
        return None
    return cnlp.lift(corner.coefficients(rep.x), corner.starts(rep.x))


def coarse_size(m: int) -> int:
    """Loops along one side on the next coarser level (halved, rounded up; at least 2)."""
    return m if m <= COARSEST else max(2, (m + 1) // 2)


def coarse_problem(pr: WeftProblem, params: WeftParams, m_c: int, n_c: int) -> WeftProblem | None:
    """The same pull on an m_c × n_c fabric: every clamped material point moves to the loop at
    the same fraction of the courses and wales, and its displacement from the natural position
    scales with the fabric, r = ((n_c−1)/(n−1), (m_c−1)/(m−1)). Points that meet are merged
    (targets averaged, fixed coordinates united). None where this is not defined (loads, or a
    point and a rigid clamp meeting)."""
    m, n = pr.courses, pr.wales
    if pr.loads:
        return None
    r = np.array([(n_c - 1) / (n - 1) if n > 1 else 1.0, (m_c - 1) / (m - 1) if m > 1 else 1.0])

    def coarse_loop(loop: tuple[int, int]) -> tuple[int, int]:
        return (1 + round((loop[0] - 1) * r[1]), 1 + round((loop[1] - 1) * r[0]))

    merged: dict[tuple, list[Clamp]] = {}
    for c, target in zip(pr.clamps, params.targets):
        loop = coarse_loop(c.loop)
        key = canonical_point(loop, c.s, pr.L, n_c)
        moved = replace(c, loop=loop, target=None)
        d = np.asarray(target) - pr.natural_position(c.loop, c.s)
        merged.setdefault(key, []).append((moved, d))
    clamps, held = [], set()
    for key, group in merged.items():
        c0 = group[0][0]
        fix = tuple(any(c.fix[k] for c, _ in group) for k in range(2))
        d = np.mean([d for _, d in group], axis=0)
        angle = next((c.angle for c, _ in group if c.angle is not None), None)
        clamps.append(replace(c0, fix=fix, angle=angle, target=None))
        clamps[-1] = replace(clamps[-1], target=_natural(pr, m_c, n_c, c0.loop, c0.s) + r * d)
        held.add(key)
    rigid = []
    for rc, (tx, ty, rot) in zip(pr.rigid_clamps, params.rigid):
        pts, seen = [], set()
        for loop, label, s in rc.points:
            lc = coarse_loop(loop)
            key = canonical_point(lc, s, pr.L, n_c)
            if key in held:
                return None
            if key not in seen:
                seen.add(key)
                pts.append((lc, label, s))
        held |= seen
        rigid.append(RigidClamp(tuple(pts), r * np.array([tx, ty]), float(rot), r * rc.centre))
    return replace(pr, name=f"{pr.name} (coarse {m_c}x{n_c})", courses=m_c, wales=n_c,
                   clamps=tuple(clamps), rigid_clamps=tuple(rigid), reduction=None)


def _natural(pr: WeftProblem, m: int, n: int, loop: tuple[int, int], s: float) -> np.ndarray:
    return replace(pr, courses=m, wales=n).natural_position(loop, s)


def prolong(coarse: WeftNLP, xc: np.ndarray, fine: WeftNLP) -> np.ndarray:
    """A fine decision vector from a coarse solution: loop coefficients interpolated bilinearly
    at the same fractions of the courses and wales, course-start displacements interpolated and
    scaled by 1/r, every other loop chained from its course start (eq. 1) and the lifted
    points recomputed, so only continuity and the clamps keep (small) residuals."""
    pc, pf = coarse.problem, fine.problem
    a_c = coarse.coefficients(xc)
    u_c = coarse.starts(xc)[:, 0] - pc.natural_starts()[:, 0]
    xi = _fractions(pf.courses, pc.courses)
    eta = _fractions(pf.wales, pc.wales)
    a = _interp(_interp(a_c, xi, axis=0), eta, axis=1)
    r = np.array([(pc.wales - 1) / (pf.wales - 1) if pf.wales > 1 else 1.0,
                  (pc.courses - 1) / (pf.courses - 1) if pf.courses > 1 else 1.0])
    course_starts = pf.natural_starts()[:, 0] + _interp(u_c, xi, axis=0) / r
    ends = positions(a.reshape(-1, n_coeffs(pf.t)), [pf.L], pf.L, pf.t).reshape(
        pf.courses, pf.wales, 2)
    starts = np.concatenate([course_starts[:, None], ends[:, :-1]], axis=1).cumsum(axis=1)
    return fine.lift(a, starts)


def _fractions(fine: int, coarse: int) -> np.ndarray:
    """Fractional coarse indices (0-based) of the fine indices at the same fraction of the side."""
    return np.arange(fine) * ((coarse - 1) / (fine - 1) if fine > 1 else 0.0)


def _interp(arr: np.ndarray, at: np.ndarray, axis: int) -> np.ndarray:
    """Linear interpolation of ``arr`` along ``axis`` at fractional indices ``at``."""
    lo = np.clip(np.floor(at).astype(int), 0, arr.shape[axis] - 1)
    hi = np.minimum(lo + 1, arr.shape[axis] - 1)
    w = (at - lo).reshape([-1 if k == axis else 1 for k in range(arr.ndim)])
    return np.take(arr, lo, axis=axis) * (1 - w) + np.take(arr, hi, axis=axis) * w


def coarse_chain(pr: WeftProblem, params: WeftParams) -> list[WeftProblem]:
    """The same pull on ever coarser fabrics (halved until a side has at most COARSEST loops),
    finest first; empty where the problem is small or no coarser problem is defined."""
    chain: list[WeftProblem] = []
    while True:
        m_c, n_c = coarse_size(pr.courses), coarse_size(pr.wales)
        cp = None if (m_c, n_c) == (pr.courses, pr.wales) else coarse_problem(pr, params, m_c, n_c)
        if cp is None:
            return chain
        chain.append(cp)
        pr, params = cp, WeftParams.of(cp)


def multilevel_start(wnlp: WeftNLP, p: np.ndarray, log: list[str] | None = None
                     ) -> np.ndarray | None:
    """Solve the pull on the coarsest fabric of :func:`coarse_chain` from its natural state; if
    that took more than EASY_ITERATIONS (the pull is hard for a cold start), prolong the
    solution level by level (each level solved from the prolonged start) up to this fabric.
    None (start natural) where no coarser problem is defined, the probe was easy or a coarse
    solve failed. Every coarse solve is appended to ``log``, coarsest first."""
    from .solve import WeftSolver, solve
    if wnlp.model != "full":
        return None
    chain = coarse_chain(wnlp.problem, WeftParams.from_vector(wnlp.problem, p))
    x, prev = None, None
    for level, cp in enumerate(reversed(chain)):
        nlp = build_nlp(cp)
        x0 = None if prev is None else prolong(prev, x, nlp)
        rep = solve(nlp, WeftSolver(nlp), x0=x0, start="natural")
        if log is not None:
            log.append(f"multilevel {cp.courses}x{cp.wales}: {rep.status} ({rep.iterations} it, "
                       f"{rep.solve_s:.2f} s)")
        if not rep.success or (level == 0 and rep.iterations <= EASY_ITERATIONS):
            return None
        x, prev = rep.x, nlp
    return None if prev is None else prolong(prev, x, wnlp)


def _rotation(phi: float) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])
