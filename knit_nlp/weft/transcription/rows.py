"""Material points and constraint rows every weft transcription describes the same way.

- *Special points*: the distinct clamped and loaded material points (loop k, s), with each
  clamp's, load's and rigid clamp's index among them.
- *Evaluation points*: the s-values each loop's integral of eq. (1) is evaluated at: the loop's
  end L (the chaining of eq. 1), the four spring points B, R, E, H of eqs. (6)-(7) and the
  special points.
- *Clamp rows*: per clamp its held coordinates P[dims] − target[dims] and, if it holds an angle,
  θ(s) − angle; per rigid clamp, every point P − (c + R(φ)(P0 − c) + t). :func:`add_clamp_rows`
  places them in a constraint layout and :class:`ClampRows` records where; results read the
  reactions from the multipliers at those rows.

Every transcription keeps both, the points and the rows, in one :class:`ClampTable`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import casadi as ca
import numpy as np

from ...layout import Layout
from ..model.basis import n_coeffs
from ..model.parametrisation import Full, Reduced
from ..model.problem import RigidClamp, WeftProblem

SPRING_POINTS = ("B", "R", "E", "H")
SPRINGS = (("SL", "B", "E"), ("SR", "R", "H"))   # block, upper point, lower point


@dataclass
class SpecialPoint:
    """A clamped or loaded material point: 0-based loop index k = (i−1)·n + (j−1) and s."""

    k: int
    s: float


@dataclass(frozen=True)
class ClampRows:
    """The constraint rows of one clamp: its held coordinates (``dims``) and its angle."""

    position: slice | None
    dims: tuple[int, ...]
    angle: slice | None


@dataclass(frozen=True)
class ClampTable:
    """Where an NLP holds and loads its fabric: the special points (:func:`special_points`),
    each clamp's, load's and rigid clamp's indices among them, and the clamps' and rigid
    clamps' constraint rows (:func:`add_clamp_rows`)."""

    specials: list[SpecialPoint]
    clamp_points: list[int]
    load_points: list[int]
    rigid_points: list[list[int]]
    clamp_rows: list[ClampRows]
    rigid_rows: list[slice]


def loop_index(pr: WeftProblem, loop: tuple[int, int]) -> int:
    """0-based loop index k of a 1-based (course, wale)."""
    return (loop[0] - 1) * pr.wales + (loop[1] - 1)


def has_springs(pr: WeftProblem) -> bool:
    """Whether the fabric has crossing springs (eqs. 6-7): two courses or more."""
    return pr.courses > 1 and pr.crossings is not None


def eval_points(pr: WeftProblem, specials: Sequence[SpecialPoint]) -> list[float]:
    """The s-values each loop's integral reports: L, the spring points, then special points."""
    pts = [pr.L]
    if has_springs(pr):
        pts += [pr.crossings.s[k] for k in SPRING_POINTS]
    for sp in specials:
        if sp.s not in pts:
            pts.append(sp.s)
    return pts


def special_points(pr: WeftProblem) -> tuple[list[SpecialPoint], list[int], list[int],
                                             list[list[int]]]:
    """Distinct clamped/loaded material points, and each clamp's, load's and rigid clamp's
    point indices among them."""
    specials: list[SpecialPoint] = []

    def index(loop: tuple[int, int], s: float) -> int:
        k = loop_index(pr, loop)
        for q, sp in enumerate(specials):
            if sp.k == k and sp.s == s:
                return q
        specials.append(SpecialPoint(k, s))
        return len(specials) - 1

    clamps = [index(c.loop, c.s) for c in pr.clamps]
    loads = [index(ld.loop, ld.s) for ld in pr.loads]
    rigid = [[index(loop, s) for loop, _, s in rc.points] for rc in pr.rigid_clamps]
    return specials, clamps, loads, rigid


def rigid_natural_points(pr: WeftProblem) -> list[np.ndarray]:
    """Natural positions (k × 2) of each rigid clamp's points."""
    return [np.array([pr.natural_position(loop, s) for loop, _, s in rc.points])
            for rc in pr.rigid_clamps]


def rigid_targets(rc: RigidClamp, natural: np.ndarray, tx: Any, ty: Any, rotation: Any) -> Any:
    """Where a rigid clamp's points go (2 × k): c + R(φ)(P0 − c) + t, for numbers (a DM) or
    CasADi symbols alike."""
    d = ca.DM((natural - rc.centre).T)
    c, s = ca.cos(rotation), ca.sin(rotation)
    return (ca.DM(rc.centre) + ca.vertcat(c * d[0, :] - s * d[1, :], s * d[0, :] + c * d[1, :])
            + ca.vertcat(tx, ty))


def held_dims(fix: tuple[bool, bool]) -> tuple[int, ...]:
    """The coordinates (0 = x, 1 = y) a clamp holds."""
    return tuple(d for d in range(2) if fix[d])


def add_clamp_rows(g: Layout, pr: WeftProblem) -> tuple[list[ClampRows], list[slice]]:
    """Append the clamp rows to a constraint layout, in this order: per clamp its held
    coordinates then its angle, then per rigid clamp its points (x, y per point); return where
    each clamp's and each rigid clamp's rows are."""
    clamp_rows, rigid_rows = [], []
    for q, c in enumerate(pr.clamps):
        dims = held_dims(c.fix)
        pos = g.add(f"clamp{q}_pos", len(dims), 1) if dims else None
        angle = g.add(f"clamp{q}_angle", 1, 1) if c.angle is not None else None
        clamp_rows.append(ClampRows(pos, dims, angle))
    for q, rc in enumerate(pr.rigid_clamps):
        rigid_rows.append(g.add(f"rigid{q}", 2 * len(rc.points), 1))
    return clamp_rows, rigid_rows


def n_parameters(pr: WeftProblem, parametrisation: Full | Reduced) -> int:
    """Parameter count as the paper counts it (docs/weft_model.md, "Parameter counts").

    Full: m·n·(2t+2) + 2m. Reduced over p × q representatives: p·q·2t + 2p + 2m.
    """
    if not isinstance(parametrisation, Reduced):
        return pr.courses * pr.wales * n_coeffs(pr.t) + 2 * pr.courses
    red = parametrisation.resolve(pr.courses, pr.wales)
    p, q = len(red.courses), len(red.wales)
    return p * q * 2 * pr.t + 2 * p + 2 * pr.courses
