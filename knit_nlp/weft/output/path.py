"""A loading path (the steps of a continuation solve) as force against displacement per grip.

A grip is a clamp, the clamps one shorthand table made (``clamp[3]``: displacements averaged,
reactions summed) or a rigid clamp (its translation, its total force). Step 0 is the natural
state, an equilibrium with zero reactions by construction (WeftParams.natural).
"""
from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ...jsonio import write_csv
from ..model.problem import WeftProblem
from .plot import plot_force_displacement
from .reactions import SolvedFabric

FIELDS = ("step", "load_factor", "grip", "points", "displacement_x", "displacement_y",
          "force_x", "force_y", "distance", "force_along_pull", "energy_total")


def _grips(r: SolvedFabric) -> dict[str, tuple[int, np.ndarray, np.ndarray]]:
    """grip name -> (points, displacement, force on the fabric) at one result."""
    members: dict[str, list[tuple[np.ndarray, np.ndarray]]] = defaultdict(list)
    for c in r.clamps:
        moved = c.target - r.problem.natural_position(c.loop, r.problem.clamps[c.number - 1].s)
        members[c.group or c.grip].append((moved, c.reaction))
    out = {name: (len(ms), np.mean([m for m, _ in ms], axis=0), np.sum([f for _, f in ms], axis=0))
           for name, ms in members.items()}
    for rc in r.rigid_clamps:
        out[f"rigid clamp {rc.number}"] = (len(rc.points), rc.translation.copy(), rc.force)
    return out


def path_rows(steps: Sequence[tuple[float, SolvedFabric]]) -> list[dict[str, Any]]:
    """One row per grip per step of a loading path ((load factor, solution) per step; step 0,
    the natural state, is added); ``distance`` and ``force_along_pull`` are along the grip's
    final displacement (blank for a grip that holds still)."""
    if not steps:
        return []
    final = _grips(steps[-1][1])
    rows = [_row(0, 0.0, name, k, np.zeros(2), np.zeros(2), final[name][1], 0.0)
            for name, (k, _, _) in final.items()]
    for number, (tau, r) in enumerate(steps, start=1):
        for name, (k, moved, force) in _grips(r).items():
            rows.append(_row(number, tau, name, k, moved, force, final[name][1], r.energy.total))
    return rows


def _row(step: int, tau: float, name: str, k: int, moved: np.ndarray, force: np.ndarray,
         final_move: np.ndarray, energy: float) -> dict[str, Any]:
    norm = float(np.hypot(*final_move))
    unit = final_move / norm if norm > 0 else None
    return {"step": step, "load_factor": tau, "grip": name, "points": k,
            "displacement_x": moved[0], "displacement_y": moved[1],
            "force_x": force[0], "force_y": force[1],
            "distance": "" if unit is None else float(moved @ unit),
            "force_along_pull": "" if unit is None else float(force @ unit),
            "energy_total": energy}


def write_path(stem: Path, problem: WeftProblem,
               steps: Sequence[tuple[float, SolvedFabric]]) -> list[Path]:
    """``<stem>.path.csv`` and its force-displacement picture ``<stem>.path.png``; nothing for
    an empty path (a direct solve)."""
    rows = path_rows(steps)
    if not rows:
        return []
    csv = write_csv(stem.with_name(stem.name + ".path.csv"), rows, FIELDS)
    png = plot_force_displacement(stem.with_name(stem.name + ".path.png"), rows,
                                  problem.units, problem.name)
    return [csv, png]
