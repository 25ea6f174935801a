"""Pictures of the fabric (docs/jacquard.md, "Rendering"; paper Fig. 2 stitch models).

One figure: the two design grids (fall-plate, the front, over inlay, the back) beside the natural
and the simulated fabric. In the fabric panels each pillar loop is a closed smooth yarn through
6 points (P1-P6), each inlay underlap a smooth yarn through 4 points and each fall-plate underlap
a 2-point yarn, all placed in the frame of the displaced particles: the loop of P(i,j) spans
P(i,j) -> P(i,j+1), its lateral unit is perpendicular to that, scaled by the wale spacing w.
So that the motif reads as it does on a real fabric's face, a bar's underlaps are drawn as wide
as their structure (thick wide, thin narrow, net not at all: a net cell's jacquard yarn stays
in its own wale, hidden by the pillar loop) and each cell is tinted by its front (fall-plate)
structure. Periodic repeats are tiled; a fixed patch is drawn once. A key under the fabric
panels names each of these; the simulated panel also draws each particle's displacement as an
arrow from its natural place, magnified by a round factor (named in the key) so that a stretch
of a fraction of a millimetre can be seen.

Curves are cubic Bezier paths (the exact form of a uniform Catmull-Rom spline), one compound
path per bar and structure, so the SVG holds a few dozen path elements instead of one per yarn.
"""
from __future__ import annotations

import io
import re
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import matplotlib
import numpy as np
from matplotlib.patches import Patch, PathPatch
from matplotlib.path import Path as MplPath

from ..atomic import write_text
from ..figures import new_figure, save_figure
from .problem import JacquardProblem, JacquardSystem
from .springs import Network, zigzag_direction

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


class Solved(Protocol):
    """What the picture reads of a solution (``JacquardResult`` has it)."""

    problem: JacquardProblem
    network: Network
    positions: np.ndarray
    solver: str

# Local stitch points (u in units of w to the right, v in units of the loop's height).
PILLAR = np.array([[0.06, 0.0], [-0.22, 0.30], [-0.20, 0.95], [0.20, 0.95], [0.22, 0.30],
                   [-0.06, 0.0]])                      # 6-point pillar loop, closed
INLAY_END = np.array([[0.0, 0.167], [0.0, 0.40]])     # 4-point inlay: start, pull-out ...
FALL_PLATE_V = 0.5                                     # 2-point fall-plate underlap height
CELL = np.array([[-0.5, 0.0], [0.5, 0.0], [0.5, 1.0], [-0.5, 1.0]])   # a cell, loop frame
COLOURS = {"ground": "#8c8577", "fall_plate": "#b0281a", "inlay": "#8fb3dd"}
OUTLINE = {"fall_plate": "#4a0d06", "inlay": None}     # the back bar: pale, no outline
BACKGROUND = "#fbf8f1"
# Yarn widths in units of w: thick underlaps wide, thin narrow, net not drawn (docs/jacquard.md);
# the inlay (back bar, mostly hidden behind the face) at INLAY_SCALE of these.
WIDTH = {"ground": 0.05, "thick": 0.16, "thin": 0.07}
INLAY_SCALE = 0.5
# Tint of a cell by its fall-plate structure (alpha of the fall-plate colour); net untinted.
TINT = {"thick": 0.75, "thin": 0.25}
DESIGN_GREYS = {0: "#ffffff", 1: "#a6a6a6", 2: "#1a1a1a"}      # net, thin, thick (as in PNGs)
STRUCTURE_CODES = {"thick": 2, "thin": 1}
MAX_LOOPS = 24    # a periodic design is tiled (up to 3 repeats) to about this many loops
DRAW_LIMIT = 120  # the whole fabric is drawn up to this many wales / courses (a window of this
#                   size beyond, labelled as such; ``window`` asks for a smaller one)


def bezier_path(ctrl: np.ndarray, closed: bool) -> MplPath:
    """One compound path of uniform Catmull-Rom splines through ``ctrl`` (n curves, K points),
    each segment p1 -> p2 written exactly as the cubic Bezier with control points
    p1 + (p2 - p0)/6 and p2 - (p3 - p1)/6 (ends of open curves mirrored)."""
    if closed:
        pts = np.concatenate([ctrl[:, -1:], ctrl, ctrl[:, :2]], axis=1)
    else:
        pts = np.concatenate([2 * ctrl[:, :1] - ctrl[:, 1:2], ctrl,
                              2 * ctrl[:, -1:] - ctrl[:, -2:-1]], axis=1)
    p0, p1, p2, p3 = (pts[:, k:k + pts.shape[1] - 3] for k in range(4))
    c1, c2 = p1 + (p2 - p0) / 6.0, p2 - (p3 - p1) / 6.0
    n, segs = p1.shape[:2]
    verts = np.concatenate([p1[:, :1], np.stack([c1, c2, p2], axis=2).reshape(n, 3 * segs, 2)],
                           axis=1)
    codes = np.full(verts.shape[1], MplPath.CURVE4, dtype=MplPath.code_type)
    codes[0] = MplPath.MOVETO
    return MplPath(verts.reshape(-1, 2), np.tile(codes, n))


def polygon_path(corners: np.ndarray) -> MplPath:
    """One compound path of closed polygons ``corners`` (n, K, 2)."""
    n, k = corners.shape[:2]
    codes = np.full(k + 1, MplPath.LINETO, dtype=MplPath.code_type)
    codes[0], codes[-1] = MplPath.MOVETO, MplPath.CLOSEPOLY
    verts = np.concatenate([corners, corners[:, :1]], axis=1)
    return MplPath(verts.reshape(-1, 2), np.tile(codes, n))


class _Tiling:
    """Positions of the drawn loops: repeats tiled (periodic) or the patch once (fixed), and
    the frame of each loop."""

    def __init__(self, p: JacquardProblem, x: np.ndarray, window: int | None = None) -> None:
        """The whole patch (fixed) or whole repeats, tiled up to 3 times while under MAX_LOOPS
        (periodic); at most ``window`` (default DRAW_LIMIT) loops each way from the corner."""
        self.p = p
        m, n = p.wales, p.courses
        tiles = (lambda k: 1) if p.boundary == "fixed" else (lambda k: min(3, max(1, MAX_LOOPS // k)))
        cap = DRAW_LIMIT if window is None else window
        self.nw = min(cap, m * tiles(m))
        self.nc = min(cap, n * tiles(n))
        self.window = self.nw < m or self.nc < n
        self.x = x.reshape(n, m, 2)

    def root(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Position of P(i,j) for unwrapped (tiled) indices."""
        p = self.p
        im, jm = np.mod(i, p.wales), np.mod(j, p.courses)
        base = self.x[jm, im]
        shift = np.stack([(i - im) * p.w, (j - jm) * p.h], axis=-1)
        return base + shift

    def frame(self, i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Root, loop axis (root -> next root) and lateral unit * w of loop (i, j)."""
        r = self.root(i, j)
        if self.p.boundary == "fixed":
            top = np.where(((j % self.p.courses) == self.p.courses - 1)[..., None],
                           r + np.array([0.0, self.p.h]), self.root(i, j + 1))
        else:
            top = self.root(i, j + 1)
        axis = top - r
        length = np.maximum(np.hypot(axis[..., 0], axis[..., 1]), 1e-12)[..., None]
        lateral = np.stack([axis[..., 1], -axis[..., 0]], axis=-1) / length * self.p.w
        return r, axis, lateral

    def local(self, i, j, uv: np.ndarray) -> np.ndarray:
        """Points ``uv`` (K, 2) of loop (i, j) in the plane: shape (n, K, 2)."""
        r, axis, lat = self.frame(i, j)
        return (r[:, None] + uv[None, :, 1:2] * axis[:, None] + uv[None, :, 0:1] * lat[:, None])

    def codes(self, sys: JacquardSystem, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        return sys.codes[np.mod(j, self.p.courses), np.mod(i, self.p.wales)]


def _add(ax: "Axes", patch: PathPatch) -> None:
    """Add a patch inside the panel's fixed limits: not ``add_patch``, which would find the
    extrema of every Bezier segment to update the data limits (4 s of a 7 s picture), and
    left out of the layout, which would measure it again."""
    patch.set_in_layout(False)
    patch.set_clip_path(ax.patch)
    ax.add_artist(patch)


def _stroke(ax: "Axes", path: MplPath, colour: str, width_pts: float,
            outline: str | None = None) -> None:
    """A yarn: one compound path, optionally over a darker, slightly wider outline."""
    for c, lw in ([(outline, width_pts * 1.3)] if outline else []) + [(colour, width_pts)]:
        _add(ax, PathPatch(path, facecolor="none", edgecolor=c, linewidth=lw,
                           capstyle="round", joinstyle="round"))


def _underlaps(t: _Tiling, sys: JacquardSystem, i, j) -> dict[str, np.ndarray]:
    """Control points of one system's thick and thin underlaps (net cells draw none; a fixed
    patch has none leaving it, as springs.build_springs drops those springs)."""
    p = t.p
    codes, d = t.codes(sys, i, j), zigzag_direction(p, np.mod(j, p.courses))
    out = {}
    for struct, code in STRUCTURE_CODES.items():
        sel = codes == code
        if p.boundary == "fixed":
            far = i + (sys.span[struct] - 1) * d
            sel &= (far >= 0) & (far < p.wales) & (j + 1 < p.courses)
        if not sel.any() or sys.span[struct] == 1:
            continue
        ci, cj, o = i[sel], j[sel], (sys.span[struct] - 1) * d[sel]
        if sys.name == "inlay":
            out[struct] = np.concatenate([t.local(ci, cj, INLAY_END),
                                          t.local(ci + o, cj + 1, INLAY_END[::-1])], axis=1)
        else:
            v = np.array([[0.0, FALL_PLATE_V]])
            out[struct] = np.concatenate([t.local(ci, cj, v), t.local(ci + o, cj + 1, v)], axis=1)
    return out


def draw_fabric(ax: "Axes", p: JacquardProblem, x: np.ndarray, title: str,
                window: int | None = None) -> None:
    """The fabric with particle positions ``x`` ((M*N, 2), row j*M + i): cells tinted by the
    front structure, inlay underlaps (back), pillar loops, fall-plate underlaps (front).
    Positions that are not all finite (a diverged run) are not drawn; the panel says so."""
    if not np.isfinite(x).all():
        ax.set_title(title, fontsize=10)
        ax.text(0.5, 0.5, "not drawn: the positions are not finite", ha="center",
                va="center", transform=ax.transAxes)
        return
    t = _Tiling(p, x, window)
    jj, ii = np.meshgrid(np.arange(t.nc), np.arange(t.nw), indexing="ij")
    i, j = ii.ravel(), jj.ravel()
    cells = t.local(i, j, CELL)
    pad = 0.3 * p.w
    ax.set_xlim(cells[..., 0].min() - pad, cells[..., 0].max() + pad)
    ax.set_ylim(cells[..., 1].min() - pad, cells[..., 1].max() + pad)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_facecolor(BACKGROUND)
    ax.figure.get_layout_engine().execute(ax.figure)     # the layout a draw would make ...
    ax.apply_aspect()                                     # ... without drawing everything
    dpp = ax.transData.transform([(p.w, 0), (0, 0)])
    pts_per_w = abs(dpp[0, 0] - dpp[1, 0]) * 72.0 / ax.figure.dpi
    systems = {s.name: s for s in p.systems}
    front = t.codes(systems["fall_plate"], i, j)
    for struct, code in STRUCTURE_CODES.items():
        if (front == code).any():
            _add(ax, PathPatch(polygon_path(cells[front == code]), linewidth=0,
                               facecolor=COLOURS["fall_plate"], alpha=TINT[struct]))
    layers = {name: _underlaps(t, s, i, j) for name, s in systems.items()}
    for struct, ctrl in layers["inlay"].items():                       # back bar first
        _stroke(ax, bezier_path(ctrl, False), COLOURS["inlay"],
                INLAY_SCALE * WIDTH[struct] * pts_per_w, OUTLINE["inlay"])
    _stroke(ax, bezier_path(t.local(i, j, PILLAR), True), COLOURS["ground"],
            WIDTH["ground"] * pts_per_w)
    for struct, ctrl in layers["fall_plate"].items():                  # front bar on top
        _stroke(ax, MplPath(ctrl.reshape(-1, 2), np.tile([MplPath.MOVETO, MplPath.LINETO],
                                                         ctrl.shape[0])),
                COLOURS["fall_plate"], WIDTH[struct] * pts_per_w, OUTLINE["fall_plate"])


def draw_design(ax: "Axes", sys: JacquardSystem, title: str) -> None:
    """One repeat's design grid: black thick, grey thin, white net; top row = top course."""
    grey = np.array([matplotlib.colors.to_rgb(DESIGN_GREYS[c]) for c in range(3)])
    m, n = sys.codes.shape[1], sys.codes.shape[0]
    ax.imshow(grey[sys.codes], origin="lower", extent=(0.5, m + 0.5, 0.5, n + 0.5),
              interpolation="nearest")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("wale", fontsize=8)
    ax.set_ylabel("course", fontsize=8)
    ax.tick_params(labelsize=7)
    for spine in ax.spines.values():
        spine.set_color("#777777")


def figure(result: Solved, window: int | None = None) -> tuple["Figure", dict[str, "Axes"]]:
    """The picture: design grids | natural fabric | simulated fabric (axes by those names);
    the fabric panels draw at most ``window`` loops each way (default: the whole fabric up to
    DRAW_LIMIT), and their titles say when they show a window."""
    p = result.problem
    t = _Tiling(p, result.network.natural, window)
    aspect = (t.nc * p.h) / (t.nw * p.w)
    height = max(4.0, min(11.0, 5.2 * aspect + 1.2))
    fig = new_figure(figsize=(13, height), dpi=100, layout="constrained")
    grid = fig.add_gridspec(2, 3, width_ratios=[0.55, 1, 1])
    axes = {"fall_plate": fig.add_subplot(grid[0, 0]), "inlay": fig.add_subplot(grid[1, 0]),
            "natural": fig.add_subplot(grid[:, 1]), "simulated": fig.add_subplot(grid[:, 2])}
    systems = {s.name: s for s in p.systems}
    draw_design(axes["fall_plate"], systems["fall_plate"], "fall-plate design (front, red)")
    draw_design(axes["inlay"], systems["inlay"], "inlay design (back, blue)")
    axes["inlay"].legend(handles=[Patch(facecolor=DESIGN_GREYS[c], edgecolor="#777777",
                                        label=s) for s, c in (("thick", 2), ("thin", 1),
                                                              ("net", 0))],
                         loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=3, fontsize=8,
                         frameon=False)
    reps = ("the fixed patch" if p.boundary == "fixed" and t.nw == p.wales and t.nc == p.courses
            else f"{t.nw // p.wales} x {t.nc // p.courses} repeats" if t.nw >= p.wales
            and t.nc >= p.courses else f"{t.nw} x {t.nc} window at the bottom-left corner\nof "
            f"the {p.wales} x {p.courses}" + ("" if window else
                                              f"; whole fabric drawn up to {DRAW_LIMIT}"))
    draw_fabric(axes["natural"], p, result.network.natural, f"{p.name}: natural ({reps})",
                window)
    pulled = "; ".join(f"{q.edge} moved ({q.displacement[0]:g}, {q.displacement[1]:g}) mm"
                       for q in p.pulls)
    draw_fabric(axes["simulated"], p, result.positions,
                f"simulated ({result.solver})" + (f": {pulled}" if pulled else ""), window)
    handles = fabric_key(p)
    if np.isfinite(result.positions).all():
        handles += draw_displacement(axes["simulated"], p, result.network.natural,
                                     result.positions, window)
    fig.legend(handles=handles, loc="outside lower right", ncol=3, fontsize=8, frameon=False)
    return fig, axes


def fabric_key(p: JacquardProblem) -> list:
    """Legend entries for what the fabric panels draw: the pillar loops, each bar's underlaps
    by structure (as wide as drawn relative to each other) and the tinted cells."""
    from matplotlib.lines import Line2D
    used = {s.name: {k for k, c in STRUCTURE_CODES.items() if (s.codes == c).any()}
            for s in p.systems}
    out = [Line2D([], [], color=COLOURS["ground"], lw=1.5, label="pillar loop (ground yarn)")]
    for struct in ("thick", "thin"):
        if struct in used.get("fall_plate", ()):
            out.append(Line2D([], [], color=COLOURS["fall_plate"], lw=12 * WIDTH[struct],
                              label=f"fall-plate underlap, {struct} (front bar)"))
    for struct in ("thick", "thin"):
        if struct in used.get("inlay", ()):
            out.append(Line2D([], [], color=COLOURS["inlay"], lw=12 * INLAY_SCALE * WIDTH[struct],
                              label=f"inlay underlap, {struct} (back bar, under the loops)"))
    for struct in ("thick", "thin"):
        if struct in used.get("fall_plate", ()):
            out.append(Patch(facecolor=COLOURS["fall_plate"], alpha=TINT[struct],
                             label=f"cell with a {struct} front (shaded; net: none)"))
    return out


ARROWS = 16            # at most this many displacement arrows each way
ARROW_COLOUR = "#111111"


def displacement_scale(largest: float, w: float) -> float:
    """The magnification that draws the largest displacement about 1.5 wale spacings long,
    rounded down to 1, 2 or 5 x 10^k (at least 1: nothing is drawn shorter than it is)."""
    if largest <= 0:
        return 1.0
    raw = 1.5 * w / largest
    k = 10.0 ** np.floor(np.log10(raw))
    return float(max(1.0, max(d * k for d in (1, 2, 5) if d * k <= raw)))


def arrow_path(base: np.ndarray, d: np.ndarray, head: float) -> MplPath:
    """One compound path of arrows from ``base`` (k, 2) along ``d`` (k, 2): a shaft and a
    closed triangular head (length ``head``, or half the arrow if shorter; half as wide), so
    that the SVG holds one path for all of them. Arrows of zero length are left out."""
    length = np.hypot(d[:, 0], d[:, 1])
    keep = length > 0
    base, d, length = base[keep], d[keep], length[keep]
    t = d / length[:, None]
    n = np.column_stack([-t[:, 1], t[:, 0]])
    hl = np.minimum(head, 0.5 * length)[:, None]
    tip = base + d
    neck = tip - hl * t
    verts = np.stack([base, neck, tip, neck + 0.5 * hl * n, neck - 0.5 * hl * n, tip], axis=1)
    codes = np.array([MplPath.MOVETO, MplPath.LINETO, MplPath.MOVETO, MplPath.LINETO,
                      MplPath.LINETO, MplPath.CLOSEPOLY], dtype=MplPath.code_type)
    return MplPath(verts.reshape(-1, 2), np.tile(codes, len(base)))


def draw_displacement(ax: "Axes", p: JacquardProblem, natural: np.ndarray, x: np.ndarray,
                      window: int | None = None) -> list:
    """Arrows from each drawn particle's natural position (every repeat drawn, thinned to
    ARROWS each way) along its displacement, magnified so that a small stretch can be seen; the legend entry says by
    how much and the largest displacement. Nothing for a fabric that did not move."""
    from matplotlib.lines import Line2D
    u = (x - natural).reshape(p.courses, p.wales, 2)
    largest = float(np.hypot(u[..., 0], u[..., 1]).max())
    if largest <= 1e-12 * max(p.w, p.h):
        return []
    t, moved = _Tiling(p, natural, window), _Tiling(p, x, window)
    step = max(1, int(np.ceil(max(t.nw, t.nc) / ARROWS)))
    jj, ii = np.meshgrid(np.arange(0, t.nc, step), np.arange(0, t.nw, step), indexing="ij")
    base = t.root(ii.ravel(), jj.ravel())             # every drawn repeat's particles
    d = moved.root(ii.ravel(), jj.ravel()) - base
    scale = displacement_scale(largest, p.w)
    arrows = PathPatch(arrow_path(base, d * scale, 0.25 * p.w), facecolor=ARROW_COLOUR,
                       edgecolor=ARROW_COLOUR, linewidth=0.8, zorder=6)
    _add(ax, arrows)
    return [Line2D([], [], color=ARROW_COLOUR, marker=">", lw=1.2, ms=5,
                   label=f"particle displacement from its natural place, drawn x{scale:g} "
                   f"(largest {largest:.3g} mm)")]


def compact_svg(text: str) -> str:
    """Path data with coordinates to 0.01 pt (matplotlib writes 6 decimals) and no line breaks
    between commands: the same drawing in about half the bytes."""
    def shorten(match: re.Match) -> str:
        data = re.sub(r"(\d\.\d\d)\d+", r"\1", match.group(1))
        return ' d="' + " ".join(data.split()) + '"'
    return re.sub(r' d="([^"]*)"', shorten, text)


def render(result: Solved, path: Path, svg: bool = False,
           window: int | None = None) -> list[Path]:
    """Write the picture to ``path`` (PNG) and, if asked, the SVG beside it (``window``:
    :func:`figure`)."""
    fig, _ = figure(result, window)
    written = [save_figure(fig, path)]
    if svg:
        buffer = io.StringIO()
        with matplotlib.rc_context({"svg.fonttype": "none"}):     # text as text, not glyphs
            fig.savefig(buffer, format="svg", metadata={"Date": None})
        written.append(write_text(path.with_suffix(".svg"), compact_svg(buffer.getvalue())))
    return written
