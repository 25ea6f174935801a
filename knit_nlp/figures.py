"""Matplotlib figures for result pictures, without pyplot: a library import never switches
matplotlib's backend, and pictures are saved atomically. Every picture is saved through
:func:`save_figure`, which first wraps titles that would not fit inside the image; legends are
built from what was drawn (:func:`legend_below`), so a new kind of artist with a label joins
the key by itself."""
from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.legend import Legend
from matplotlib.text import Text

from .atomic import atomic_file

MARGIN_PX = 4.0          # a title keeps this far from the image's edges


def new_figure(**kwargs: Any) -> Figure:
    """A figure drawn by the Agg canvas, leaving pyplot and its backend alone."""
    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def _wrap(text: Text, width_px: float, renderer: Any) -> None:
    """Rewrap ``text`` (at word boundaries, keeping its own line breaks) until it is at most
    ``width_px`` wide; a single word wider than that is left as it is."""
    original = text.get_text()
    if not original.strip() or text.get_window_extent(renderer).width <= width_px:
        return
    longest = max(len(line) for line in original.splitlines())
    for chars in range(longest - 1, 8, -1):
        text.set_text("\n".join(textwrap.fill(p, chars, break_long_words=False)
                                for p in original.splitlines()))
        if text.get_window_extent(renderer).width <= width_px:
            return


def fit_titles(fig: Figure) -> None:
    """Wrap every axes title and the figure's suptitle so that each lies inside the image: an
    axes title centred over its axes may be as wide as twice the distance from the axes'
    centre to the nearer edge of the image."""
    renderer = fig.canvas.get_renderer()
    engine = fig.get_layout_engine()
    if engine is not None:
        engine.execute(fig)
    width = fig.bbox.width
    for ax in fig.axes:
        box = ax.get_position()
        centre = 0.5 * (box.x0 + box.x1) * width
        for title in (ax.title, ax._left_title, ax._right_title):
            _wrap(title, 2 * min(centre, width - centre) - 2 * MARGIN_PX, renderer)
    if fig._suptitle is not None:
        _wrap(fig._suptitle, width - 2 * MARGIN_PX, renderer)


def settle_layout(fig: Figure, rounds: int = 8) -> None:
    """Wrap the titles (:func:`fit_titles`), run the figure's layout engine until the axes
    stop moving (constrained layout with equal-aspect axes and a tall legend creeps by a few
    pixels per draw) and fix the result: every later draw (the file saved, a reader measuring
    it) has the same layout."""
    engine = fig.get_layout_engine()
    fit_titles(fig)
    if engine is None:
        return
    before = None
    for _ in range(rounds):
        engine.execute(fig)
        now = [ax.get_position().bounds for ax in fig.axes]
        if before is not None and max(abs(a - b) for p, q in zip(now, before)
                                      for a, b in zip(p, q)) < 1e-5:
            break
        before = now
    fig.set_layout_engine("none")


def legend_entries(fig: Figure) -> tuple[list[Any], list[str]]:
    """The handles and labels of every labelled artist drawn in the figure's axes, once per
    label, in drawing order."""
    seen: dict[str, Any] = {}
    for ax in fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(label, handle)
    return list(seen.values()), list(seen)


def legend_below(fig: Figure, fontsize: float = 8, max_columns: int = 3,
                 reserve: float = 0.0) -> Legend | None:
    """One legend for the whole figure, under the axes (constrained layout's "outside lower
    left"), built from what was drawn, in as many columns (up to ``max_columns``) as fit the
    image's width less the fraction ``reserve`` kept free on the right (for a reference
    arrow)."""
    handles, labels = legend_entries(fig)
    if not handles:
        return None
    renderer = fig.canvas.get_renderer()
    legend = None
    for ncol in range(min(max_columns, len(handles)), 0, -1):
        if legend is not None:
            legend.remove()
        legend = fig.legend(handles, labels, loc="outside lower left", ncol=ncol,
                            fontsize=fontsize, frameon=False)
        if legend.get_window_extent(renderer).width <= (1 - reserve) * fig.bbox.width - 2 * MARGIN_PX:
            break
    return legend


def save_figure(fig: Any, path: Path, **savefig_args: Any) -> Path:
    """A matplotlib figure saved atomically, its titles wrapped to fit and its layout settled
    (:func:`settle_layout`); the format is the suffix of ``path``. SVG files carry no date, so two runs write the same
    bytes."""
    path = Path(path)
    fmt = path.suffix.lstrip(".").lower()
    if fmt == "svg":
        savefig_args.setdefault("metadata", {"Date": None})
    if "dpi" in savefig_args and savefig_args["dpi"] != fig.dpi:
        fig.set_dpi(savefig_args["dpi"])
    settle_layout(fig)
    with atomic_file(path) as fh:
        fig.savefig(fh, format=fmt, **savefig_args)
    return path
