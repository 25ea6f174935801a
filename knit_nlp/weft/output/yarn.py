"""The yarn drawn with its thickness, and the active contacts, on a solution picture."""
from __future__ import annotations

from typing import Any

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection

YARN_ALPHA = 0.3
CONTACT = "black"


def yarn_bands(lines: np.ndarray, radius: float) -> list[np.ndarray]:
    """One polygon per course: its centreline offset by ±radius along the normals."""
    bands = []
    for course in lines:
        c = np.concatenate([course[0]] + [loop[1:] for loop in course[1:]], axis=0)
        t = np.gradient(c, axis=0)
        t /= np.maximum(np.linalg.norm(t, axis=1), 1e-300)[:, None]
        nrm = np.stack([-t[:, 1], t[:, 0]], axis=1)
        bands.append(np.concatenate([c + radius * nrm, (c - radius * nrm)[::-1]]))
    return bands


def draw_yarn(ax: Axes, result: Any, deformed: np.ndarray) -> None:
    """Bands of width 2r around every course (coloured like the courses) and a marker at every
    active contact (the midpoint of its two centreline points)."""
    yarn = result.problem.yarn
    if yarn is None:
        raise ValueError("the yarn has no thickness here: add [yarn] radius to draw it")
    m = len(deformed)
    cmap = matplotlib.colormaps["viridis"]
    colours = [cmap((i + 0.5) / m) for i in range(m)]
    ax.add_collection(PolyCollection(yarn_bands(deformed, yarn.radius), facecolors=colours,
                                     edgecolors="none", alpha=YARN_ALPHA, zorder=1.5,
                                     label=f"yarn, radius {yarn.radius:g} "
                                     f"{result.problem.units.length}"))
    contacts = result.extra.get("contact", {}).get("contacts", [])
    if contacts:
        pts = np.array([c["point"] for c in contacts])
        ax.plot(pts[:, 0], pts[:, 1], "o", ms=3.5, mfc="white", mec=CONTACT, mew=1.0, zorder=5,
                label=f"active contact ({len(contacts)})")
