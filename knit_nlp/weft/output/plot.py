"""Pictures of weft-knit solutions that explain themselves: axes in the problem's units, a
course key (or a displacement colourbar), grips drawn as they hold (a point clamp as a square,
the clamps of one course/wale/edge shorthand and a rigid clamp as a bar whose legend entry gives
the grip's total force, a moved clamp's target as a cross), reactions and loads as arrows on one
scale with a reference arrow, one legend outside the fabric built from what is drawn (a new
labelled artist joins it by itself); full-versus-reduced overlays; force against displacement along a loading path; and
GIF animations of a loading path (matplotlib's PillowWriter)."""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
from matplotlib.animation import PillowWriter
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from ...atomic import temporary_path
from ...figures import fit_titles, legend_below, new_figure, save_figure, settle_layout
from ...units import Units
from .export import COLOURINGS
from .reactions import SolvedFabric
from .yarn import draw_yarn

DPI = 110
GIF_DPI = 80                   # an animation's frames
REACTION, LOAD, GRIP = "crimson", "royalblue", "black"
ARROW_FRACTION = 0.15          # the largest arrow is this fraction of the fabric's extent
KEY_WIDTH = 0.3               # the fraction of the width under the picture kept for the reference arrow
NEGLIGIBLE = 1e-6              # arrows below this fraction of the largest (or below tol) are not drawn


def course_lines(lines: np.ndarray) -> list[np.ndarray]:
    """One polyline per course from (m, n, S, 2) loop samples."""
    return [np.concatenate(list(course), axis=0) for course in lines]


def _segments(lines: np.ndarray) -> np.ndarray:
    """Every sampled segment (k, 2, 2) of (m, n, S, 2) loop samples, course by course."""
    return np.stack([lines[..., :-1, :], lines[..., 1:, :]], axis=-2).reshape(-1, 2, 2)


def fabric_figure(extent: np.ndarray, width: float = 7.5) -> tuple[Figure, Axes]:
    """A figure whose axes have about the data's aspect ratio (tight framing)."""
    w, h = np.maximum(extent, 1e-9)
    height = float(np.clip((width - 2.2) * h / w, 2.5, 10.0)) + 1.7    # axes + title, legend
    fig = new_figure(figsize=(width, height), dpi=DPI, layout="constrained")
    return fig, fig.subplots()


def round_reference(value: float) -> float:
    """A round number (1, 2 or 5 × 10^k) near ``value``, the reference arrow's length."""
    exp = np.floor(np.log10(value))
    return float(min((1, 2, 5, 10), key=lambda d: abs(d * 10 ** exp - value)) * 10 ** exp)


def _arrows(result: SolvedFabric) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """(point, force, kind) of every reaction and load, before the negligible ones are dropped."""
    out = [(c.position, c.reaction, "reaction") for c in result.clamps]
    out += [(p, f, "reaction") for rc in result.rigid_clamps
            for p, f in zip(rc.positions, rc.reactions)]
    out += [(ld.position, ld.force, "load") for ld in result.loads]
    return out


def drawn_arrows(result: SolvedFabric) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """The arrows a picture draws: those above max(NEGLIGIBLE × largest, the solver's tol)."""
    arrows = _arrows(result)
    if not arrows:
        return []
    largest = max(float(np.hypot(*f)) for _, f, _ in arrows)
    floor = max(NEGLIGIBLE * largest, result.problem.solver.tol)
    return [a for a in arrows if np.hypot(*a[1]) > floor]


def _grip_bars(result: SolvedFabric) -> tuple[list[tuple[str, np.ndarray, str]], np.ndarray]:
    """(name, polyline through the held points, legend label with the grip's total force) of
    every shorthand clamp table and rigid clamp, and the positions of the single point
    clamps."""
    units = result.problem.units
    groups: dict[str, list] = defaultdict(list)
    singles = []
    for c in result.clamps:
        (groups[c.group].append(c) if c.group else singles.append(c.position))
    bars = []
    for name, members in groups.items():
        total = np.sum([c.reaction for c in members], axis=0)
        bars.append((name, np.array([c.position for c in members]),
                     f"{name} ({len(members)} points): total force "
                     f"{_pair(total)} {units.force}"))
    for rc in result.rigid_clamps:
        bars.append((f"rigid_clamp[{rc.number}]", rc.positions,
                     f"rigid_clamp[{rc.number}] ({len(rc.positions)} points): total force "
                     f"{_pair(rc.force)} {units.force}, moment {rc.moment:.4g} {units.energy}"))
    return bars, np.array(singles).reshape(-1, 2)


def _pair(v: np.ndarray) -> str:
    """A force as "(x, y)" to four significant digits (negligible components as 0)."""
    scale = max(float(np.abs(v).max()), 1e-300)
    return "(" + ", ".join(f"{(0.0 if abs(c) < 1e-9 * scale else c):.4g}" for c in v) + ")"


def draw_solution(ax: Axes, result: SolvedFabric, natural: np.ndarray, deformed: np.ndarray,
                  colour: str | None = "course", forces: bool = True, yarn: bool = False) -> Any:
    """Draw a solution into ``ax``: natural loops grey, deformed loops coloured by course, by
    displacement magnitude or (``colour`` None) in one colour, the grips (each shorthand table
    and rigid clamp a bar whose legend entry gives its total force), targets and, with
    ``forces``, the force arrows. Every artist is labelled for the figure's legend. Returns
    the colour-mapped collection (None for one colour) and the arrows' scale (None: none).
    With ``yarn`` the yarn is drawn with its thickness and the active contacts marked."""
    pts = np.concatenate([natural.reshape(-1, 2), deformed.reshape(-1, 2)])
    size = float(np.max(pts.max(axis=0) - pts.min(axis=0)))
    ax.add_collection(LineCollection(course_lines(natural), colors="0.8", linewidths=1.0,
                                     label="natural", zorder=1))
    mapped = None
    if colour == "displacement":
        mag = np.linalg.norm(deformed - natural, axis=-1)
        mapped = LineCollection(_segments(deformed), array=0.5 * (mag[..., :-1] + mag[..., 1:]).ravel(),
                                cmap="viridis", linewidths=1.8, zorder=2)
        ax.add_collection(mapped)
    elif colour == "course":
        m = len(deformed)
        mapped = LineCollection(course_lines(deformed), array=np.arange(1, m + 1), cmap="viridis",
                                linewidths=1.8, zorder=2)
        mapped.set_clim(0.5, m + 0.5)
        ax.add_collection(mapped)
    else:
        ax.add_collection(LineCollection(course_lines(deformed), colors="tab:blue",
                                         linewidths=1.4, zorder=2, label="equilibrium"))
    if yarn:
        draw_yarn(ax, result, deformed)
    _draw_grips(ax, result)
    scale = _draw_forces(ax, result, size) if forces else None
    ax.autoscale()
    ax.set_aspect("equal")
    ax.margins(0.03)
    units = result.problem.units
    ax.set_xlabel(f"x [{units.length}]")
    ax.set_ylabel(f"y [{units.length}]")
    return mapped, scale


def solution_figure(result: SolvedFabric, natural: np.ndarray, deformed: np.ndarray,
                    colour: str = "course", yarn: bool = False) -> tuple[Figure, Axes]:
    """The solution picture (not saved): :func:`draw_solution` with its colour key, the
    reference arrow under the picture, a title and the legend below the axes; with ``yarn`` the
    yarn with its thickness and the active contacts (``yarn.draw_yarn``)."""
    if colour not in COLOURINGS:
        raise ValueError(f"colour must be one of {', '.join(COLOURINGS)}; got {colour!r}")
    units = result.problem.units
    pts = np.concatenate([natural.reshape(-1, 2), deformed.reshape(-1, 2)])
    fig, ax = fabric_figure(pts.max(axis=0) - pts.min(axis=0))
    mapped, forces = draw_solution(ax, result, natural, deformed, colour, yarn=yarn)
    colour_key(fig, ax, mapped, colour, len(deformed), units)
    reference_arrow(ax, forces, units)
    told = getattr(result, "checked", None) or {}      # the answer's own check, its words
    ax.set_title(f"{result.problem.name} ({result.model}): stored energy "
                 f"{result.energy.total:.4g} {units.energy}, "
                 f"{'converged' if result.success else 'NOT CONVERGED'}"
                 + (f"\ncheck: {told['verdict']}" if told else ""), fontsize=10,
                 color="tab:red" if told.get("ok") is False else "black", wrap=True)
    legend_below(fig, reserve=KEY_WIDTH if forces else 0.0)
    settle_layout(fig)
    return fig, ax


def colour_key(fig: Figure, ax: Axes, mapped: Any, colour: str | None, courses: int,
               units: Units) -> None:
    """The colourbar of :func:`draw_solution`'s coloured loops (nothing for one colour)."""
    if mapped is None:
        return
    if colour == "displacement":
        fig.colorbar(mapped, ax=ax, label=f"displacement [{units.length}]", shrink=0.8)
        return
    bar = fig.colorbar(mapped, ax=ax, label="course (deformed loops)", shrink=0.8)
    bar.set_ticks(course_ticks(courses))


def course_ticks(courses: int, most: int = 10) -> np.ndarray:
    """Evenly spaced course numbers for a course key: every course up to ``most`` courses, else
    the multiples of the smallest of 1, 2, 5 x 10^k that gives at most ``most`` ticks (5, 10,
    15, ... rather than the uneven 1, 4, 7, 11 of rounded equal divisions)."""
    if courses <= most:
        return np.arange(1, courses + 1)
    step = next(d * 10 ** e for e in range(int(np.log10(courses)) + 1) for d in (1, 2, 5)
                if courses // (d * 10 ** e) <= most)
    return np.arange(step, courses + 1, step)


def _draw_grips(ax: Axes, result: SolvedFabric) -> None:
    bars, singles = _grip_bars(result)
    for name, bar, label in bars:
        ax.plot(bar[:, 0], bar[:, 1], "-", color=GRIP, lw=4, alpha=0.6, solid_capstyle="butt",
                zorder=3, label=label)
        if len(bars) > 1:               # which bar is which: its table's name beside it
            ax.annotate(name, bar[len(bar) // 2], fontsize=7, ha="center", va="center",
                        zorder=7, bbox={"boxstyle": "round,pad=0.15", "fc": "white",
                                        "ec": "none", "alpha": 0.8})
    if len(singles):
        ax.plot(singles[:, 0], singles[:, 1], "s", color=GRIP, ms=6, zorder=4,
                label="point clamp")
    pr = result.problem
    moved = [c for c in result.clamps if np.linalg.norm(
        c.target - pr.natural_position(c.loop, pr.clamps[c.number - 1].s)) > pr.solver.tol]
    # a target that holds both coordinates is a cross; one that holds x (y) only is a bar
    # across that axis at the held value, through where the point ended
    for fix, marker, label in ((("x", "y"), "x", "clamp target"),
                               (("x",), "|", "clamp target (x held)"),
                               (("y",), "_", "clamp target (y held)")):
        tg = np.array([[c.target[0] if "x" in fix else c.position[0],
                        c.target[1] if "y" in fix else c.position[1]]
                       for c in moved if c.fix == fix]).reshape(-1, 2)
        if len(tg):
            ax.plot(tg[:, 0], tg[:, 1], marker, color=GRIP, ms=12, mew=2, zorder=5, label=label)


@dataclass(frozen=True)
class ForceScale:
    """The arrows' scale (data length per force unit), the largest force drawn and a quiver
    to hang the reference arrow on."""

    quiver: Any
    scale: float
    largest: float


def _draw_forces(ax: Axes, result: SolvedFabric, size: float) -> ForceScale | None:
    """The reaction and load arrows on one scale (None: no arrow is drawn)."""
    arrows = drawn_arrows(result)
    if not arrows:
        return None
    largest = max(float(np.hypot(*f)) for _, f, _ in arrows)
    scale = ARROW_FRACTION * size / largest
    q = None
    for kind, colour in (("reaction", REACTION), ("load", LOAD)):
        sel = [(p, f) for p, f, k in arrows if k == kind]
        if not sel:
            continue
        p, f = np.array([a for a, _ in sel]), np.array([b for _, b in sel])
        q = ax.quiver(p[:, 0], p[:, 1], f[:, 0] * scale, f[:, 1] * scale, angles="xy",
                      scale_units="xy", scale=1, color=colour, width=0.005, zorder=6,
                      label="force of each clamp on the fabric" if kind == "reaction"
                      else "load")
        ax.update_datalim(p + f * scale)                 # keep the arrow tips in view
    return ForceScale(q, scale, largest)


def reference_arrow(ax: Axes, forces: ForceScale | None, units: Units) -> None:
    """The reference arrow of the force scale, under the picture (nothing without arrows)."""
    if forces is None:
        return
    ref = round_reference(forces.largest)
    ax.quiverkey(forces.quiver, 1.0 - KEY_WIDTH + 0.02, 0.035, ref * forces.scale,
                 f"{ref:g} {units.force}",
                 labelpos="E", coordinates="figure", color="0.2", fontproperties={"size": 8})


def plot_solution(path: Path, result: SolvedFabric, natural: np.ndarray,
                  deformed: np.ndarray, colour: str = "course", yarn: bool = False) -> Path:
    """PNG of :func:`solution_figure`."""
    fig, _ = solution_figure(result, natural, deformed, colour, yarn)
    return save_figure(fig, path, dpi=DPI)


def held_points(problem: Any, lines: np.ndarray) -> tuple[list[tuple[str, np.ndarray]], np.ndarray]:
    """Where a frame's grips hold, from its sampled loops ``lines`` (m, n, S, 2; S samples
    evenly spaced in s over [0, L]) by interpolation at each held point's s: (legend label,
    (k, 2) points) of every shorthand clamp table and rigid clamp, and the single point
    clamps' positions."""
    s = np.linspace(0.0, problem.L, lines.shape[2])

    def at(loop: tuple[int, int], where: float) -> np.ndarray:
        curve = lines[loop[0] - 1, loop[1] - 1]
        return np.array([np.interp(where, s, curve[:, 0]), np.interp(where, s, curve[:, 1])])
    groups: dict[str, list[np.ndarray]] = defaultdict(list)
    singles = []
    for c in problem.clamps:
        (groups[c.table].append(at(c.loop, c.s)) if c.expanded else singles.append(at(c.loop, c.s)))
    bars = [(f"{name} ({len(pts)} points)", np.array(pts)) for name, pts in groups.items()]
    bars += [(f"rigid_clamp[{k}] ({len(rc.points)} points)",
              np.array([at(loop, where) for loop, _, where in rc.points]))
             for k, rc in enumerate(problem.rigid_clamps, start=1)]
    return bars, np.array(singles).reshape(-1, 2)


def animate(path: Path, natural: np.ndarray, frames: Sequence[tuple[str, np.ndarray]],
            units: Units, fps: int = 4, problem: Any = None) -> Path:
    """A GIF of deformed centrelines ``frames`` ((title, (m, n, S, 2)) each) over the natural
    loops, framed to hold every frame: a loading path from a continuation solve or a study.
    With ``problem`` (the WeftProblem) every frame draws its grips where they hold
    (:func:`held_points`: a shorthand table's or rigid clamp's points as a bar, point clamps
    as squares). The layout is settled at the GIF's resolution, so the legend under the
    picture lies inside every frame."""
    pts = np.concatenate([natural.reshape(-1, 2)] + [d.reshape(-1, 2) for _, d in frames])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    fig, ax = fabric_figure(hi - lo, width=6.0)
    fig.set_dpi(GIF_DPI)
    ax.add_collection(LineCollection(course_lines(natural), colors="0.8", linewidths=1.0,
                                     label="natural"))
    m = len(natural)
    lc = LineCollection(course_lines(frames[0][1]), array=np.arange(1, m + 1), cmap="viridis",
                        linewidths=1.6)
    lc.set_clim(0.5, m + 0.5)
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, label="course (deformed loops)", shrink=0.8).set_ticks(course_ticks(m))
    grips = _grip_artists(ax, problem, frames[0][1])
    pad = 0.03 * (hi - lo).max()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel(f"x [{units.length}]")
    ax.set_ylabel(f"y [{units.length}]")
    ax.set_title(max((t for t, _ in frames), key=len), fontsize=9)
    legend_below(fig, max_columns=2)
    settle_layout(fig)                      # at GIF_DPI, with the longest title
    writer = PillowWriter(fps=fps)
    with temporary_path(path) as tmp:
        with writer.saving(fig, str(tmp), dpi=GIF_DPI):
            for title, lines in frames:
                lc.set_segments(course_lines(lines))
                _move_grips(grips, problem, lines)
                ax.set_title(title, fontsize=9)
                fit_titles(fig)
                writer.grab_frame()
    return path


def _grip_artists(ax: Axes, problem: Any, lines: np.ndarray) -> list[Any]:
    """The grips' lines of the first frame (bars, then the point clamps), labelled for the
    legend; none without a problem."""
    if problem is None:
        return []
    bars, singles = held_points(problem, lines)
    out = [ax.plot(b[:, 0], b[:, 1], "-", color=GRIP, lw=3, alpha=0.6, solid_capstyle="butt",
                   zorder=3, label=label)[0] for label, b in bars]
    if len(singles):
        out += ax.plot(singles[:, 0], singles[:, 1], "s", color=GRIP, ms=5, zorder=4,
                       label="point clamp")
    return out


def _move_grips(artists: list[Any], problem: Any, lines: np.ndarray) -> None:
    """The grips' lines of :func:`_grip_artists` moved to where they hold in ``lines``."""
    if not artists:
        return
    bars, singles = held_points(problem, lines)
    for artist, pts in zip(artists, [b for _, b in bars] + ([singles] if len(singles) else [])):
        artist.set_data(pts[:, 0], pts[:, 1])


def plot_force_displacement(path: Path, rows: Sequence[dict[str, Any]], units: Units,
                            name: str) -> Path:
    """Force along the pull against distance for every grip that moves (rows of
    :func:`knit_nlp.weft.output.path.path_rows`)."""
    fig = new_figure(figsize=(6.5, 4.5), dpi=DPI, layout="constrained")
    ax = fig.subplots()
    grips = dict.fromkeys(r["grip"] for r in rows if r["distance"] != "")
    for grip in grips:
        pts = [(r["distance"], r["force_along_pull"]) for r in rows if r["grip"] == grip]
        d, f = np.array(pts).T
        ax.plot(d, f, "o-", ms=3, label=grip)
    ax.set_xlabel(f"distance along the pull [{units.length}]")
    ax.set_ylabel(f"force on the fabric along the pull [{units.force}]")
    ax.set_title(f"{name}: force against displacement", fontsize=10)
    ax.grid(alpha=0.3)
    if grips:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    return save_figure(fig, path, dpi=DPI)


def plot_overlay(path: Path, full: np.ndarray, reduced: np.ndarray, title: str,
                 units: Units | None = None) -> Path:
    """PNG of full (thin black) and reduced loops, the reduced ones coloured by the distance
    between corresponding centreline points."""
    units = units or Units()
    pts = np.concatenate([full.reshape(-1, 2), reduced.reshape(-1, 2)])
    fig, ax = fabric_figure(pts.max(axis=0) - pts.min(axis=0))
    ax.add_collection(LineCollection(course_lines(full), colors="k", linewidths=0.8,
                                     label="full model"))
    err = np.linalg.norm(full - reduced, axis=-1)
    lc = LineCollection(_segments(reduced), array=0.5 * (err[..., :-1] + err[..., 1:]).ravel(),
                        cmap="plasma", linewidths=2.0,
                        label="reduced model, coloured by its distance to the full one")
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, label=f"distance full - reduced [{units.length}]", shrink=0.8)
    ax.autoscale()
    ax.set_aspect("equal")
    ax.margins(0.03)
    ax.set_xlabel(f"x [{units.length}]")
    ax.set_ylabel(f"y [{units.length}]")
    ax.set_title(title, fontsize=10)
    legend_below(fig, max_columns=2)
    return save_figure(fig, path, dpi=DPI)
