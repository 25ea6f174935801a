"""The yarn drawn with its thickness, and the active contacts, on a solution picture."""
from __future__ import annotations

from typing import Any

import matplotlib
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection

YARN_ALPHA = 0.6         # the band's fill; its outline (YARN_EDGE pt, the course colour darkened)
YARN_EDGE = 0.5          # is opaque, so the yarn's width 2r reads even where it is a few pixels
YARN_ZORDER = 2.5        # over the coloured centrelines (zorder 2, 1.8 pt), which it covers
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
    """Bands of width 2r around every course (coloured like the courses, outlined, drawn over
    the centrelines so that the picture shows the yarn's width, not the centreline's line
    width) and a marker at every active contact (the midpoint of its two centreline
    points)."""
    yarn = result.problem.yarn
    if yarn is None:
        raise ValueError("the yarn has no thickness here: add [yarn] radius to draw it")
    m = len(deformed)
    cmap = matplotlib.colormaps["viridis"]
    colours = [cmap((i + 0.5) / m) for i in range(m)]
    edges = [tuple(0.6 * np.array(c[:3])) + (1.0,) for c in colours]
    ax.add_collection(PolyCollection(yarn_bands(deformed, yarn.radius),
                                     facecolors=[c[:3] + (YARN_ALPHA,) for c in colours],
                                     edgecolors=edges, linewidths=YARN_EDGE, zorder=YARN_ZORDER,
                                     label=f"yarn, radius {yarn.radius:g} "
                                     f"{result.problem.units.length}"))
    contacts = () if result.contact is None else result.contact.contacts
    if contacts:
        pts = np.array([c.point for c in contacts])
        ax.plot(pts[:, 0], pts[:, 1], "o", ms=3.5, mfc="white", mec=CONTACT, mew=1.0, zorder=5,
                label=f"active contact ({len(contacts)})")
