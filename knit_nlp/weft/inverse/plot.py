"""Pictures of the inverse commands, drawn like a solve's picture (``weft.output.plot``: axes in
the problem's units, grips with their total forces, one legend built from what is drawn):
control (start and achieved shapes, goals, the actuated clamps' travel, the forces at the
answer), fit (observed against fitted points per load case) and overlays on a photograph
(the photograph at its own resolution, with a key under it)."""
from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.patches import FancyArrowPatch

from ...figures import legend_below, new_figure, save_figure, settle_layout
from ...units import Units
from ..output.plot import (DPI, KEY_WIDTH, fabric_figure, colour_key, course_lines, draw_solution,
                           reference_arrow)
from ..output.reactions import SolvedFabric

GOAL, TRAVEL, OPENING = "darkorange", "darkorange", "magenta"
CHECK_CHARS = 80            # a check's words per title line: control's picture
PANEL_CHARS = 55            # ... a fit's panel (4.8 inches wide, 9 pt)


def told(title: str, check: dict[str, Any] | None, chars: int = CHECK_CHARS
         ) -> tuple[str, str]:
    """A title with the answer's own check under it (a result JSON's ``check`` block, as a
    solve's picture says it: ``output.plot.solution_figure``), in lines of at most
    ``chars`` characters (a line as wide as the figure ran under the colour bar), and its
    colour: red when the check refutes the answer."""
    if not check:
        return title, "black"
    return (f"{title}\n" + textwrap.fill(f"check: {check['verdict']}", chars),
            "tab:red" if check.get("ok") is False else "black")


def same_shape(a: np.ndarray, b: np.ndarray, rel: float = 1e-6) -> bool:
    """Whether two sampled shapes coincide (every point within ``rel`` of their extent: far
    below a pixel), so that drawing both would hide one under the other."""
    if a.shape != b.shape:
        return False
    pts = np.concatenate([a.reshape(-1, 2), b.reshape(-1, 2)])
    return bool(np.max(np.abs(a - b)) <= rel * float(np.max(np.ptp(pts, axis=0))))


def plot_control(path: Path, result: SolvedFabric, natural: np.ndarray, start: np.ndarray,
                 achieved: np.ndarray, goals: np.ndarray, reached: np.ndarray,
                 travel: list[tuple[np.ndarray, np.ndarray]],
                 openings: list[tuple[np.ndarray, str]], title: str,
                 check: dict[str, Any] | None = None) -> Path:
    """The equilibrium at the answer drawn as a solve's picture (``result``: its grips, the
    force each clamp applies), with the start shape dashed (or, where it is the natural
    shape, the natural loops named as both), each goal (diamond) and the point
    that reached for it (dot), an arrow from each actuated clamp's start target to its answer,
    and each opening's two points joined (``openings``: ((2, 2) points, its legend label))."""
    units = result.problem.units
    pts = np.concatenate([natural.reshape(-1, 2), start.reshape(-1, 2), achieved.reshape(-1, 2),
                          goals.reshape(-1, 2)])
    fig, ax = fabric_figure(pts.max(axis=0) - pts.min(axis=0))
    same = same_shape(start, natural)
    if not same:
        ax.add_collection(LineCollection(course_lines(start), colors="0.45", linewidths=0.8,
                                         linestyles="dashed", label="start (before control)",
                                         zorder=1.5))
    mapped, forces = draw_solution(ax, result, natural, achieved, "course")
    if same:                                # one drawing, named for both
        for artist in ax.collections:
            if artist.get_label() == "natural":
                artist.set_label("natural, also the start (before control)")
    if len(goals):
        ax.plot(goals[:, 0], goals[:, 1], "D", mfc="none", color=GOAL, ms=11, mew=2, zorder=8,
                label="goal")
        ax.plot(reached[:, 0], reached[:, 1], "o", color=GOAL, ms=4, zorder=10,
                label="the goal's point, achieved")
    for k, (a, b) in enumerate(travel):
        ax.add_patch(FancyArrowPatch(a, b, arrowstyle="-|>", mutation_scale=14, color=TRAVEL,
                                     lw=2, zorder=8, label="actuated clamp: start → answer"
                                     if k == 0 else "_travel"))
        ax.update_datalim([a, b])
    for pair, label in openings:
        ax.plot(pair[:, 0], pair[:, 1], "-o", color=OPENING, lw=2, ms=4, zorder=9, label=label)
    ax.update_datalim(goals.reshape(-1, 2))
    ax.autoscale()
    colour_key(fig, ax, mapped, "course", len(achieved), units)
    reference_arrow(ax, forces, units)
    text, colour = told(title, check)
    ax.set_title(text, fontsize=10, color=colour, wrap=True)
    legend_below(fig, reserve=KEY_WIDTH if forces else 0.0)
    settle_layout(fig)                  # the title wrapped to the axes (a solve's picture's way)
    return save_figure(fig, path, dpi=DPI)


def plot_fit(path: Path, cases: list[tuple[str, SolvedFabric, np.ndarray, np.ndarray,
                                           np.ndarray, np.ndarray]], title: str,
             checks: dict[str, dict[str, Any]] | None = None) -> Path:
    """One panel per load case: the natural and the fitted equilibrium's loops with their grips
    (``result``), observed points (crosses) and the model's points at the fitted values
    (circles); each panel's title says its equilibrium's own check (``checks``: per case, the
    ``check`` block). ``cases``: (name, result, natural, fitted loops, observed, fitted
    points)."""
    units: Units = cases[0][1].problem.units if cases else Units()
    fig = new_figure(figsize=(4.8 * max(len(cases), 1), 5.6), dpi=DPI, layout="constrained")
    axes = fig.subplots(1, max(len(cases), 1), squeeze=False)[0]
    for ax, (name, result, natural, lines, observed, fitted) in zip(axes, cases):
        draw_solution(ax, result, natural, lines, None, forces=False)
        ax.plot(observed[:, 0], observed[:, 1], "x", color="crimson", ms=7, zorder=8,
                label="observed point")
        ax.plot(fitted[:, 0], fitted[:, 1], "o", mfc="none", color="k", ms=6, zorder=8,
                label="model point at the fitted values")
        ax.update_datalim(np.concatenate([observed, fitted]))
        ax.autoscale()
        text, colour = told(f"load case {name}", (checks or {}).get(name), PANEL_CHARS)
        ax.set_title(text, fontsize=9, color=colour, wrap=True)
    if not cases:
        axes[0].set(xlabel=f"x [{units.length}]", ylabel=f"y [{units.length}]")
        axes[0].text(0.5, 0.5, "no load case has a solution to draw", ha="center",
                     transform=axes[0].transAxes)
    fig.suptitle(title, fontsize=10)
    legend_below(fig)
    settle_layout(fig)                  # each panel's check wrapped to its panel
    return save_figure(fig, path, dpi=DPI)


def plot_on_image(path: Path, image: np.ndarray, lines_px: np.ndarray, matches_px: np.ndarray,
                  mapped_px: np.ndarray, observed_px: np.ndarray | None, caption: str = "") -> Path:
    """The image at its own resolution (one image pixel per picture pixel, in the top rows of
    the picture) with centrelines drawn over it, and a strip under it with the key and
    ``caption``."""
    h, w = image.shape[:2]
    dpi = 100
    fig = new_figure(figsize=(w / dpi, (h + 1) / dpi), dpi=dpi)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(image, extent=(-0.5, w - 0.5, h - 0.5, -0.5), interpolation="nearest")
    ax.add_collection(LineCollection(course_lines(lines_px), colors="deepskyblue", linewidths=1.2,
                                     label="model centrelines"))
    ax.plot(matches_px[:, 0], matches_px[:, 1], "o", mfc="none", color="yellow", ms=10, mew=2,
            label="match: the pixel given")
    ax.plot(mapped_px[:, 0], mapped_px[:, 1], "+", color="red", ms=10, mew=2,
            label="match: its model point, mapped")
    if observed_px is not None and len(observed_px):
        ax.plot(observed_px[:, 0], observed_px[:, 1], "x", color="magenta", ms=6,
                label="observed point, mapped")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.axis("off")
    renderer = fig.canvas.get_renderer()
    text = fig.text(0.0, 0.0, caption, fontsize=8, va="bottom", ha="left", wrap=False)
    handles, labels = ax.get_legend_handles_labels()
    for ncol in (2, 1):                 # as many columns as the image's width holds
        legend = fig.legend(handles, labels, loc="lower left", ncol=ncol, fontsize=8,
                            frameon=False)
        if legend.get_window_extent(renderer).width <= w - 8 or ncol == 1:
            break
        legend.remove()
    key_h = legend.get_window_extent(renderer).height
    cap_h = text.get_window_extent(renderer).height + 4 if caption else 0.0
    strip = int(np.ceil(key_h + cap_h + 6))
    fig.set_size_inches(w / dpi, (h + strip) / dpi)
    total = h + strip
    ax.set_position((0, strip / total, 1, h / total))
    text.set_position((4 / w, 3 / total))
    legend.set_bbox_to_anchor((0, (cap_h + 3) / total, 1, 1), transform=fig.transFigure)
    return save_figure(fig, path, dpi=dpi)
