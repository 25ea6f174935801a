"""Crossings of vertically neighbouring loops and the material points of eqs. (2)-(5).

In the natural configuration the centrelines of loop (i, j) ("upper", shifted up by the course
spacing c) and loop (i−1, j) ("lower") cross at four points: A, C on the upper loop's left leg
(s_A < s_C), the same points being D, F on the lower loop; Q, S on the upper loop's right leg,
being G, P on the lower loop. B, E, H, R are the s-midpoints of eqs. (2)-(5).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .basis import phi
from .contact.natural import natural_crossings
from .natural_loop import NaturalLoop

LABELS = ("A", "C", "B", "D", "F", "E", "Q", "S", "R", "G", "P", "H")


class CrossingError(ValueError):
    """The natural geometry does not give the four crossings the model needs."""


@dataclass(frozen=True)
class Crossings:
    """Material s-values of the labelled points and the spring frames (eqs. 2-8).

    ``s`` maps each label to its s-value (the same on every loop). ``frame_left``/``frame_right``
    are 2×2 matrices with rows (a, b): b along A0→C0 (Q0→S0), a ⟂ b. ``rest_left``/``rest_right``
    are the natural spring vectors B0E0 and R0H0 (lower point minus upper point).
    """

    s: dict[str, float]
    frame_left: np.ndarray
    frame_right: np.ndarray
    rest_left: np.ndarray
    rest_right: np.ndarray


def find_crossings(loop: NaturalLoop, samples: int = 801) -> Crossings:
    """Locate the four crossings of an upper and a lower natural loop and label them.

    Raises :class:`CrossingError` unless there are exactly two crossings on each half of the
    upper loop.
    """
    L = loop.length
    shift = np.array([0.0, loop.course_spacing])
    pairs = _refine(loop, _candidate_pairs(loop, samples, shift), shift)
    left = sorted(p for p in pairs if p[0] < L / 2)
    right = sorted(p for p in pairs if p[0] > L / 2)
    if len(left) != 2 or len(right) != 2:
        raise CrossingError(
            f"the natural loops of neighbouring courses cross {len(pairs)} times "
            f"({len(left)} on the left leg, {len(right)} on the right); the model needs 2 + 2")
    (sA, sD), (sC, sF) = left
    (sQ, sG), (sS, sP) = right
    s = dict(A=sA, C=sC, D=sD, F=sF, Q=sQ, S=sS, G=sG, P=sP,
             B=0.5 * (sA + sC), E=0.5 * (sD + sF), R=0.5 * (sQ + sS), H=0.5 * (sG + sP))
    xy = {k: loop.xy([v])[0] for k, v in s.items()}
    up = {k: xy[k] + shift for k in "ACBQSR"}
    return Crossings(s, _frame(up["A"], up["C"]), _frame(up["Q"], up["S"]),
                     xy["E"] - up["B"], xy["H"] - up["R"])


def _frame(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Rows (a, b): b the unit vector p0→p1, a = b rotated by +90°."""
    b = (p1 - p0) / np.linalg.norm(p1 - p0)
    return np.array([[-b[1], b[0]], b])


def _candidate_pairs(loop: NaturalLoop, samples: int, shift: np.ndarray) -> list[tuple[float, float]]:
    """Polyline segment intersections of the upper and lower loop: approximate (s_up, s_low)
    (``contact.natural.natural_crossings``, the intersection of two sampled yarns)."""
    s = np.linspace(0.0, loop.length, samples)
    low = loop.xy(s)
    return [(su, sl) for su, sl, _ in natural_crossings(low + shift, low, s)]


def _refine(loop: NaturalLoop, pairs: list[tuple[float, float]], shift: np.ndarray,
            ) -> list[tuple[float, float]]:
    """Newton on upper(s_u) − lower(s_l) = 0 from each candidate; duplicates merged."""
    L, t, a0 = loop.length, loop.harmonics, loop.coeffs
    out: list[tuple[float, float]] = []
    for su, sl in pairs:
        res = np.full(2, np.inf)
        for _ in range(50):
            pu, pl = loop.xy([su, sl])
            res = pu + shift - pl
            th_u, th_l = phi([su, sl], L, t) @ a0
            jac = np.array([[np.cos(th_u), -np.cos(th_l)], [np.sin(th_u), -np.sin(th_l)]])
            try:
                step = np.linalg.solve(jac, -res)
            except np.linalg.LinAlgError:
                break
            su, sl = su + step[0], sl + step[1]
            if np.max(np.abs(step)) < 1e-14 * L:
                break
        if not (0.0 <= su <= L and 0.0 <= sl <= L and np.max(np.abs(res)) < 1e-9 * L):
            continue
        if not any(abs(su - a) < 1e-8 * L and abs(sl - b) < 1e-8 * L for a, b in out):
            out.append((float(su), float(sl)))
    return out
