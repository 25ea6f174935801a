"""Pictures of the fabric (docs/jacquard.md, "Rendering"; paper Fig. 2 stitch models).

Each pillar loop is a closed smooth yarn through 6 points (P1-P6), each inlay underlap a smooth
yarn through 4 points and each fall-plate underlap a 2-point yarn, all placed in the frame of
the displaced particles: the loop of P(i,j) spans P(i,j) -> P(i,j+1), its lateral unit is
perpendicular to that, scaled by the wale spacing w. Several repeats are tiled; natural and
simulated fabric are drawn side by side. Proportions: docs/jacquard.md, "Rendering".
"""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

from typing import TYPE_CHECKING  # noqa: E402

from .problem import JacquardProblem  # noqa: E402
from .springs import zigzag_direction  # noqa: E402

if TYPE_CHECKING:
    from .result import JacquardResult

# Local stitch points (u in units of w to the right, v in units of the loop's height).
PILLAR = np.array([[0.06, 0.0], [-0.22, 0.30], [-0.20, 0.95], [0.20, 0.95], [0.22, 0.30],
                   [-0.06, 0.0]])                      # 6-point pillar loop, closed
INLAY_END = np.array([[0.0, 0.167], [0.0, 0.40]])     # 4-point inlay: start, pull-out ...
FALL_PLATE_V = 0.5                                     # 2-point fall-plate underlap height
COLOURS = {"ground": "#efe9d8", "fall_plate": "#c0392b", "inlay": "#2e6fb5"}
OUTLINE = "#3a3a3a"
WIDTH = {"ground": 0.13, "thick": 0.11, "thin": 0.07, "net": 0.06}   # yarn widths, units of w
MAX_LOOPS = 24    # largest number of wales / courses drawn per panel


def catmull_rom(ctrl: np.ndarray, closed: bool, samples: int = 8) -> np.ndarray:
    """Sample centripetal-free (uniform) Catmull-Rom splines through ``ctrl`` (n, K, 2)."""
    if closed:
        pts = np.concatenate([ctrl[:, -1:], ctrl, ctrl[:, :2]], axis=1)
    else:
        pts = np.concatenate([2 * ctrl[:, :1] - ctrl[:, 1:2], ctrl,
                              2 * ctrl[:, -1:] - ctrl[:, -2:-1]], axis=1)
    t = np.linspace(0, 1, samples, endpoint=False)[:, None]
    basis = 0.5 * np.stack([-t**3 + 2 * t**2 - t, 3 * t**3 - 5 * t**2 + 2,
                            -3 * t**3 + 4 * t**2 + t, t**3 - t**2], axis=0)   # (4, S, 1)
    segs = []
    for k in range(pts.shape[1] - 3):
        p = pts[:, k:k + 4]                                                   # (n, 4, 2)
        segs.append(np.einsum("bsx,nbc->nsc", basis, p))
    out = np.concatenate(segs, axis=1)
    last = ctrl[:, :1] if closed else ctrl[:, -1:]
    return np.concatenate([out, last], axis=1)


class _Tiling:
    """Positions of the drawn loops: repeats tiled, and the frame of each loop."""

    def __init__(self, p: JacquardProblem, x: np.ndarray) -> None:
        self.p = p
        m, n = p.wales, p.courses
        self.nw = min(MAX_LOOPS, m * min(3, max(1, MAX_LOOPS // m)))
        self.nc = min(MAX_LOOPS, n * min(3, max(1, MAX_LOOPS // n)))
        self.x = x.reshape(n, m, 2)

    def root(self, i: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Position of P(i,j) for unwrapped (tiled) indices."""
        p = self.p
        im, jm = np.mod(i, p.wales), np.mod(j, p.courses)
        base = self.x[jm, im]
        shift = np.stack([(i - im) * p.w, (j - jm) * p.h], axis=-1)
        return base + shift     # a fixed patch is tiled the same way, copies side by side

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


def _yarns(ax, curves: np.ndarray, colour: str, width_pts: float) -> None:
    """Draw curves as yarns: a dark outline under a coloured core."""
    segs = list(curves)
    ax.add_collection(LineCollection(segs, colors=OUTLINE, linewidths=width_pts * 1.35,
                                     capstyle="round", joinstyle="round"))
    ax.add_collection(LineCollection(segs, colors=colour, linewidths=width_pts,
                                     capstyle="round", joinstyle="round"))


def _underlaps(t: _Tiling, sys, i, j) -> dict[str, np.ndarray]:
    """Control points of one system's underlaps, grouped by structure."""
    p = t.p
    codes = sys.codes[np.mod(j, p.courses), np.mod(i, p.wales)]
    d = zigzag_direction(p, np.mod(j, p.courses))
    out = {}
    for code, struct in ((2, "thick"), (1, "thin"), (0, "net")):
        sel = codes == code
        if not sel.any():
            continue
        ci, cj = i[sel], j[sel]
        o = (sys.span[struct] - 1) * d[sel]
        side = -0.32 if sys.name == "inlay" else 0.32
        if sys.name == "inlay":
            start = t.local(ci, cj, INLAY_END)
            end = t.local(ci + o, cj + 1, INLAY_END[::-1])
            if struct == "net":
                start = t.local(ci, cj, np.array([[side, 0.167], [side + 0.04, 0.5]]))
                end = t.local(ci, cj + 1, np.array([[side - 0.04, -0.2], [side, 0.167]]))
            out[struct] = np.concatenate([start, end], axis=1)          # 4 points
        else:
            a = t.local(ci, cj, np.array([[0.0 if struct != "net" else side, FALL_PLATE_V]]))
            b = t.local(ci + o, cj + 1, np.array([[0.0 if struct != "net" else side,
                                                    FALL_PLATE_V - (0.6 if struct == "net" else 0.0)]]))
            out[struct] = np.concatenate([a, b], axis=1)                # 2 points
    return out


def draw_fabric(ax, p: JacquardProblem, x: np.ndarray, title: str) -> None:
    """Tiled repeats of the fabric with particle positions ``x`` ((M*N, 2), row j*M + i)."""
    t = _Tiling(p, x)
    jj, ii = np.meshgrid(np.arange(t.nc), np.arange(t.nw), indexing="ij")
    i, j = ii.ravel(), jj.ravel()
    roots = t.root(i, j)
    pad = 1.5 * p.w
    ax.set_xlim(roots[:, 0].min() - pad, roots[:, 0].max() + pad)
    ax.set_ylim(roots[:, 1].min() - 0.6 * p.h, roots[:, 1].max() + 1.4 * p.h)
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("mm")
    ax.figure.canvas.draw()
    dpp = ax.transData.transform([(p.w, 0), (0, 0)])
    pts_per_w = abs(dpp[0, 0] - dpp[1, 0]) * 72.0 / ax.figure.dpi
    layers = {s.name: _underlaps(t, s, i, j) for s in p.systems}
    for struct, ctrl in layers.get("inlay", {}).items():          # back bar first
        _yarns(ax, catmull_rom(ctrl, False), COLOURS["inlay"], WIDTH[struct] * pts_per_w)
    loops = catmull_rom(t.local(i, j, PILLAR), True)
    _yarns(ax, loops, COLOURS["ground"], WIDTH["ground"] * pts_per_w)
    for struct, ctrl in layers.get("fall_plate", {}).items():     # front bar on top
        _yarns(ax, catmull_rom(ctrl, False, samples=2), COLOURS["fall_plate"],
               WIDTH[struct] * pts_per_w)
    ax.set_facecolor("#20242a")


def render(result: "JacquardResult", path: Path, svg: bool = False) -> list[Path]:
    """Natural and simulated fabric side by side: ``path`` (PNG) and, if asked, the SVG."""
    p, natural, final, solver = (result.problem, result.network.natural, result.positions,
                                 result.solver)
    t = _Tiling(p, natural)
    aspect = (t.nc * p.h + 2 * p.h) / (t.nw * p.w + 3 * p.w)
    fig, axes = plt.subplots(1, 2, figsize=(12, max(3.5, min(12, 6 * aspect + 1))), dpi=110)
    reps = (f"{t.nw // p.wales} x {t.nc // p.courses} repeats" if t.nw >= p.wales and
            t.nc >= p.courses else f"{t.nw} x {t.nc} window of the {p.wales} x {p.courses} repeat")
    draw_fabric(axes[0], p, natural, f"{p.name}: natural ({reps})")
    draw_fabric(axes[1], p, final, f"simulated ({solver})")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    written = [path]
    if svg:
        fig.savefig(path.with_suffix(".svg"))
        written.append(path.with_suffix(".svg"))
    plt.close(fig)
    return written
