"""The radii the contact rule can judge, and the one-line reason for those it cannot.

The rule (natural.py) has three parts, shared by the solver's pair search and ``check`` (both
take them from ``NaturalFabric``): pieces of one course closer than π·r along the yarn are one
piece (``NaturalFabric.exclusion``); other pieces keep min(2r, natural gap) apart
(``NaturalFabric.lookup``); pieces in the box of a designed crossing only must not cross anew
(``natural.py``, ``zones.py``). The first part is a cut along the yarn: the pair just past
it must already keep its 2r in the natural fabric, or a pair 7.70 along the yarn is judged
and one 7.69 along it is not, though they are the same contact (r = 2.45, π·r = 7.697, on the
10 x 10 pull: the solver, sampling every 0.63, took them for one piece; check, sampling every
0.05, found 23 gaps 38 % short). A tube of radius r whose centreline bends tighter than r
overlaps itself on the inside of the bend, and its pieces π·r apart are then closer than 2r:
such a radius is refused (:func:`refusal`), with the largest radius the natural loop admits.
So is a radius at or above the course spacing (a course's yarn would cover the next course's
whole width) and one so thin that 2r is below the solver's tolerance on the gap rows.
"""
from __future__ import annotations

import numpy as np

from .natural import EXCLUSION

CUT_TOL = 1e-3             # the natural pieces at the cut must keep 2r·(1 − CUT_TOL)
THINNEST = 1e-6            # r below THINNEST·L: 2r is lost in IPOPT's tolerance (1e-8)
SAMPLES = 2001             # points per loop where the cut is measured


def cut_gap(natural, radius: float, loop: tuple[np.ndarray, np.ndarray] | None = None
            ) -> tuple[float, float]:
    """The smallest distance between natural pieces of one course EXCLUSION·π·r apart along
    the yarn, and the material point s where it is (on a course of natural loops; ``loop``:
    the natural loop sampled, :func:`_loop`)."""
    L = natural.length
    s, xy = _loop(natural) if loop is None else loop
    u = s + EXCLUSION * np.pi * radius
    loops, rest = np.divmod(u, L)
    there = np.stack([np.interp(rest, s, xy[:, 0]), np.interp(rest, s, xy[:, 1])], axis=1)
    shift = loops[:, None] * np.array([natural.wale_spacing, natural.rise])
    d = np.linalg.norm(there + shift - xy, axis=1)
    i = int(np.argmin(d))
    return float(d[i]), float(s[i])


def _loop(natural) -> tuple[np.ndarray, np.ndarray]:
    """The natural loop at ``SAMPLES`` points (linear between them: 4e-6 of L = 10 off the
    curve, far below ``CUT_TOL``)."""
    s = np.linspace(0.0, natural.length, SAMPLES)
    return s, natural.xy(s)


def largest_clean(natural, radius: float) -> float:
    """The largest radius up to ``radius`` whose cut is clean (bisection, to 1e-6 of it)."""
    loop = _loop(natural)
    lo, hi = THINNEST * natural.length, radius
    if not _clean(natural, lo, loop):
        return 0.0
    while hi - lo > 1e-6 * radius:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _clean(natural, mid, loop) else (lo, mid)
    return lo


def _clean(natural, radius: float, loop) -> bool:
    return cut_gap(natural, radius, loop)[0] >= 2 * radius * (1 - CUT_TOL)


def refusal(natural, radius: float) -> str | None:
    """Why the contact rule cannot judge a yarn of this radius on this natural loop, in one
    line (None when it can)."""
    L, c = natural.length, natural.course_spacing
    if radius < THINNEST * L:
        return (f"{radius:g} is below {THINNEST:g} of the loop length: a gap of 2r is lost in "
                "the solver's tolerance; leave [yarn] out for the paper's model")
    if radius >= c:
        return (f"{radius:g} is at or above the course spacing {c:.4g}: a course's yarn would "
                "cover the next course's whole width, so every piece of the fabric overlaps its "
                "neighbours; the model cannot place such a yarn")
    gap, s = cut_gap(natural, radius)
    if gap < 2 * radius * (1 - CUT_TOL):
        best = largest_clean(natural, radius)
        return (f"{radius:g} makes the same-yarn rule ambiguous: pieces of one yarn "
                f"pi*r = {EXCLUSION * np.pi * radius:.4g} apart along it (from s = {s:.3g}) "
                f"are {gap:.4g} apart, closer than 2r = {2 * radius:.4g}, in the natural loop "
                f"(it bends tighter than the yarn is thick); use r <= {best:.4g}")
    return None
