"""Weft centrelines for other tools: CSV rows ``course,wale,s,x,y`` and an SVG of one polyline
per course (lengths in the problem's unit, y up as in the model; SVG's y axis is flipped)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...atomic import write_text
from ...jsonio import write_csv

EXPORTS = ("csv", "svg")
COLOURINGS = ("course", "displacement")     # how the solution picture colours loops (plot.py)
SVG_UNITS = ("mm", "cm", "in")     # lengths SVG itself knows; others are drawn at PX_PER_UNIT
PX_PER_UNIT = 20.0


def write_centreline_csv(path: Path, lines: np.ndarray, s: np.ndarray) -> Path:
    """One row per sampled point: 1-based course and wale, s along the loop, x, y."""
    m, n, k, _ = lines.shape
    rows = [{"course": i + 1, "wale": j + 1, "s": float(s[q]), "x": float(lines[i, j, q, 0]),
             "y": float(lines[i, j, q, 1])}
            for i in range(m) for j in range(n) for q in range(k)]
    return write_csv(path, rows, ("course", "wale", "s", "x", "y"))


def write_centreline_svg(path: Path, lines: np.ndarray, unit: str, stroke: float = 0.15) -> Path:
    """One ``<polyline>`` per course (id ``course-i``), viewBox in model units with y flipped."""
    pts = lines.reshape(-1, 2)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.02 * float(np.max(hi - lo)) + stroke
    w, h = hi - lo + 2 * pad
    polys = []
    for i, course in enumerate(lines):
        xy = np.concatenate(list(course), axis=0)
        coords = " ".join(f"{x - lo[0] + pad:.4f},{hi[1] + pad - y:.4f}" for x, y in xy)
        polys.append(f'<polyline id="course-{i + 1}" points="{coords}"/>')
    size = (f"{w:.4f}{unit}", f"{h:.4f}{unit}") if unit in SVG_UNITS else (
        f"{w * PX_PER_UNIT:.1f}", f"{h * PX_PER_UNIT:.1f}")
    return write_text(
        path,
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {w:.4f} {h:.4f}" '
        f'width="{size[0]}" height="{size[1]}">\n'
        f'<desc>weft centrelines, one polyline per course; lengths in {unit}</desc>\n'
        f'<g fill="none" stroke="black" stroke-width="{stroke}" stroke-linejoin="round">\n'
        + "\n".join(polys) + "\n</g>\n</svg>\n")
