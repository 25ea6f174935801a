"""Starting points of a weft NLP that need no solve (those that solve are in ``solve``).

- ``rigid_start``: the natural configuration violates a moved clamp by the whole pull (182
  units on the 100 × 100 diagonal pull) and IPOPT's filter line search then takes 1/128 of its
  first steps.
  ``rigid_start`` removes the rigid part of that violation: it turns and moves the natural fabric
  by the rigid motion that best fits the clamp targets (2-D Kabsch over the fully clamped
  points). Every loop's angle gains the turn (θ → θ + φ, the constant basis coefficient of
  eq. 15), loop starts are turned and moved with it, and the transcription lifts those loops
  (``WeftNLP.lift``; exact in both models: a common turn keeps continuity and lies in every
  reduced space), so chaining (eq. 1), continuity (18)-(19) and all lifted constraints hold
  exactly; only the clamps (and angle clamps) keep a residual.
- coarse problems and their prolongation (loops and multipliers), for the multilevel start of
  the full model;
- perturbations of a straight natural yarn: where the natural yarn is straight, a compressive
  clamp leaves IPOPT at a point where the end position does not depend, to first order, on the
  shape (the Jacobian loses rank); the solve then starts from a few smooth perturbations and
  keeps the lowest-energy solution (``solve``).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..model.basis import n_coeffs, phi
from ..model.params import WeftParams
from ..model.problem import Clamp, RigidClamp, WeftProblem, canonical_point
from ..model.quadrature import positions
from ..transcription.protocol import WeftNLP
from ..transcription.rows import rigid_natural_points, rigid_targets

STARTS = ("multilevel", "rigid", "natural")
COARSEST = 12          # the multilevel start solves cold once a side is at most this many loops


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
    for rc, P0, motion in zip(pr.rigid_clamps, rigid_natural_points(pr), params.rigid):
        nat += list(P0)
        tgt += list(np.asarray(rigid_targets(rc, P0, *motion)).T)
    return np.reshape(nat, (-1, 2)), np.reshape(tgt, (-1, 2))


def best_rigid_motion(nat: np.ndarray, tgt: np.ndarray) -> tuple[float, np.ndarray]:
    """Angle φ and translation b minimising Σ|R(φ)X + b − x|² (2-D Kabsch); φ = 0 for fewer
    than two points, b = 0 for none."""
    if len(nat) == 0:
        return 0.0, np.zeros(2)
    cn, ct = nat.mean(axis=0), tgt.mean(axis=0)
    u, v = nat - cn, tgt - ct
    turn = float(np.arctan2(np.sum(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]), np.sum(u * v))) \
        if len(nat) > 1 else 0.0
    return turn, ct - _rotation(turn) @ cn


def rigid_start(wnlp: WeftNLP, p: np.ndarray) -> np.ndarray:
    """The natural fabric turned by φ and moved by b, the best rigid fit to the clamp targets."""
    pr = wnlp.problem
    turn, b = best_rigid_motion(*clamp_pairs(wnlp, p))
    coeffs = np.broadcast_to(pr.natural.coeffs, (pr.courses, pr.wales, n_coeffs(pr.t))).copy()
    coeffs[..., -1] += turn
    return wnlp.lift(coeffs, pr.natural_starts() @ _rotation(turn).T + b)


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
    """A fine decision vector from a coarse solution: loop coefficients and every loop start's
    displacement from its natural position interpolated bilinearly at the same fractions of the
    courses and wales, the displacements scaled by 1/r (the pull scales with the fabric,
    :func:`coarse_problem`), and the lifted points recomputed; the chaining rows (eq. 1) keep
    per-loop residuals of the interpolation's order.

    The starts used to be chained from each course's first loop through the interpolated
    shapes: the per-loop errors then add up along a course, and the start's energy grew about
    4.7x per level (100 x 100 diagonal pull: 2 775 against the solution's 547, violation 2.1;
    interpolated: 574, violation 1.7); at 200 x 200 the chained start had energy 1.08e5 and
    violation 11.6, and IPOPT crawled from it (docs/measurements.md, "Scale")."""
    pc, pf = coarse.problem, fine.problem
    xi = _fractions(pf.courses, pc.courses)
    eta = _fractions(pf.wales, pc.wales)
    a = _interp(_interp(coarse.coefficients(xc), xi, axis=0), eta, axis=1)
    r = np.array([(pc.wales - 1) / (pf.wales - 1) if pf.wales > 1 else 1.0,
                  (pc.courses - 1) / (pf.courses - 1) if pf.courses > 1 else 1.0])
    d_c = coarse.starts(xc) - pc.natural_starts()
    d = _interp(_interp(d_c, xi, axis=0), eta, axis=1) / r
    return fine.lift(a, pf.natural_starts() + d)


# the full model's per-loop constraint blocks (``transcription.full``) and the loop grid each
# lives on, as (courses, wales) offsets from the fabric's: chaining and continuity rows on every
# loop but the last of each course, the lifted spring vectors on every loop above course 1
LOOP_BLOCKS = {"chain": (0, -1), "continuity": (0, -1), "lift_SL": (-1, 0), "lift_SR": (-1, 0)}


def prolong_multipliers(coarse: WeftNLP, lam: np.ndarray, fine: WeftNLP) -> np.ndarray:
    """The fine constraints' multipliers from a coarse solution's, for a warm start.

    The multipliers are forces and moments. Under the multilevel scaling (the pull scaled with
    the fabric, loops of the same size) the strain field is the same at the same fraction of
    the fabric, so the per-loop forces of :data:`LOOP_BLOCKS` (yarn tension at loop ends,
    spring forces, continuity moments) are interpolated bilinearly at the same fractions,
    unscaled; the forces at the clamped points balance forces over a whole cross-section, which
    in 2-D grows with the fabric, so they are scaled by 1/r (r the geometric mean of the two
    axes' ratios) where the coarse problem has the same rows; blocks it lacks or that differ
    in size (merged clamps) start at zero. Measured on the 100 x 100 diagonal pull: the coarse
    levels 13, 25 and 50 took 5, 5 and 6 iterations instead of 7, 8 and 8, to the same minima
    (docs/measurements.md)."""
    pc, pf = coarse.problem, fine.problem
    ratios = [(c - 1) / (f - 1) for c, f in ((pc.courses, pf.courses), (pc.wales, pf.wales))
              if f > 1]
    r = float(np.sqrt(np.prod(ratios))) if ratios else 1.0
    out = np.zeros(fine.n_constraints)
    for name, (start, stop, _) in fine.g.blocks.items():
        if name not in coarse.g.blocks:
            continue
        vc = lam[coarse.g.slice(name)]
        if name in LOOP_BLOCKS:
            dc, dw = LOOP_BLOCKS[name]
            mc, nc, mf, nf = pc.courses + dc, pc.wales + dw, pf.courses + dc, pf.wales + dw
            if min(mc, nc, mf, nf) < 1:
                continue
            grid = vc.reshape(mc, nc, -1)           # loop-major rows (``full._Constraints``)
            out[start:stop] = _interp(_interp(grid, _fractions(mf, mc), axis=0),
                                      _fractions(nf, nc), axis=1).ravel()
        elif vc.size == stop - start:
            out[start:stop] = vc / r
    return out


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


def _rotation(phi: float) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])


def perturbed_starts(wnlp: WeftNLP, amplitude: float = 0.05) -> list[tuple[str, np.ndarray]]:
    """Smooth low-mode perturbations of the natural shape, as decision vectors.

    Along each course (global arc length S in [0, ℓ], ℓ = n·L) θ gets + ε·f(πS/ℓ) with f one of
    cos, sin and their second harmonics; each loop's share is fitted to the basis by least
    squares and the loop starts are re-chained so the start is consistent.
    """
    pr = wnlp.problem
    m, n, L, t = pr.courses, pr.wales, pr.L, pr.t
    ell = n * L
    s = np.linspace(0.0, L, 8 * n_coeffs(t))
    basis = phi(s, L, t)
    out = []
    for name, f in (("cos1", lambda u: np.cos(u)), ("sin1", lambda u: np.sin(u)),
                    ("cos2", lambda u: np.cos(2 * u)), ("sin2", lambda u: np.sin(2 * u))):
        coeffs = np.broadcast_to(pr.natural.coeffs, (m, n, n_coeffs(t))).copy()
        for j in range(n):
            fit, *_ = np.linalg.lstsq(basis, amplitude * f(np.pi * (j * L + s) / ell), rcond=None)
            coeffs[:, j] += fit
        starts = pr.natural_starts().copy()
        ends = positions(coeffs.reshape(-1, n_coeffs(t)), [L], L, t).reshape(m, n, 2)
        for j in range(1, n):
            starts[:, j] = starts[:, j - 1] + ends[:, j - 1]
        out.append((name, wnlp.lift(coeffs, starts)))
    return out


def needs_perturbation(wnlp: WeftNLP, p: np.ndarray) -> bool:
    """A straight natural yarn with any clamp moved off its natural position (or any load) is
    degenerate at parameters p."""
    if not wnlp.problem.natural.is_straight:
        return False
    return not np.allclose(WeftParams.natural(wnlp.problem).vector(), p)


def largest_move(pr: WeftProblem, p_from: np.ndarray, p_to: np.ndarray) -> float:
    """The furthest any held point moves from parameters p_from to p_to: a point clamp's held
    coordinates, a rigid clamp's every point (in the plane)."""
    a, b = WeftParams.from_vector(pr, p_from), WeftParams.from_vector(pr, p_to)
    moves = [0.0]
    for c, t0, t1 in zip(pr.clamps, a.targets, b.targets):
        d = (np.asarray(t1) - np.asarray(t0)) * np.asarray(c.fix, dtype=float)
        moves.append(float(np.hypot(*d)))
    for rc, P0, m0, m1 in zip(pr.rigid_clamps, rigid_natural_points(pr), a.rigid, b.rigid):
        d = np.asarray(rigid_targets(rc, P0, *m1)) - np.asarray(rigid_targets(rc, P0, *m0))
        moves.append(float(np.max(np.hypot(*d))))
    return max(moves)
