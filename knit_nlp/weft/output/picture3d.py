"""A PNG of the yarn in three dimensions as a tube of radius r (issue 39, item 3; the tubes
and their frames: :mod:`knit_nlp.weft.output.tubes`).

Three panels, every axis in the problem's length unit, every one of true aspect (a circle of
radius r is round), so the yarn's thickness reads against the axes:

- an oblique view of the fabric (at most OBLIQUE_LOOPS x OBLIQUE_LOOPS loops in its middle;
  the panel's title names them), every tube face in one depth-sorted collection, shaded; a
  loop's samples are thinned to every k-th (at most ``tubes.FACE_BUDGET`` faces; the title
  says k);
- a side view looking along -x at the loops of the middle wale in SIDE_LOOPS courses (y-z):
  the courses' loops interlock there, one passing over the next;
- a side view looking along +y at the middle two courses over SIDE_LOOPS wales (x-z).

A side view draws the exact projection of each tube (the union of discs of radius r around the
projected centreline: one capsule per segment, far segments first, with the tube's silhouette
as a darker line). Courses are told apart by colour (viridis, the plan view's key, with a
colourbar); designed crossings are marked where they fall in a view and named in the legend.
A fabric of any size is drawn in about the time of a 12 x 12 one (the windows above).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.ticker import FormatStrFormatter

from ...figures import legend_below, new_figure, save_figure
from .plot import course_ticks
from .tubes import SIDES, check_centrelines, course_colours, course_path, thinned, tube_rings

DPI = 110
CROSSING = "crimson"
CAPSULE_ARC = 7             # points on each half circle of a side view's capsule
LIGHT = np.array([-0.4, -0.6, 0.7]) / np.linalg.norm([-0.4, -0.6, 0.7])   # from above
ELEVATION, AZIMUTH = 28.0, -60.0           # the oblique view (degrees)
OBLIQUE_LOOPS = 12                         # the oblique view shows at most this many x this many loops
SIDE_LOOPS = 4                             # the side views show this many loops along their axis


def capsules(p: np.ndarray, radius: float) -> np.ndarray:
    """Outlines (P-1, 2·CAPSULE_ARC, 2) of the capsules of radius r around the segments of a
    2-D polyline p (P, 2): their union is the union of the discs of radius r centred on the
    polyline (the projection of a tube of radius r about the 3-D polyline)."""
    a, b = p[:-1], p[1:]
    d = b - a
    ang = np.arctan2(d[:, 1], d[:, 0])[:, None]
    half = np.linspace(-np.pi / 2, np.pi / 2, CAPSULE_ARC)[None, :]
    end = b[:, None] + radius * np.stack([np.cos(ang + half), np.sin(ang + half)], -1)
    start = a[:, None] + radius * np.stack([np.cos(ang + np.pi + half),
                                            np.sin(ang + np.pi + half)], -1)
    return np.concatenate([end, start], axis=1)


def _side_view(ax, pieces: list[tuple[np.ndarray, int]], radius: float, axes_ij: tuple[int, int],
               depth: int, toward: float, colours: np.ndarray, label: str) -> None:
    """The tubes of ``pieces`` ((P, 3) polyline, course) projected on coordinates ``axes_ij``,
    the segments furthest from the viewer (``toward``·coordinate ``depth`` smallest) first:
    each segment its capsule in the course's colour, then the capsule's two long sides (the
    tube's silhouette) as darker lines, so that a tube in front hides the outline behind it."""
    from matplotlib.collections import PolyCollection
    caps, faces, order = [], [], []
    for path, course in pieces:
        caps.append(capsules(path[:, list(axes_ij)], radius))
        faces.append(np.repeat(colours[course][None], len(path) - 1, axis=0))
        order.append(toward * 0.5 * (path[:-1, depth] + path[1:, depth]))
    caps, faces = np.concatenate(caps), np.concatenate(faces)
    k = CAPSULE_ARC
    sides = (caps[:, [k - 1, k]], caps[:, [2 * k - 1, 0]])     # the two straight edges
    dark = faces.copy()
    dark[:, :3] *= 0.45
    polys, face, edge, width = [], [], [], []
    for q in np.argsort(np.concatenate(order), kind="stable"):
        polys += [caps[q], sides[0][q], sides[1][q]]
        face += [faces[q], (0, 0, 0, 0), (0, 0, 0, 0)]
        edge += [(0, 0, 0, 0), dark[q], dark[q]]
        width += [0.0, 0.7, 0.7]
    ax.add_collection(PolyCollection(polys, facecolors=face, edgecolors=edge, linewidths=width,
                                     label=label))
    ax.autoscale()
    ax.set_aspect("equal", adjustable="datalim")   # the box fills its cell: labels stay inside
    ax.margins(0.04)


def _shaded_faces(path: np.ndarray, radius: float, colour: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quads (Q, 4, 3) of one tube and their colours, Lambert-shaded by the light ``LIGHT``."""
    ring = tube_rings(path, radius, SIDES)
    nxt = np.roll(ring, -1, axis=1)
    quads = np.stack([ring[:-1], nxt[:-1], nxt[1:], ring[1:]], axis=2).reshape(-1, 4, 3)
    centre = 0.25 * quads.sum(axis=1)
    mid = 0.5 * (path[:-1] + path[1:])
    normal = centre - np.repeat(mid, SIDES, axis=0)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    shade = 0.35 + 0.65 * np.clip(normal @ LIGHT, 0.0, 1.0)
    rgba = np.repeat(colour[None], len(quads), axis=0)
    rgba[:, :3] *= shade[:, None]
    return quads, rgba


def _oblique(ax, c: np.ndarray, courses: range, radius: float, colours: np.ndarray,
             unit: str, label: str) -> None:
    """The oblique view of the loops ``c`` (courses ``courses`` of the fabric): every tube face
    in one depth-sorted collection, on axes of true aspect."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection
    quads, rgba = zip(*(_shaded_faces(course_path(loops)[0], radius, colours[k])
                        for loops, k in zip(c, courses)))
    ax.add_collection3d(Poly3DCollection(np.concatenate(quads), facecolors=np.concatenate(rgba),
                                         edgecolors="none", label=label))
    lo, hi = c.reshape(-1, 3).min(axis=0) - radius, c.reshape(-1, 3).max(axis=0) + radius
    ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), zlim=(lo[2], hi[2]))
    ax.set_box_aspect(np.maximum(hi - lo, 1e-3 * (hi - lo).max()), zoom=1.25)
    # a flat fabric's z axis is a few pixels tall at true aspect: one tick there (its
    # thickness is read in the side views), both ends where it has room
    z = [lo[2], hi[2]] if hi[2] - lo[2] > 0.1 * (hi - lo)[:2].max() else [0.5 * (lo[2] + hi[2])]
    step = 10.0 ** np.floor(np.log10(hi[2] - lo[2]))
    ax.set_zticks(np.unique(np.round(np.array(z) / step) * step) + 0.0)
    ax.zaxis.set_major_formatter(FormatStrFormatter("%.3g"))
    ax.computed_zorder = False                 # the crossings' markers stay on top
    ax.view_init(ELEVATION, AZIMUTH)
    for axis, name in zip((ax.set_xlabel, ax.set_ylabel, ax.set_zlabel), "xyz"):
        axis(f"{name} [{unit}]", fontsize=8)
    ax.tick_params(labelsize=7)


def _fmt(value: float) -> str:
    return f"{value:.4g}"


def window(count: int, size: int) -> range:
    """At most ``size`` consecutive indices about the middle of ``count``."""
    start = max(0, (count - size) // 2)
    return range(start, min(count, start + size))


def _near(crossings: np.ndarray, pieces: list[np.ndarray], radius: float) -> np.ndarray:
    """The crossings inside the bounding box (grown by r) of the drawn pieces."""
    pts = np.concatenate([p.reshape(-1, 3) for p in pieces])
    lo, hi = pts.min(axis=0) - radius, pts.max(axis=0) + radius
    return crossings[np.all((crossings >= lo) & (crossings <= hi), axis=1)]


def _span(r: range, name: str) -> str:
    return f"{name} {r.start + 1}" if len(r) == 1 else f"{name}s {r.start + 1}-{r.stop}"


def plot_tubes(path: Path, centrelines: np.ndarray, radius: float,
               crossings: np.ndarray | None = None, unit: str = "mm", title: str = "") -> Path:
    """PNG at ``path`` of the yarn as tubes of radius ``radius`` about ``centrelines``
    (m, n, S, 3), in the length unit ``unit``: an oblique view of (at most OBLIQUE_LOOPS x
    OBLIQUE_LOOPS loops in the middle of) the fabric and two side views of true aspect of
    SIDE_LOOPS loops in its middle (the module's docstring), courses told apart by colour,
    ``crossings`` (k, 3) marked where they fall in a view. Returns ``path``."""
    c = check_centrelines(centrelines, radius)
    x = np.empty((0, 3)) if crossings is None else np.asarray(crossings, dtype=float).reshape(-1, 3)
    m, n, _, _ = c.shape
    colours = course_colours(m)
    rows, cols = window(m, OBLIQUE_LOOPS), window(n, OBLIQUE_LOOPS)
    shown, step = thinned(c[rows.start:rows.stop, cols.start:cols.stop])
    fig = new_figure(figsize=(8.0, 8.5), dpi=DPI, layout="constrained")
    grid = fig.add_gridspec(3, 1, height_ratios=(2.8, 1.0, 1.0))
    # the side views first: the legend takes its swatch of the yarn from the first axes
    yarn = f"yarn: a tube of radius {_fmt(radius)} {unit}, coloured by course (side views: " \
        "its exact outline, far parts drawn first)"
    mark = f"interlock contact: where two courses' yarns press ({len(x)} in all)"
    _side_views(fig, grid, c, x, radius, colours, unit, yarn, mark)
    ax3 = fig.add_subplot(grid[0], projection="3d")
    _oblique(ax3, shown, rows, radius, colours, unit, yarn)
    whole = len(rows) == m and len(cols) == n
    ax3.set_title("oblique view" + ("" if whole else f" of {_span(rows, 'course')}, "
                                    f"{_span(cols, 'wale')}")
                  + ("" if step == 1 else f" (1 sample in {step} of each loop)"), fontsize=9)
    near = _near(x, [shown], radius)
    if len(near):
        ax3.plot(near[:, 0], near[:, 1], near[:, 2], "o", ms=4, mfc="none", mec=CROSSING,
                 mew=1.0, label=mark, zorder=5)
    _course_key(fig, ax3, m)
    fig.suptitle((title + ": " if title else "") + f"yarn as a tube of radius {_fmt(radius)} "
                 f"{unit}, {m} x {n} loops", fontsize=10)
    legend_below(fig, max_columns=1)
    return save_figure(fig, path, dpi=DPI)


def _side_views(fig, grid, c: np.ndarray, x: np.ndarray, radius: float, colours: np.ndarray,
                unit: str, yarn: str, mark: str) -> None:
    """The two side views (rows 1 and 2 of ``grid``): the middle wale's loops in SIDE_LOOPS
    courses looking along -x, and the middle two courses over SIDE_LOOPS wales looking
    along +y, with the crossings that fall in each."""
    m, n = c.shape[:2]
    j, band, pair = n // 2, window(m, SIDE_LOOPS), window(m, 2)
    wales = window(n, SIDE_LOOPS)
    views = (([(c[k, j], k) for k in band], (1, 2), 0, 1.0,
              f"side view looking along -x: wale {j + 1}, {_span(band, 'course')}"),
             ([(course_path(c[k, wales.start:wales.stop])[0], k) for k in pair], (0, 2), 1, -1.0,
              f"side view looking along +y: {_span(pair, 'course')}, {_span(wales, 'wale')}"))
    for row, (pieces, ij, depth, toward, name) in enumerate(views, start=1):
        ax = fig.add_subplot(grid[row])
        _side_view(ax, pieces, radius, ij, depth, toward, colours, yarn)
        near = _near(x, [p for p, _ in pieces], radius)
        if len(near):
            ax.plot(near[:, ij[0]], near[:, ij[1]], "o", ms=5, mfc="none", mec=CROSSING,
                    mew=1.2, zorder=5, label=mark)
        ax.set_xlabel(f"{'xyz'[ij[0]]} [{unit}]")
        ax.set_ylabel(f"z [{unit}]")
        ax.set_title(name + " (true aspect)", fontsize=9)
        ax.tick_params(labelsize=7)


def _course_key(fig, axes, m: int) -> None:
    """A colourbar of the course colours (integer ticks, :func:`plot.course_ticks`)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import BoundaryNorm, ListedColormap
    mappable = ScalarMappable(BoundaryNorm(np.arange(0.5, m + 1), m),
                              ListedColormap(course_colours(m)))
    bar = fig.colorbar(mappable, ax=axes, label="course (yarn colour)", shrink=0.7, pad=0.1)
    bar.set_ticks(course_ticks(m))
