"""What ``knit-nlp sweep`` writes besides ``summary.json``: one CSV row per point and one
overview picture (energy and, where the rows carry it, each grip's total force on the fabric,
against the first key, in the problem's units)."""
from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..jsonio import write_csv
from ..units import Units

DPI = 100
FAILED = "not converged or lost (drawn at 0)"
STYLES, MARKERS = ("-", "--", ":", "-."), ("o", "s", "^", "D")


def _cell(value: Any) -> Any:
    return " ".join(f"{v:g}" for v in value) if isinstance(value, list) else value


def _clamp_columns(row: dict[str, Any]) -> dict[str, float]:
    out: dict[str, float] = {}
    for q, c in enumerate(row.get("clamps", []), start=1):
        out[f"clamp{q}_reaction_x"], out[f"clamp{q}_reaction_y"] = c["reaction"]
    for q, r in enumerate(row.get("rigid_clamps", []), start=1):
        out[f"rigid_clamp{q}_force_x"], out[f"rigid_clamp{q}_force_y"] = r["force"]
        out[f"rigid_clamp{q}_moment"] = r["moment"]
    return out


def table_rows(summary: dict[str, Any], keys: Sequence[str]) -> list[dict[str, Any]]:
    """One flat row per point: path, index, the varied keys, success, energies, reactions."""
    rows = []
    for r in summary["points"]:
        e = r.get("energy") or {}
        row = {"path": r["path"], "index": r["index"],
               **{k: _cell(r["label"][k]) for k in keys},
               "success": r["success"], "status": r["status"],
               "energy_total": e.get("total", np.nan), "energy_spring": e.get("spring", np.nan),
               "energy_bending": e.get("bending", np.nan),
               "iterations": r.get("iterations", ""), "reason": r.get("reason", "")}
        if "residual_force" in r:
            row["residual_force"] = r["residual_force"]
        rows.append({**row, **_clamp_columns(r)})
    return rows


def write_table(path: Path, rows: list[dict[str, Any]]) -> Path:
    """The CSV (columns: the union of the rows' keys, in order of first appearance)."""
    fields = list(dict.fromkeys(k for r in rows for k in r))
    return write_csv(path, [{k: r.get(k, "") for k in fields} for r in rows], fields)


def grip_force(row: dict[str, Any], grip: str) -> float:
    """The magnitude of a grip's total force on the fabric in a row (NaN: none there)."""
    value = (row.get("grips") or {}).get(grip)
    return np.nan if value is None else float(np.hypot(*value))


def _grip_label(grip: str, where: str, before: Sequence[str], earlier: Sequence[np.ndarray],
                force: np.ndarray, keep: np.ndarray) -> str:
    """A grip's legend label; a grip whose forces equal an earlier grip's at every drawn point
    (to 1e-9 of the largest, e.g. the two clamps of a pull) says that its line lies on that
    one's, drawn over it."""
    label = f"{grip}, {where}" if where else grip
    for other, f in zip(before, earlier):
        a, b = force[keep], f[keep]
        scale = max(float(np.nanmax(np.abs(np.r_[a, b, 0.0]))), 1e-300)
        if len(a) and np.allclose(a, b, rtol=0, atol=1e-9 * scale, equal_nan=True):
            return f"{label} (equal to {other}: its line lies on {other}'s)"
    return label


def _abscissa(values: list[Any]) -> np.ndarray:
    """Numbers as they are; X,Y pairs as the distance from the first."""
    arr = np.array(values, dtype=float)
    return arr if arr.ndim == 1 else np.linalg.norm(arr - arr[0], axis=1)


def plot_overview(path: Path, summary: dict[str, Any], keys: Sequence[str], title: str,
                  units: Units | None = None, key_units: dict[str, str] | None = None) -> Path:
    """Energy and, where the rows carry grips, the magnitude of each grip's total force on the
    fabric (a shorthand table's points summed: an edge clamp is one grip) against the first
    key, one line per grip and combination of the other keys; points that did not converge
    (or were lost) as crosses on the axis. ``units``: the problem's; ``key_units``: the unit
    of each key's values."""
    from ..figures import new_figure, save_figure     # matplotlib (0.4 s) only when drawing
    units, key_units = units or Units(), key_units or {}
    rows = summary["points"]
    grips = list(dict.fromkeys(g for r in rows for g in (r.get("grips") or {})))
    fig = new_figure(figsize=(11 if grips else 6.5, 4.8), dpi=DPI, layout="constrained")
    axes = fig.subplots(1, 2 if grips else 1, squeeze=False)[0]
    x_key, others = keys[0], keys[1:]
    group = lambda r: tuple(str(r["label"][k]) for k in others)  # noqa: E731
    combinations = [(name, list(members)) for name, members in
                    itertools.groupby(sorted(rows, key=group), key=group)]
    for combination, (name, members) in enumerate(combinations):
        x = _abscissa([r["label"][x_key] for r in members])
        ok = np.array([bool(r["success"]) for r in members])
        order = np.argsort(x, kind="stable")
        keep = order[ok[order]]
        where = ", ".join(f"{k} = {v}" for k, v in zip(others, name))
        series = [(axes[0], [r["energy"]["total"] if "energy" in r else np.nan for r in members],
                   where or "stored energy", 0)]
        forces = [np.array([grip_force(r, g) for r in members]) for g in grips]
        series += [(axes[1], f, _grip_label(g, where, grips[:k], forces[:k], f, keep), k)
                   for k, (g, f) in enumerate(zip(grips, forces))]
        for ax, y, label, style in series:
            # one colour per combination of the other keys, one line style and marker per grip;
            # with a single combination, one colour per grip as well
            colour = f"C{(combination if len(combinations) > 1 else style) % 10}"
            ax.plot(x[keep], np.asarray(y, dtype=float)[keep], color=colour, label=label,
                    ls=STYLES[style % len(STYLES)], marker=MARKERS[style % len(MARKERS)],
                    ms=6 - style % len(MARKERS), mfc="none" if style else colour,
                    zorder=2 + style)
            if (~ok).any():
                ax.plot(x[~ok], np.zeros((~ok).sum()), "x", color=colour, ms=9, mew=2,
                        label=FAILED)
    is_pair = isinstance(rows[0]["label"][x_key], list)
    unit = key_units.get(x_key, "")
    xlabel = (f"{x_key}: distance from the first value" if is_pair else x_key) + \
        (f" [{unit}]" if unit else "")
    axes[0].set(xlabel=xlabel, ylabel=f"stored energy [{units.energy}]", title="energy")
    if grips:
        axes[1].set(xlabel=xlabel, ylabel=f"|total force of the grip on the fabric| [{units.force}]",
                    title="each grip's total force (a table's points summed)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.title.set_fontsize(10)
        entries = dict(zip(*reversed(ax.get_legend_handles_labels())))    # label -> handle
        if len(entries) > 1 or grips:
            ax.legend(list(entries.values()), list(entries), fontsize=7)
    fig.suptitle(title, fontsize=10)
    return save_figure(fig, path, dpi=DPI)
