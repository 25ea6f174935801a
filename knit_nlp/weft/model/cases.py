"""Shared load cases as problem documents (the dicts a TOML problem file parses to), used by the
shipped problems' tests, the scripts and the benchmarks: one definition of each pull.

- :func:`diagonal_pull`: the paper's eq. 28 (x₁₁(0) = y₁₁(0) = 0, H of loop (1, 5) moved to
  (16.2, 13.9) on a 5 × 5 fabric) scaled to an m × n fabric: the chord from the pinned corner to
  H(1, n) is stretched and turned exactly as eq. 28 stretches and turns it on 5 × 5.
- :func:`course_pull`: left edge held in x (course 1 also in y), right edge pulled along x.
- :func:`unclamped`: the fabric alone, with the paper's material.
"""
from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from .crossing_points import find_crossings
from .natural_loop import natural_loop, preset_coeffs

PAPER_MATERIAL = {"k_a": 1.0, "k_b": 0.01, "R_f": 1.0}      # eq. 28's values
EQ28_TARGET = (16.2, 13.9)                                    # x₁₅(s_H), y₁₅(s_H) on 5 × 5


@lru_cache(maxsize=None)
def _jersey():
    return natural_loop(preset_coeffs("jersey", 3), 10.0, 3)


def _natural_h(n: int) -> np.ndarray:
    """Natural position of H on loop (1, n) of a jersey fabric with loop (1, 1) at the origin."""
    loop = _jersey()
    return np.array([(n - 1) * loop.wale_spacing, 0.0]) + loop.xy([find_crossings(loop).s["H"]])[0]


def eq28_map() -> tuple[float, float]:
    """(stretch, turn in radians) that eq. 28 applies to the corner-to-H(1, 5) chord."""
    h0, h1 = _natural_h(5), np.array(EQ28_TARGET)
    turn = np.arctan2(h1[1], h1[0]) - np.arctan2(h0[1], h0[0])
    return float(np.linalg.norm(h1) / np.linalg.norm(h0)), float(turn)


def unclamped(m: int, n: int) -> dict[str, Any]:
    """An m × n jersey fabric (t = 3) with the paper's material and no clamps."""
    return {"fabric": {"courses": m, "wales": n}, "material": dict(PAPER_MATERIAL)}


def diagonal_pull(n: int, m: int | None = None) -> dict[str, Any]:
    """Eq. 28 scaled to an m × n fabric (m = n by default): loop (1, 1)'s start pinned at the
    origin, H of loop (1, n) moved by eq. 28's stretch and turn of its chord."""
    m = n if m is None else m
    stretch, turn = eq28_map()
    c, s = np.cos(turn), np.sin(turn)
    target = stretch * np.array([[c, -s], [s, c]]) @ _natural_h(n)
    doc = unclamped(m, n)
    doc.update(name=f"diagonal_pull_{m}x{n}",
               clamp=[{"loop": [1, 1], "point": "start", "position": [0.0, 0.0]},
                      {"loop": [1, n], "point": "H", "position": target.tolist()}])
    return doc


def course_pull(n: int, strain: float = 0.25, m: int | None = None) -> dict[str, Any]:
    """Left edge held in x (course 1 also in y), right edge pulled by ``strain`` of the fabric's
    natural width along x."""
    m = n if m is None else m
    w = _jersey().wale_spacing
    clamps = []
    for i in range(1, m + 1):
        clamps.append({"loop": [i, 1], "point": "start", "displacement": [0.0, 0.0],
                       "fix": ["x", "y"] if i == 1 else ["x"]})
        clamps.append({"loop": [i, n], "point": "end", "displacement": [strain * n * w, 0.0],
                       "fix": ["x"]})
    doc = unclamped(m, n)
    doc.update(name=f"course_pull_{m}x{n}", clamp=clamps)
    return doc
