"""What ``knit-nlp sweep`` writes besides ``summary.json``: one CSV row per point and one
overview picture (energy, and where the rows carry it the largest clamp force, against the
first key)."""
from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..figures import new_figure, save_figure
from ..jsonio import write_csv


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


def largest_force(row: dict[str, Any]) -> float:
    """The largest clamp reaction or rigid-clamp force magnitude of a row (NaN: none)."""
    value = row.get("largest_force")
    return np.nan if value is None else float(value)


def _abscissa(values: list[Any]) -> np.ndarray:
    """Numbers as they are; X,Y pairs as the distance from the first."""
    arr = np.array(values, dtype=float)
    return arr if arr.ndim == 1 else np.linalg.norm(arr - arr[0], axis=1)


def plot_overview(path: Path, summary: dict[str, Any], keys: Sequence[str], title: str) -> Path:
    """Energy (and, where the rows carry it, the largest clamp force) against the first key,
    one line per combination of the other keys; failed points as crosses on the axis."""
    rows = summary["points"]
    forces = any(r.get("largest_force") is not None for r in rows)
    fig = new_figure(figsize=(11 if forces else 6, 4.3))
    axes = fig.subplots(1, 2 if forces else 1, squeeze=False)
    x_key, others = keys[0], keys[1:]
    group = lambda r: tuple(str(r["label"][k]) for k in others)  # noqa: E731
    for name, members in itertools.groupby(sorted(rows, key=group), key=group):
        members = list(members)
        x = _abscissa([r["label"][x_key] for r in members])
        ok = np.array([bool(r["success"]) for r in members])
        label = ", ".join(f"{k} = {v}" for k, v in zip(others, name)) or None
        ys = [[r["energy"]["total"] if "energy" in r else np.nan for r in members]]
        if forces:
            ys.append([largest_force(r) for r in members])
        for ax, y in zip(axes[0], ys):
            order = np.argsort(x, kind="stable")
            y = np.array(y, dtype=float)
            line, = ax.plot(x[order][ok[order]], y[order][ok[order]], "o-", ms=4, label=label)
            ax.plot(x[~ok], np.zeros((~ok).sum()), "x", color=line.get_color(), ms=9, mew=2)
    is_pair = isinstance(rows[0]["label"][x_key], list)
    xlabel = f"{x_key} (distance from the first value)" if is_pair else x_key
    axes[0, 0].set(xlabel=xlabel, ylabel="stored energy", title="energy")
    if forces:
        axes[0, 1].set(xlabel=xlabel, ylabel="|force|", title="largest clamp force on the fabric")
    for ax in axes[0]:
        ax.grid(alpha=0.3)
        if others:
            ax.legend(fontsize=7)
    fig.suptitle(f"{title} (x on the axis: not converged or lost)", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path, dpi=100)
