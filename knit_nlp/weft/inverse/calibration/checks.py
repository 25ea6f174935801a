"""What a textile researcher checks first (issue 40 item 4), model beside measured.

Besides the RMS strain errors of the metric (``metric``), read off the force-strain curves:

- the force at 10 % and 30 % axial strain (N);
- the tangent stiffening from 5 % to 45 % strain, K(0.45) / K(0.05), with the tangent stiffness
  K(ε) = (F(ε + h) − F(ε − h)) / 2h, h = 0.025 (a central secant: the measured runs are too
  noisy for a derivative);
- the ratio of wale to course stiffness per width at 10 % strain, K_y(0.1)/W_y over
  K_x(0.1)/W_x, W the real specimen's width (mm).

F(ε) on a sequence of (axial strain, force) points: linear between the last point before the
first one whose strain reaches ε and that one (on the model's monotone curve nodes, plain
linear interpolation; on a measured run, within a frame of its first frame reaching ε). The
measured value is the median over runs of F(ε); runs that never reach ε are left out, and where
none does the value is None (the y tests stop at 23 % strain: no 30 % force, no stiffening).
"""
from __future__ import annotations

from typing import Any

import numpy as np

FORCE_STRAINS = (0.10, 0.30)
STIFFENING = (0.05, 0.45)
RATIO_STRAIN = 0.10
HALF = 0.025


def force_at(axial: np.ndarray, force: np.ndarray, strain: float) -> float | None:
    """F(ε) (module doc) on one sequence of points; None when the strain is never reached."""
    hits = np.flatnonzero(np.asarray(axial) >= strain)
    if hits.size == 0:
        return None
    k = int(hits[0])
    if k == 0:
        return float(force[0])
    e0, e1, f0, f1 = axial[k - 1], axial[k], force[k - 1], force[k]
    return float(f0 + (f1 - f0) * (strain - e0) / (e1 - e0))


def median_force(curves: list[tuple[np.ndarray, np.ndarray]], strain: float) -> float | None:
    """Median over (axial, force) curves of F(ε), over the curves that reach ε."""
    values = [f for f in (force_at(a, F, strain) for a, F in curves) if f is not None]
    return float(np.median(values)) if values else None


def tangent(curves: list[tuple[np.ndarray, np.ndarray]], strain: float) -> float | None:
    """K(ε) = (F(ε + h) − F(ε − h)) / 2h, N per unit strain, from the median forces."""
    hi, lo = median_force(curves, strain + HALF), median_force(curves, strain - HALF)
    return None if hi is None or lo is None else (hi - lo) / (2 * HALF)


def _ratio(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None or b == 0 else a / b


def curve_checks(curves: list[tuple[np.ndarray, np.ndarray]], width: float) -> dict[str, Any]:
    """Force at FORCE_STRAINS, stiffening over STIFFENING and stiffness per width (N/mm per
    unit strain) at RATIO_STRAIN, of one test's curve(s)."""
    k0, k1 = (tangent(curves, e) for e in STIFFENING)
    k_ratio = tangent(curves, RATIO_STRAIN)
    return {"force_N": {f"{e:g}": median_force(curves, e) for e in FORCE_STRAINS},
            "stiffening": _ratio(k1, k0),
            "stiffness_per_width": None if k_ratio is None else k_ratio / width}


def outcome_checks(model: tuple[np.ndarray, np.ndarray], runs: list[tuple[np.ndarray, np.ndarray]],
                width: float) -> dict[str, Any]:
    """One test's checks, model (its curve nodes) beside measured (its runs), same width."""
    return {"model": curve_checks([model], width), "measured": curve_checks(runs, width)}


def wale_over_course(checks: list[tuple[str, dict[str, Any]]]) -> dict[str, float | None] | None:
    """The ratio of wale to course stiffness per width at RATIO_STRAIN, model and measured, from
    the first test of each direction ((direction, test checks) pairs); None without both."""
    first = {}
    for direction, c in checks:
        first.setdefault(direction, c)
    if set(first) != {"courses", "wales"}:
        return None
    return {side: _ratio(first["wales"][side]["stiffness_per_width"],
                         first["courses"][side]["stiffness_per_width"])
            for side in ("model", "measured")}


def describe(c: dict[str, Any]) -> str:
    """One summary line of a test's checks: model (measured)."""
    def pair(key: str, sub: str | None = None, fmt: str = ".3g") -> str:
        m = c["model"][key] if sub is None else c["model"][key][sub]
        d = c["measured"][key] if sub is None else c["measured"][key][sub]
        show = lambda v: "n/a" if v is None else format(v, fmt)   # noqa: E731
        return f"{show(m)} (measured {show(d)})"
    forces = ", ".join(f"at {float(e):.0%} {pair('force_N', e)} N" for e in c["model"]["force_N"])
    return (f"force {forces}; stiffening {STIFFENING[0]:.0%} -> {STIFFENING[1]:.0%} "
            f"{pair('stiffening')}; stiffness per width at {RATIO_STRAIN:.0%} "
            f"{pair('stiffness_per_width')} N/mm")
