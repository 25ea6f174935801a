"""Checking written pictures by content: where their coloured pixels are, in data coordinates.

``SavedFigures`` (the ``saved_figures`` fixture) records, for every figure the code under test
saves, each axes' data-to-pixel transform at the saved resolution, the axes' and legend's pixel
boxes; the test then reads the PNG back (matplotlib.image.imread) and compares the pixels of a
colour class with curves computed independently from the result files. It also records what
a reader needs to understand the picture (``Readability``: every text's box, every axis label,
what each drawn artist is explained by, the view limits); ``check_explained`` asserts that
every picture explains itself: axis labels with units, every marker in a legend, a colourbar
or a caption, every text inside the image, nothing drawn outside the view.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
from matplotlib.collections import Collection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.quiver import QuiverKey
from matplotlib.text import Text
from scipy.integrate import cumulative_trapezoid
from scipy.ndimage import binary_dilation
from scipy.spatial import cKDTree


@dataclass
class SavedAxes:
    transform: np.ndarray          # 3 x 3 affine: data -> display pixels (origin bottom left)
    box: np.ndarray                # [x0, y0, x1, y1] display pixels
    legend: np.ndarray | None      # the legend's box, if any


@dataclass
class ReadAxes:
    """What a reader sees of one axes: its labels, view and the artists it draws."""

    xlabel: str
    ylabel: str
    title: str
    data: bool                                  # an axes with its axis on (not a colourbar)
    xlim: tuple[float, float]
    ylim: tuple[float, float]
    labels: list[str]                           # the label of every drawn artist
    unexplained: list[str]                      # drawn artists no legend/colourbar/caption names
    outside: list[str]                          # drawn artists reaching outside the view


@dataclass
class Readability:
    """Everything ``check_explained`` needs of one saved figure (recorded at save time)."""

    size: tuple[float, float]                   # pixels
    texts: list[tuple[str, np.ndarray]]         # (text, [x0, y0, x1, y1] pixels)
    axes: list[ReadAxes] = field(default_factory=list)
    legend: list[str] = field(default_factory=list)

    @property
    def all_text(self) -> str:
        return "\n".join(t for t, _ in self.texts)


def _drawn(ax) -> list:
    """The artists an axes draws that need explaining: lines, collections and patches (not
    images, texts, or the background)."""
    out = [a for a in ax.lines if len(np.atleast_1d(a.get_xdata())) > 0]
    out += list(ax.collections) + [a for a in ax.patches if a is not ax.patch]
    return [a for a in out if a.get_visible()]


def _outside(artist, ax) -> bool:
    """Whether a line or collection reaches outside the axes' view (patches are clipped on
    purpose and not checked)."""
    (x0, x1), (y0, y1) = sorted(ax.get_xlim()), sorted(ax.get_ylim())
    tol = 1e-6 * max(x1 - x0, y1 - y0)
    if isinstance(artist, Line2D):
        xy = np.column_stack([np.asarray(artist.get_xdata(), float),
                              np.asarray(artist.get_ydata(), float)])
    elif isinstance(artist, Collection) and artist.get_transform() == ax.transData:
        box = artist.get_datalim(ax.transData)
        if not np.isfinite(box.extents).all() or box.width == box.height == 0 and not len(artist.get_paths()):
            return False
        xy = box.get_points()
    else:
        return False
    xy = xy[np.isfinite(xy).all(axis=1)]
    return bool(len(xy)) and bool(np.any((xy[:, 0] < x0 - tol) | (xy[:, 0] > x1 + tol)
                                         | (xy[:, 1] < y0 - tol) | (xy[:, 1] > y1 + tol)))


def read_figure(fig: Figure, renderer) -> Readability:
    """The readability record of a drawn figure."""
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    legend = [t.get_text() for lg in legends for t in lg.get_texts()]
    texts: list[Text] = list(fig.texts) + [t for lg in legends for t in lg.get_texts()]
    if fig._suptitle is not None and fig._suptitle not in texts:
        texts.append(fig._suptitle)
    for ax in fig.axes:
        texts += [ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label]
        texts += list(ax.texts)
        texts += [a.text for a in ax.get_children() if isinstance(a, QuiverKey)]
    shown = [(t.get_text(), np.array(t.get_window_extent(renderer).extents))
             for t in texts if t.get_visible() and t.get_text().strip()]
    captions = [t for t, _ in shown]
    mappables = {id(ax._colorbar.mappable) for ax in fig.axes if hasattr(ax, "_colorbar")}
    rec = Readability((fig.bbox.width, fig.bbox.height), shown, legend=legend)
    for ax in fig.axes:
        if hasattr(ax, "_colorbar"):
            continue
        drawn = _drawn(ax)
        labels = [a.get_label() for a in drawn]
        unexplained = [f"{type(a).__name__} {lab!r}" for a, lab in zip(drawn, labels)
                       if id(a) not in mappables and not (
                           lab and not lab.startswith("_")
                           and (lab in legend or any(lab in c for c in captions)))]
        outside = [f"{type(a).__name__} {a.get_label()!r}" for a in drawn if _outside(a, ax)]
        rec.axes.append(ReadAxes(ax.get_xlabel(), ax.get_ylabel(), ax.get_title(), ax.axison,
                                 ax.get_xlim(), ax.get_ylim(), labels, unexplained, outside))
    return rec


UNIT = re.compile(r"\[[^\]]+\]")


def check_explained(rec: Readability, dimensionless: tuple[str, ...] = ()) -> Readability:
    """A picture explains itself: every text lies inside the image (a title that does not fit
    is clipped) and none is drawn over another, every axis with its axis on has x and y labels with a unit in brackets (or is
    named in ``dimensionless``, e.g. "wale"), every drawn line, collection and patch is named
    by a legend entry, a colourbar or a caption, and no line or collection reaches outside the
    view (nothing cropped silently)."""
    w, h = rec.size
    clipped = [t for t, box in rec.texts
               if box[0] < -1 or box[1] < -1 or box[2] > w + 1 or box[3] > h + 1]
    assert not clipped, f"texts outside the {w:.0f} x {h:.0f} px image: {clipped}"
    overlaps = [(a, b) for i, (a, p) in enumerate(rec.texts) for b, q in rec.texts[i + 1:]
                if min(p[2], q[2]) - max(p[0], q[0]) > 1 and min(p[3], q[3]) - max(p[1], q[1]) > 1]
    assert not overlaps, f"texts drawn over each other: {overlaps}"
    for ax in rec.axes:
        if ax.data:
            for label in (ax.xlabel, ax.ylabel):
                assert UNIT.search(label) or label in dimensionless, \
                    f"axis label without a unit: {label!r} (axes {ax.title!r})"
        assert not ax.unexplained, f"not in a legend, colourbar or caption: {ax.unexplained}"
        assert not ax.outside, f"drawn outside the view: {ax.outside} (axes {ax.title!r})"
    return rec


class SavedFigures:
    """Figures saved while the fixture is active, by file name (figures saved to a buffer,
    e.g. GIF frames, in ``frames``)."""

    def __init__(self) -> None:
        self.axes: dict[str, list[SavedAxes]] = {}
        self.read: dict[str, Readability] = {}
        self.frames: list[Readability] = []

    def explained(self, name: str, dimensionless: tuple[str, ...] = ()) -> Readability:
        """``check_explained`` of the figure saved as ``name``."""
        return check_explained(self.read[name], dimensionless)

    def install(self, monkeypatch) -> None:
        original = Figure.savefig

        def savefig(fig: Figure, fname, *args, **kwargs):
            name = _saved_name(fname)
            if name is None:                                # a buffer (the SVG text, GIF frames)
                out = original(fig, fname, *args, **kwargs)
                self.frames.append(read_figure(fig, fig.canvas.get_renderer()))
                return out
            dpi = kwargs.get("dpi") or fig.dpi
            old = fig.dpi
            fig.set_dpi(dpi)
            renderer = fig.canvas.get_renderer()
            fig.canvas.draw()
            self.axes[name] = [
                SavedAxes(ax.transData.get_matrix().copy(), np.array(ax.bbox.extents),
                          None if ax.get_legend() is None else
                          np.array(ax.get_legend().get_window_extent(renderer).extents))
                for ax in fig.axes if ax.get_label() != "<colorbar>"]
            self.read[name] = read_figure(fig, renderer)
            fig.set_dpi(old)
            return original(fig, fname, *args, **kwargs)
        monkeypatch.setattr(Figure, "savefig", savefig)


def _saved_name(fname) -> str | None:
    """The file name a figure is saved under: a path's, or for an open file the name it will
    be renamed to (knit_nlp.atomic writes ``.<name>.<random><suffix>`` beside it first)."""
    if isinstance(fname, (str, Path)):
        return Path(fname).name
    raw = getattr(fname, "name", None)
    if not isinstance(raw, (str, Path)):
        return None
    tmp = Path(raw)
    if not tmp.name.startswith("."):
        return tmp.name
    return tmp.name[1:-len(tmp.suffix) or None].rsplit(".", 1)[0]


def read_rgb(path: Path) -> np.ndarray:
    """The PNG as floats (rows top to bottom, RGB in [0, 1])."""
    return mpimg.imread(path)[..., :3].astype(float)


def to_pixels(ax: SavedAxes, pts: np.ndarray, height: int) -> np.ndarray:
    """Data points (k, 2) -> image (column, row) coordinates (rows from the top)."""
    xy = pts @ ax.transform[:2, :2].T + ax.transform[:2, 2]
    return np.column_stack([xy[:, 0], height - xy[:, 1]])


def pixels_in_axes(ax: SavedAxes, mask: np.ndarray, border: float = 3.0) -> np.ndarray:
    """(column, row) of the masked pixels inside the axes box and outside its legend."""
    h = mask.shape[0]
    rows, cols = np.nonzero(mask)
    x, y = cols + 0.5, h - (rows + 0.5)
    x0, y0, x1, y1 = ax.box
    keep = (x > x0 + border) & (x < x1 - border) & (y > y0 + border) & (y < y1 - border)
    if ax.legend is not None:
        lx0, ly0, lx1, ly1 = ax.legend
        keep &= ~((x > lx0 - border) & (x < lx1 + border) & (y > ly0 - border) & (y < ly1 + border))
    return np.column_stack([cols[keep] + 0.5, rows[keep] + 0.5])


def _outside_legend(ax: SavedAxes, px: np.ndarray, height: int) -> np.ndarray:
    if ax.legend is None:
        return np.ones(len(px), dtype=bool)
    x, y = px[:, 0], height - px[:, 1]
    lx0, ly0, lx1, ly1 = ax.legend
    return ~((x > lx0) & (x < lx1) & (y > ly0) & (y < ly1))


def distance_to(curve_px: np.ndarray, px: np.ndarray) -> np.ndarray:
    """Distance (pixels) from each pixel centre to the nearest of the densely sampled curve."""
    return cKDTree(curve_px).query(px)[0]


def polyline_points(lines: np.ndarray, per_segment: int = 16) -> np.ndarray:
    """Dense points along polylines (..., S, 2), as drawn (straight segments)."""
    a, b = lines[..., :-1, :], lines[..., 1:, :]
    u = np.linspace(0.0, 1.0, per_segment, endpoint=False)[:, None]
    inner = (a[..., None, :] + u * (b - a)[..., None, :]).reshape(-1, 2)
    return np.concatenate([inner, lines[..., -1, :].reshape(-1, 2)])


def saturated(rgb: np.ndarray, chroma: float = 0.12) -> np.ndarray:
    """Colourful pixels (max − min channel above ``chroma``)."""
    return rgb.max(axis=-1) - rgb.min(axis=-1) > chroma


def reddish(rgb: np.ndarray) -> np.ndarray:
    """Red dominates (crimson markers and arrows, and their antialiased edges)."""
    return (rgb[..., 0] >= rgb[..., 1]) & (rgb[..., 0] >= rgb[..., 2])


def near(rgb: np.ndarray, colour: str, tol: float = 0.06) -> np.ndarray:
    """Pixels within ``tol`` (each channel) of a '#rrggbb' colour."""
    c = np.array([int(colour[k:k + 2], 16) / 255 for k in (1, 3, 5)])
    return np.all(np.abs(rgb - c) < tol, axis=-1)


def weft_centrelines(coefficients: np.ndarray, course_starts: np.ndarray, L: float,
                     samples: int = 1500) -> np.ndarray:
    """Dense course polylines (m, n·samples, 2) from a result JSON's loops, by the trapezoid
    rule on θ(s) = a·φ(s), φ = [sin(2πks/L), k = 1..t; cos(2πks/L), k = 1..t; s; 1] (eqs. 1,
    14-16), independent of the package's quadrature."""
    m, n, nc = coefficients.shape
    t = (nc - 2) // 2
    s = np.linspace(0.0, L, samples)
    k = np.arange(1, t + 1)[:, None]
    basis = np.vstack([np.sin(2 * np.pi * k * s / L), np.cos(2 * np.pi * k * s / L), s, np.ones_like(s)])
    out = np.zeros((m, n * samples, 2))
    for i in range(m):
        start = np.asarray(course_starts[i], dtype=float)
        for j in range(n):
            theta = coefficients[i, j] @ basis
            xy = np.column_stack([cumulative_trapezoid(np.cos(theta), s, initial=0.0),
                                  cumulative_trapezoid(np.sin(theta), s, initial=0.0)])
            out[i, j * samples:(j + 1) * samples] = start + xy
            start = start + xy[-1]
    return out


def check_weft_picture(path: Path, result: dict, L: float, natural: np.ndarray,
                       figs: SavedFigures) -> dict[str, float]:
    """The solution picture (weft/plot.py) shows the result where the result says it is:

    - every coloured (viridis) pixel in the axes (but for 12 px around the clamps and 3 px
      around the red reaction arrows, drawn over the yarn) lies within 4 px of a deformed
      centreline (1.8 pt lines of 61-point polylines)
      computed from the JSON's coefficients and course starts, and the centrelines are drawn
      (a coloured pixel within 2 px of 97 % of their samples outside the legend and the
      clamp squares);
    - every light grey pixel lies within 3 px of a natural centreline (``natural``: the NPZ's
      sampled loops (m, n, S, 2), drawn as polylines) or of a deformed one (antialiased edges);
    - a crimson marker sits on every clamp's reported position.
    Returns the measured fractions (for messages)."""
    rgb = read_rgb(path)
    (ax,) = figs.axes[path.name]
    h = rgb.shape[0]
    loops = result["loops"]
    deformed = weft_centrelines(np.asarray(loops["coefficients"]), np.asarray(loops["course_starts"]), L)
    curve = to_pixels(ax, deformed.reshape(-1, 2), h)
    nat = to_pixels(ax, polyline_points(natural), h)
    red = saturated(rgb, 0.3) & reddish(rgb)
    near_red = binary_dilation(red, iterations=3)       # arrows drawn over the yarn, blended
    colour = saturated(rgb) & ~reddish(rgb) & ~near_red
    px = pixels_in_axes(ax, colour)
    held = to_pixels(ax, np.array([c["position"] for c in result["clamps"]]), h)
    visible = curve[::7][_outside_legend(ax, curve[::7], h)]
    if len(held):       # clamp squares and target crosses are drawn over the yarn
        visible = visible[distance_to(held, visible) > 12.0]
        px = px[distance_to(held, px) > 12.0]
    off = float(np.mean(distance_to(curve, px) > 4.0))
    covered = float(np.mean(distance_to(px, visible) < 2.0))
    grey_px = pixels_in_axes(ax, ~saturated(rgb, 0.04) & (rgb.mean(axis=-1) > 0.6)
                             & (rgb.mean(axis=-1) < 0.85))
    grey_off = float(np.mean(np.minimum(distance_to(nat, grey_px), distance_to(curve, grey_px)) > 3.0))
    red_px = pixels_in_axes(ax, saturated(rgb, 0.3) & reddish(rgb), border=0.0)
    red_gap = float(np.max(distance_to(red_px, held))) if len(held) else 0.0
    stats = {"coloured_off_curve": off, "curve_covered": covered, "grey_off_natural": grey_off,
             "clamp_marker_gap_px": red_gap, "coloured_pixels": len(px), "grey_pixels": len(grey_px)}
    assert len(px) > 500 and len(grey_px) > 200, stats
    assert off < 0.002 and covered > 0.97 and grey_off < 0.01 and red_gap < 2.0, stats
    return stats


def check_overlay_picture(path: Path, full: dict, reduced: dict, L: float,
                          figs: SavedFigures) -> dict[str, float]:
    """The compare picture (weft/plot.py ``plot_overlay``): black pixels lie on the full
    model's centrelines, colourful (plasma) pixels on the reduced model's, each computed from
    that model's result JSON; both are drawn (95 % of their samples have a pixel of their
    colour within 2 px, where the other model's curve does not cover them)."""
    rgb = read_rgb(path)
    ax = figs.axes[path.name][0]
    h = rgb.shape[0]
    curves = {}
    for key, res in (("full", full), ("reduced", reduced)):
        loops = res["loops"]
        lines = weft_centrelines(np.asarray(loops["coefficients"]), np.asarray(loops["course_starts"]), L)
        curves[key] = to_pixels(ax, lines.reshape(-1, 2), h)
    black = pixels_in_axes(ax, ~saturated(rgb, 0.08) & (rgb.mean(axis=-1) < 0.3))
    colour = pixels_in_axes(ax, saturated(rgb, 0.25))
    stats = {"black_off_full": float(np.mean(distance_to(curves["full"], black) > 3.0)),
             "colour_off_reduced": float(np.mean(distance_to(curves["reduced"], colour) > 3.0))}
    for key, px, other in (("full", black, "reduced"), ("reduced", colour, "full")):
        samples = curves[key][::7]
        samples = samples[distance_to(curves[other], samples) > 4.0]
        stats[f"{key}_covered"] = float(np.mean(distance_to(px, samples) < 2.0))
    assert len(black) > 300 and len(colour) > 300, stats
    assert stats["black_off_full"] < 0.002 and stats["colour_off_reduced"] < 0.002, stats
    assert stats["full_covered"] > 0.95 and stats["reduced_covered"] > 0.95, stats
    return stats


def catmull_rom_closed(ctrl: np.ndarray, samples: int = 24) -> np.ndarray:
    """Points on closed uniform Catmull-Rom splines through ``ctrl`` (n, K, 2): on each segment
    p1 -> p2, ½[2p1 + (−p0 + p2)u + (2p0 − 5p1 + 4p2 − p3)u² + (−p0 + 3p1 − 3p2 + p3)u³]."""
    k = ctrl.shape[1]
    u = np.linspace(0.0, 1.0, samples, endpoint=False)[:, None]
    out = []
    for seg in range(k):
        p0, p1, p2, p3 = (ctrl[:, (seg + d) % k][:, None] for d in (-1, 0, 1, 2))
        out.append(0.5 * (2 * p1 + (p2 - p0) * u + (2 * p0 - 5 * p1 + 4 * p2 - p3) * u ** 2
                          + (3 * p1 - p0 - 3 * p2 + p3) * u ** 3))
    return np.concatenate(out, axis=1)


def jacquard_pillar_loops(final: np.ndarray, data: dict, nw: int, nc: int) -> np.ndarray:
    """Control points (nw·nc, 6, 2) of the drawn pillar loops (wales 0..nw-1, courses
    0..nc-1, tiled across periodic repeats), from the result JSON's particle positions: the
    loop of P(i, j) spans P(i, j) -> P(i, j+1) (the next repeat's, N·h higher, across a
    periodic seam; straight up by h at a fixed top), its lateral unit ⟂ to that scaled by w
    (docs/jacquard.md, "Rendering")."""
    from knit_nlp.jacquard.render import PILLAR
    M, N, w, h = data["wales"], data["courses"], data["w_mm"], data["h_mm"]
    x = np.asarray(final).reshape(N, M, 2)
    jj, ii = np.meshgrid(np.arange(nc), np.arange(nw), indexing="ij")
    i, j = ii.ravel(), jj.ravel()

    def root(i: np.ndarray, j: np.ndarray) -> np.ndarray:
        return x[j % N, i % M] + np.column_stack([(i - i % M) * w, (j - j % N) * h])
    r = root(i, j)
    top = root(i, j + 1)
    if data["boundary"] == "fixed":
        top = np.where(((j % N) == N - 1)[:, None], r + [0.0, h], top)
    axis = top - r
    lateral = np.column_stack([axis[:, 1], -axis[:, 0]]) / np.hypot(*axis.T)[:, None] * w
    return r[:, None] + PILLAR[None, :, 1:2] * axis[:, None] + PILLAR[None, :, 0:1] * lateral[:, None]


def check_jacquard_picture(path: Path, data: dict, figs: SavedFigures) -> dict[str, float]:
    """The jacquard picture (jacquard/render.py: design grids, then the natural and the
    simulated fabric): in each fabric panel the pillar-loop pixels (the ground yarn's colour)
    lie on the loops built from the JSON's ``natural`` and ``final`` particle positions
    (within 2.5 px), and 60 % of each panel's loop curves carry such pixels within 2 px (the
    rest is under the front bar's underlaps and the back bar's, drawn on top; measured 73-80 %
    on tests/test_jacquard_cli.py's tiny problem)."""
    from knit_nlp.jacquard.render import COLOURS, MAX_LOOPS
    rgb = read_rgb(path)
    h_px = rgb.shape[0]
    M, N = data["wales"], data["courses"]

    def drawn(k: int) -> int:          # repeats tiled when periodic (up to MAX_LOOPS loops)
        return min(MAX_LOOPS, k * (1 if data["boundary"] == "fixed" else min(3, max(1, MAX_LOOPS // k))))
    ground = near(rgb, COLOURS["ground"], 0.03)
    stats = {}
    for ax, key in zip(figs.axes[path.name][-2:], ("natural", "final")):
        ctrl = jacquard_pillar_loops(np.asarray(data["particles"][key]), data, drawn(M), drawn(N))
        curve = to_pixels(ax, catmull_rom_closed(ctrl).reshape(-1, 2), h_px)
        px = pixels_in_axes(ax, ground)
        stats[f"{key}_off"] = float(np.mean(distance_to(curve, px) > 2.5))
        stats[f"{key}_covered"] = float(np.mean(distance_to(px, curve[::3]) < 2.0))
        stats[f"{key}_pixels"] = len(px)
    assert stats["natural_pixels"] > 500 and stats["final_pixels"] > 500, stats
    for key in ("natural", "final"):
        assert stats[f"{key}_off"] < 0.002 and stats[f"{key}_covered"] > 0.6, stats
    return stats


def check_line_plot(path: Path, figs: SavedFigures, axes: int,
                    series: dict[str, list[np.ndarray]]) -> dict[str, float]:
    """A line plot shows its data: for each colour ('#rrggbb') the pixels of that colour in
    axes number ``axes`` (outside the legend) lie within 4.5 px of one of its polylines (data
    points (k, 2), drawn with markers), and 70 % of its first (solid) polyline carries such
    pixels within 2 px (other series may cross it; later ones may be dotted)."""
    rgb = read_rgb(path)
    ax = figs.axes[path.name][axes]
    h = rgb.shape[0]
    stats = {}
    for colour, lines in series.items():
        curve = to_pixels(ax, np.concatenate([polyline_points(np.asarray(ln, dtype=float), 64)
                                              for ln in lines]), h)
        px = pixels_in_axes(ax, near(rgb, colour, 0.04))
        solid = to_pixels(ax, polyline_points(np.asarray(lines[0], dtype=float), 64), h)
        visible = solid[_outside_legend(ax, solid, h)]
        stats[colour] = (float(np.mean(distance_to(curve, px) > 4.5)),
                         float(np.mean(distance_to(px, visible) < 2.0)), len(px))
        off, covered, count = stats[colour]
        assert count > 50 and off < 0.002 and covered > 0.7, stats
    return stats
