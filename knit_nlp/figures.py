"""Matplotlib figures for result pictures, without pyplot: a library import never switches
matplotlib's backend, and pictures are saved atomically."""
from __future__ import annotations

from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .atomic import atomic_file


def new_figure(**kwargs: Any) -> Figure:
    """A figure drawn by the Agg canvas, leaving pyplot and its backend alone."""
    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def save_figure(fig: Any, path: Path, **savefig_args: Any) -> Path:
    """A matplotlib figure saved atomically; the format is the suffix of ``path``. SVG files
    carry no date, so two runs write the same bytes."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower()
    if fmt == "svg":
        savefig_args.setdefault("metadata", {"Date": None})
    with atomic_file(path) as fh:
        fig.savefig(fh, format=fmt, **savefig_args)
    return path
