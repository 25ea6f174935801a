"""Pictures of weft-knit solutions: natural loops (grey) against deformed loops, clamps and
their reaction arrows; and full-versus-reduced overlays coloured by local distance."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

if TYPE_CHECKING:
    from .results import WeftResult


def _course_lines(lines: np.ndarray) -> list[np.ndarray]:
    """One polyline per course from (m, n, S, 2) loop samples."""
    return [np.concatenate(list(course), axis=0) for course in lines]


def plot_solution(path: Path, result: "WeftResult", natural: np.ndarray,
                  deformed: np.ndarray) -> Path:
    """PNG of natural (grey) vs deformed loops (centrelines as sampled by the caller) with the
    clamped points (squares) and their reactions (arrows)."""
    title = (f"{result.problem.name} ({result.model}): E = {result.energy.total:.4g}, "
             f"{'converged' if result.success else 'NOT CONVERGED'}")
    held = [(c.position, c.reaction) for c in result.clamps] + [
        (pos, f) for rc in result.rigid_clamps for pos, f in zip(rc.positions, rc.reactions)]
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.add_collection(LineCollection(_course_lines(natural), colors="0.75", linewidths=1.0,
                                     label="natural"))
    colours = plt.cm.viridis(np.linspace(0.05, 0.85, max(len(deformed), 1)))
    ax.add_collection(LineCollection(_course_lines(deformed), colors=colours, linewidths=1.6,
                                     label="deformed"))
    pts = np.array([pos for pos, _ in held]) if held else np.zeros((0, 2))
    if len(pts):
        ax.plot(pts[:, 0], pts[:, 1], "s", color="crimson", ms=7, label="clamp")
        forces = np.array([f for _, f in held])
        size = np.ptp(np.concatenate([natural.reshape(-1, 2), deformed.reshape(-1, 2)]), axis=0).max()
        fmax = np.abs(forces).max()
        if fmax > 0:
            scale = 0.15 * size / fmax
            ax.quiver(pts[:, 0], pts[:, 1], forces[:, 0] * scale, forces[:, 1] * scale,
                      angles="xy", scale_units="xy", scale=1, color="crimson", width=0.006)
            ax.update_datalim(pts + forces * scale)          # keep the arrow tips in view
            ax.plot([], [], color="crimson", label=f"reaction (largest {fmax:.3g})")
    ax.autoscale()
    ax.set_aspect("equal")
    ax.margins(0.08)
    ax.set_title(title, fontsize=10)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_overlay(path: Path, full: np.ndarray, reduced: np.ndarray, title: str) -> Path:
    """PNG of full (thin black) and reduced loops, the reduced ones coloured by the distance
    between corresponding centreline points."""
    fig, ax = plt.subplots(figsize=(7.5, 7))
    ax.add_collection(LineCollection(_course_lines(full), colors="k", linewidths=0.8))
    segs = np.stack([reduced[..., :-1, :], reduced[..., 1:, :]], axis=-2).reshape(-1, 2, 2)
    err = np.linalg.norm(full - reduced, axis=-1)
    err = 0.5 * (err[..., :-1] + err[..., 1:]).ravel()
    lc = LineCollection(segs, array=err, cmap="plasma", linewidths=2.0)
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, label="distance full - reduced")
    ax.autoscale()
    ax.set_aspect("equal")
    ax.margins(0.05)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
