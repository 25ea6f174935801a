"""The control keys of a weft problem file (docs/inverse.md, "Deformation control").

``actuated``/``bounds`` on ``[[clamp]]``, ``actuated``/``translation_bounds``/``rotation_bounds``
on ``[[rigid_clamp]]``, ``[[goal]]``, ``[[opening]]`` and ``[control]``. They are read here and
stripped before the rest of the file goes to the forward reader (weft.problem), so the forward
problem is exactly the file's, with the actuated targets at their start values.
"""
from __future__ import annotations

import copy
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...tomlio import Table, load_toml
from ..model.problem import WeftProblem, PointReader, parse_problem
from ..model.reach import yarn_between

CLAMP_KEYS = ("actuated", "bounds")
RIGID_KEYS = ("actuated", "translation_bounds", "rotation_bounds")
TOP_KEYS = ("goal", "opening", "control")


@dataclass(frozen=True)
class Actuated:
    """One actuated clamp (2 unknowns: the target) or rigid clamp (3: translation, rotation).

    ``index`` is 0-based among the problem's clamp points (kind "clamp") or rigid clamps (kind
    "rigid"); ``table`` the file's table number, from 1 (what results and messages name: a
    course, wale or edge shorthand makes several points from one table); ``lower``/``upper``
    bound each unknown (±inf when not given)."""

    kind: str
    index: int
    lower: np.ndarray
    upper: np.ndarray
    table: int = 0

    @property
    def size(self) -> int:
        return 2 if self.kind == "clamp" else 3


@dataclass(frozen=True)
class Goal:
    """Where a material point should end up: ``target`` in the coordinates ``fix`` selects."""

    loop: tuple[int, int]
    point: str | float
    s: float
    target: np.ndarray
    fix: tuple[bool, bool]
    weight: float


@dataclass(frozen=True)
class Opening:
    """Two material points ((loop, label, s) each) to be kept at least ``at_least`` apart."""

    points: tuple[tuple[tuple[int, int], str | float, float], ...]
    at_least: float


@dataclass(frozen=True)
class ControlProblem:
    """A forward problem plus what the control command optimises."""

    problem: WeftProblem
    actuated: tuple[Actuated, ...]
    goals: tuple[Goal, ...]
    openings: tuple[Opening, ...]
    travel_weight: float


def has_control_keys(doc: dict[str, Any]) -> bool:
    """Whether a parsed problem file uses any key of the control contract."""
    return (any(k in doc for k in TOP_KEYS)
            or any(isinstance(t, dict) and any(k in t for k in CLAMP_KEYS)
                   for t in _as_list(doc.get("clamp")))
            or any(isinstance(t, dict) and any(k in t for k in RIGID_KEYS)
                   for t in _as_list(doc.get("rigid_clamp"))))


def strip_control_keys(doc: dict[str, Any]) -> dict[str, Any]:
    """A copy of the document without the control keys: the forward problem at the start."""
    out = copy.deepcopy(doc)
    for key in TOP_KEYS:
        out.pop(key, None)
    for table, keys in (("clamp", CLAMP_KEYS), ("rigid_clamp", RIGID_KEYS)):
        for t in _as_list(out.get(table)):
            if isinstance(t, dict):
                for k in keys:
                    t.pop(k, None)
    return out


def _as_list(value: Any) -> list[Any]:
    return value if isinstance(value, list) else []


def load_control(path: Path | str) -> ControlProblem:
    """Read and check a control problem file."""
    return parse_control(Path(path), load_toml(Path(path)))


def parse_control(path: Path | str, doc: dict[str, Any]) -> ControlProblem:
    """Check the control keys and the forward problem; bad input raises ProblemError."""
    pr = parse_problem(strip_control_keys(doc), path)
    top = Table(doc, path, "")
    actuated = [a for k, t in enumerate(top.tables("clamp")) if (a := _read_actuated_clamp(t, k, pr))]
    actuated += [a for k, t in enumerate(top.tables("rigid_clamp")) if (a := _read_actuated_rigid(t, k, pr))]
    points = PointReader(pr.courses, pr.wales, pr.natural, pr.crossings)
    goals = tuple(_read_goal(t, points, pr) for t in top.tables("goal"))
    openings = tuple(_read_opening(t, points) for t in top.tables("opening"))
    ctl = top.table("control")
    travel = ctl.number("travel_weight", 0.0, nonnegative=True)
    ctl.finish()
    if not actuated:
        raise top.error("clamp", "a control problem needs at least one clamp or rigid_clamp "
                        "with actuated = true")
    if not goals and not openings:
        raise top.error("goal", "a control problem needs at least one [[goal]] or [[opening]]")
    return ControlProblem(pr, tuple(actuated), goals, openings, travel)


def note_ignored_reduction(path: Path | str, pr: WeftProblem, command: str) -> None:
    """One stderr line when a file for ``control`` or ``fit`` has a [reduction] table: their
    equilibrium (equilibrium.py) is the full model's, so the table changes nothing."""
    if pr.reduction is not None:
        print(f"knit-nlp: {path}: [reduction] ignored: {command} solves the full model "
              "(docs/inverse.md)", file=sys.stderr)


def _box(tab: Table, key: str, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[[lo, hi], ...] bounds, one pair per coordinate, containing the start value."""
    value = tab.value(key, None)
    if value is None:
        return np.full(len(start), -np.inf), np.full(len(start), np.inf)
    if not isinstance(value, list) or len(value) != len(start) or not all(
            isinstance(v, list) and len(v) == 2 for v in value):
        raise tab.error(key, f"expected {len(start)} pairs [min, max]")
    pairs = np.array([Table({key: v}, tab.file, tab.name).numbers(key, length=2) for v in value])
    lo, hi = pairs[:, 0], pairs[:, 1]
    if np.any(lo > hi):
        raise tab.error(key, "a lower bound exceeds its upper bound")
    if np.any(start < lo) or np.any(start > hi):
        raise tab.error(key, f"the start value {start.round(6).tolist()} lies outside the bounds")
    return lo, hi


def _actuated_flag(tab: Table) -> bool:
    value = tab.value("actuated", False)
    if not isinstance(value, bool):
        raise tab.error("actuated", "expected true or false")
    return value


def _read_actuated_clamp(tab: Table, k: int, pr: WeftProblem) -> Actuated | None:
    if not _actuated_flag(tab):
        if tab.has("bounds"):
            raise tab.error("bounds", "bounds apply to an actuated clamp only (actuated = true)")
        return None
    made = pr.tables("clamp")[k]
    if len(made) != 1:
        raise tab.error("actuated", f"grips {len(made)} points (a course, wale or edge); an "
                        "actuated clamp moves one point: to move a whole course, wale or edge, "
                        "make it a [[rigid_clamp]] with actuated = true")
    clamp = pr.clamps[made[0]]
    if not all(clamp.fix):
        raise tab.error("actuated", "an actuated clamp must hold both x and y (fix = [\"x\", \"y\"])")
    lo, hi = _box(tab, "bounds", clamp.target)
    return Actuated("clamp", made[0], lo, hi, k + 1)


def _read_actuated_rigid(tab: Table, k: int, pr: WeftProblem) -> Actuated | None:
    if not _actuated_flag(tab):
        for key in ("translation_bounds", "rotation_bounds"):
            if tab.has(key):
                raise tab.error(key, "bounds apply to an actuated rigid clamp only (actuated = true)")
        return None
    rc = pr.rigid_clamps[k]
    lo_t, hi_t = _box(tab, "translation_bounds", rc.translation)
    if tab.has("rotation_bounds"):
        lo_r, hi_r = tab.numbers("rotation_bounds", length=2)
        if lo_r > hi_r or not lo_r <= rc.rotation <= hi_r:
            raise tab.error("rotation_bounds", "must be [min, max] around the start rotation")
    else:
        lo_r, hi_r = -np.inf, np.inf
    return Actuated("rigid", k, np.r_[lo_t, lo_r], np.r_[hi_t, hi_r], k + 1)


def _read_goal(tab: Table, points: PointReader, pr: WeftProblem) -> Goal:
    tab.allow("loop", "point", "position", "displacement", "fix", "weight")
    loop = points.loop(tab)
    label, s = points.point(tab)
    if tab.has("position") == tab.has("displacement"):
        raise tab.error("position", "give exactly one of position and displacement")
    if tab.has("position"):
        target = np.array(tab.numbers("position", length=2))
    else:
        target = pr.natural_position(loop, s) + np.array(tab.numbers("displacement", length=2))
    fix = tab.strings("fix", ["x", "y"], choices=("x", "y"))
    if not fix or len(set(fix)) != len(fix):
        raise tab.error("fix", "must list x and/or y, each once")
    weight = tab.number("weight", 1.0, positive=True)
    tab.finish()
    return Goal(loop, label, s, target, ("x" in fix, "y" in fix), weight)


def _read_opening(tab: Table, points: PointReader) -> Opening:
    tab.allow("points", "at_least")
    pts = []
    for sub in tab.tables("points"):
        sub.name = f"{tab.name}.{sub.name}"
        sub.allow("loop", "point")
        loop = points.loop(sub)
        label, s = points.point(sub)
        sub.finish()
        pts.append((loop, label, s))
    if len(pts) != 2:
        raise tab.error("points", f"an opening needs exactly two points, got {len(pts)}")
    at_least = tab.number("at_least", positive=True)
    (la, _, sa), (lb, _, sb) = pts
    yarn = yarn_between((la, sa), (lb, sb), points.natural.length)   # one course: inextensible
    if yarn is not None and at_least > yarn:
        raise tab.error("at_least", f"{at_least:g} is out of reach: the two points lie on "
                        f"course {la[0]} with {yarn:.6g} of inextensible yarn between them, "
                        f"so no grip can open them wider; ask for at most {yarn:.6g}")
    tab.finish()
    return Opening(tuple(pts), at_least)
