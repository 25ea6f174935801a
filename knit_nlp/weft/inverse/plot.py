"""Pictures of the inverse commands: control (natural, start and achieved shapes, goals, clamp
travel), fit (observed against fitted points per case) and overlays on a photograph."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.collections import LineCollection

from ...figures import new_figure, save_figure
from ..output.plot import course_lines


def plot_control(path: Path, natural: np.ndarray, start: np.ndarray, achieved: np.ndarray,
                 goals: np.ndarray, reached: np.ndarray, travel: list[tuple[np.ndarray, np.ndarray]],
                 title: str) -> Path:
    """Natural (grey), start (dashed) and achieved loops; goals (crosses) and the points that
    reached for them (dots); arrows from each actuated clamp's start target to its answer."""
    fig = new_figure(figsize=(7, 7))
    ax = fig.subplots()
    ax.add_collection(LineCollection(course_lines(natural), colors="0.8", linewidths=1.0, label="natural"))
    ax.add_collection(LineCollection(course_lines(start), colors="0.45", linewidths=0.8,
                                     linestyles="dashed", label="start"))
    ax.add_collection(LineCollection(course_lines(achieved), colors="tab:blue", linewidths=1.5,
                                     label="achieved"))
    if len(goals):
        ax.plot(goals[:, 0], goals[:, 1], "x", color="crimson", ms=10, mew=2, label="goal")
        ax.plot(reached[:, 0], reached[:, 1], "o", mfc="none", color="crimson", ms=8, label="reached")
    for k, (a, b) in enumerate(travel):
        ax.annotate("", xy=b, xytext=a, arrowprops={"arrowstyle": "->", "color": "darkorange", "lw": 2})
        ax.plot(*b, "s", color="darkorange", ms=7, label="actuated clamp" if k == 0 else None)
        ax.update_datalim([a, b])
    ax.autoscale()
    ax.set_aspect("equal")
    ax.margins(0.06)
    ax.set_title(title, fontsize=10)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def plot_fit(path: Path, cases: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]], title: str) -> Path:
    """One panel per case: fitted centrelines, observed points (crosses), fitted points (dots)."""
    fig = new_figure(figsize=(5 * len(cases), 5))
    axes = fig.subplots(1, len(cases), squeeze=False)
    for ax, (name, lines, observed, fitted) in zip(axes[0], cases):
        ax.add_collection(LineCollection(course_lines(lines), colors="tab:blue", linewidths=1.0))
        ax.plot(observed[:, 0], observed[:, 1], "x", color="crimson", ms=7, label="observed")
        ax.plot(fitted[:, 0], fitted[:, 1], "o", mfc="none", color="k", ms=6, label="fitted")
        ax.autoscale()
        ax.set_aspect("equal")
        ax.set_title(name, fontsize=10)
        ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path, dpi=110)


def plot_on_image(path: Path, image: np.ndarray, lines_px: np.ndarray, matches_px: np.ndarray,
                  mapped_px: np.ndarray, observed_px: np.ndarray | None) -> Path:
    """The image at its own resolution with centrelines (pixel coordinates) drawn over it."""
    h, w = image.shape[:2]
    dpi = 100
    fig = new_figure(figsize=(w / dpi, h / dpi), dpi=dpi)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(image, extent=(-0.5, w - 0.5, h - 0.5, -0.5), interpolation="nearest")
    ax.add_collection(LineCollection(course_lines(lines_px), colors="deepskyblue", linewidths=1.2))
    ax.plot(matches_px[:, 0], matches_px[:, 1], "o", mfc="none", color="yellow", ms=10, mew=2)
    ax.plot(mapped_px[:, 0], mapped_px[:, 1], "+", color="red", ms=10, mew=2)
    if observed_px is not None and len(observed_px):
        ax.plot(observed_px[:, 0], observed_px[:, 1], "x", color="magenta", ms=6)
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.axis("off")
    return save_figure(fig, path, dpi=dpi)
