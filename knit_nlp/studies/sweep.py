"""Grids over problem-file keys, for ``knit-nlp sweep`` (README, "Sweeps").

An axis is ``KEY=START:STOP:COUNT``: COUNT values evenly spaced from START to STOP. Keys are
named as in the problem file:

- weft: ``material.k_a`` | ``k_b`` | ``R_f``; ``clamp[N].position`` | ``displacement`` (vectors)
  | ``angle``; ``load[N].force`` (vector) | ``moment``; ``rigid_clamp[N].translation`` (vector)
  | ``rotation``. A vector key takes one component (``clamp[2].displacement.x=0:3:4``, the
  other component keeps the file's value) or both (``clamp[2].displacement=0,0:3,1.5:4``, the
  points on the segment between the two vectors). A displacement is from the point's natural
  position whatever the file gives (position or displacement).
- jacquard: ``ground.stiffness`` | ``pretension``;
  ``fall_plate`` | ``inlay`` ``.stiffness`` | ``.pretension`` ``.longitudinal`` | ``thick`` | ``thin``.

``--vary`` axes form a grid of independent points (every combination). ``--path`` axes (weft
only; all with the same COUNT) step together along a loading path, run in order and
warm-started, once per grid point. Every value is checked before anything is solved; a bad key
or range is an :class:`~knit_nlp.errors.ArgumentError` naming the argument (exit code 2).
"""
from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..errors import ArgumentError, ProblemError
from ..jacquard.problem import SYMBOLS, SYSTEMS, JacquardProblem
from ..jacquard.problem import parse_problem as parse_jacquard
from ..weft.model.params import MATERIAL, WeftParams
from ..weft.model.problem import WeftProblem
from .points import set_key
from .runner import LoadPath

NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_AXIS = re.compile(r"^(?P<key>[A-Za-z_][\w.\[\]]*)=(?P<start>[^:]+):(?P<stop>[^:]+):(?P<count>\d+)$")
_INDEXED = re.compile(r"^(clamp|load|rigid_clamp)\[(\d+)\]\.(\w+)(?:\.([xy]))?$")
# weft indexed tables: field -> is it a vector
WEFT_FIELDS = {"clamp": {"position": True, "displacement": True, "angle": False},
               "load": {"force": True, "moment": False},
               "rigid_clamp": {"translation": True, "rotation": False}}
JACQUARD_KEYS = (["ground.stiffness", "ground.pretension"]
                 + [f"{s}.{what}.{kind}" for s in SYSTEMS for what in ("stiffness", "pretension")
                    for kind in ("longitudinal", "thick", "thin")])
MAX_POINTS = 100_000


@dataclass(frozen=True)
class Axis:
    """One ``--vary`` or ``--path`` argument: its key and values (numbers, or [x, y] pairs)."""

    flag: str
    text: str
    key: str
    values: tuple[Any, ...]

    def error(self, message: str) -> ArgumentError:
        return ArgumentError(f"{self.flag} {self.text}", message)


def _number(text: str, axis_error) -> float:
    if not re.fullmatch(NUMBER, text.strip()):
        raise axis_error(f"{text!r} is not a number")
    return float(text)


def parse_axis(flag: str, text: str) -> Axis:
    """``KEY=START:STOP:COUNT`` (START/STOP numbers, or ``X,Y`` pairs for a whole vector)."""
    def bad(message: str) -> ArgumentError:
        return ArgumentError(f"{flag} {text}", message)

    m = _AXIS.match(text)
    if not m:
        raise bad("use KEY=START:STOP:COUNT, e.g. material.k_b=0.01:0.1:4")
    count = int(m["count"])
    if not 1 <= count <= MAX_POINTS:
        raise bad(f"COUNT must be from 1 to {MAX_POINTS}; got {count}")
    ends = []
    for part in (m["start"], m["stop"]):
        pieces = part.split(",")
        if len(pieces) not in (1, 2):
            raise bad(f"{part!r}: a number, or X,Y for a whole vector")
        ends.append(np.array([_number(p, bad) for p in pieces]))
    if ends[0].shape != ends[1].shape:
        raise bad("START and STOP must both be numbers or both X,Y pairs")
    values = [ends[0] + (ends[1] - ends[0]) * (k / (count - 1) if count > 1 else 0.0)
              for k in range(count)]
    plain = tuple(float(v[0]) if v.size == 1 else [float(c) for c in v] for v in values)
    return Axis(flag, text, m["key"], plain)


# -- weft ------------------------------------------------------------------------------------
def _weft_target(axis: Axis, pr: WeftProblem) -> tuple[str, int, str, str | None]:
    """(table, 0-based index, field, component) of a weft key, checked against the problem."""
    if axis.key.startswith("material."):
        name = axis.key[len("material."):]
        if name not in MATERIAL:
            raise axis.error(f"unknown key {axis.key!r}; material keys are "
                             f"{', '.join('material.' + k for k in MATERIAL)}")
        return "material", 0, name, None
    m = _INDEXED.match(axis.key)
    if not m or m[1] not in WEFT_FIELDS or m[3] not in WEFT_FIELDS[m[1]]:
        raise axis.error(f"unknown key {axis.key!r}; use material.k_a|k_b|R_f, "
                         "clamp[N].position|displacement|angle, load[N].force|moment, "
                         "rigid_clamp[N].translation|rotation (vectors may add .x or .y)")
    table, number, fld, comp = m[1], int(m[2]), m[3], m[4]
    count = {"clamp": len(pr.clamps), "load": len(pr.loads),
             "rigid_clamp": len(pr.rigid_clamps)}[table]
    if not 1 <= number <= count:
        raise axis.error(f"{table}[{number}] does not exist: the problem has {count} {table} "
                         f"table(s), numbered from 1")
    vector = WEFT_FIELDS[table][fld]
    if comp and not vector:
        raise axis.error(f"{table}.{fld} is a number; it has no .{comp}")
    pair = isinstance(axis.values[0], list)
    if vector and not comp and not pair:
        raise axis.error(f"{table}.{fld} is a vector: give X,Y ends or add .x or .y to the key")
    if pair and (comp or not vector):
        raise axis.error(f"X,Y ends are for a whole vector key; {axis.key!r} takes numbers")
    return table, number - 1, fld, comp


def weft_changes(pr: WeftProblem, settings: Sequence[tuple[Axis, Any]]) -> dict[str, Any]:
    """``WeftParams.with_`` keyword arguments (JSON-able) setting each axis to its value."""
    own = WeftParams.of(pr)
    targets, forces, rigid = {}, {}, {}
    out: dict[str, dict[str, Any]] = {}
    for axis, value in settings:
        table, q, fld, comp = _weft_target(axis, pr)
        if table == "material":
            out.setdefault("material", {})[fld] = value
        elif fld in ("angle", "moment"):
            out.setdefault("angles" if fld == "angle" else "moments", {})[str(q + 1)] = value
        elif fld == "rotation":
            rigid.setdefault(q, own.rigid[q].copy())[2] = value
        else:
            base = {"clamp": (targets, own.targets), "load": (forces, own.forces),
                    "rigid_clamp": (rigid, own.rigid)}[table]
            vec = base[0].setdefault(q, base[1][q].copy())
            new = np.asarray(value, dtype=float)
            if fld == "displacement":
                c = pr.clamps[q]
                new = pr.natural_position(c.loop, c.s)[[0, 1] if comp is None else
                                                       ["xy".index(comp)]] + new
            vec[[0, 1] if comp is None else ["xy".index(comp)]] = new
    for name, store in (("targets", targets), ("forces", forces), ("rigid", rigid)):
        if store:
            out[name] = {str(q + 1): v.tolist() for q, v in store.items()}
    return out


def _check_weft(pr: WeftProblem, axis: Axis) -> None:
    own = WeftParams.of(pr)
    for value in axis.values:
        try:
            own.with_(**weft_changes(pr, [(axis, value)]))
        except ValueError as err:
            raise axis.error(str(err)) from None


# -- jacquard --------------------------------------------------------------------------------
def shippable_doc(doc: dict[str, Any], pr: JacquardProblem) -> dict[str, Any]:
    """The jacquard document with every design inline (workers read no files)."""
    out = dict(doc)
    code = {"net": 0, "thin": 1, "thick": 2}          # as parse_design codes them
    letter = {code[structure]: symbol for symbol, structure in SYMBOLS.items()}
    for system in pr.systems:
        table = {k: v for k, v in doc[system.name].items()
                 if k not in ("design", "design_file", "design_image")}
        rows = ["".join(letter[int(c)] for c in row) for row in system.codes[::-1]]
        out[system.name] = {**table, "design": "\n".join(rows) + "\n"}
    return out


def _check_jacquard(doc: dict[str, Any], axis: Axis) -> None:
    if axis.key not in JACQUARD_KEYS:
        raise axis.error(f"unknown key {axis.key!r}; jacquard keys are ground.stiffness, "
                         f"ground.pretension, {{{','.join(SYSTEMS)}}}.{{stiffness,pretension}}."
                         f"{{longitudinal,thick,thin}}")
    if isinstance(axis.values[0], list):
        raise axis.error(f"{axis.key!r} takes numbers, not X,Y pairs")
    for value in axis.values:
        try:
            parse_jacquard(set_key(doc, axis.key, value), "<sweep>")
        except ProblemError as err:
            raise axis.error(err.message) from None


# -- the grid --------------------------------------------------------------------------------
def sweep_paths(doc: dict[str, Any], problem: WeftProblem | JacquardProblem,
                vary: Sequence[Axis], path: Sequence[Axis]) -> list[LoadPath]:
    """One :class:`LoadPath` per combination of the ``vary`` values; its points step through
    the ``path`` values together (one point when there are none). Labels map keys to values."""
    if not vary and not path:
        raise ArgumentError("--vary", "give at least one --vary or --path axis")
    keys = [a.key for a in (*vary, *path)]
    twice = sorted({k for k in keys if keys.count(k) > 1})
    if twice:
        raise ArgumentError(f"--vary/--path {twice[0]}", "a key may be varied only once")
    if path and len({len(a.values) for a in path}) > 1:
        raise ArgumentError(f"--path {path[1].text}", "all --path axes step together: give them "
                            "the same COUNT")
    size = int(np.prod([len(a.values) for a in vary])) * (len(path[0].values) if path else 1)
    if size > MAX_POINTS:
        raise ArgumentError("--vary", f"the grid has {size} points; at most {MAX_POINTS}")
    if problem.model == "jacquard":
        if path:
            raise ArgumentError(f"--path {path[0].text}", "jacquard points are independent "
                                "solves (no warm start): use --vary")
        doc = shippable_doc(doc, problem)
        for axis in vary:
            _check_jacquard(doc, axis)
        return [LoadPath(f"p{k:04d}", doc, [{a.key: v for a, v in zip(vary, combo)}],
                         labels=[{a.key: v for a, v in zip(vary, combo)}])
                for k, combo in enumerate(itertools.product(*(a.values for a in vary)))]
    for axis in (*vary, *path):
        _check_weft(problem, axis)
    steps = list(zip(*(a.values for a in path))) if path else [()]
    out = []
    for k, combo in enumerate(itertools.product(*(a.values for a in vary))):
        settings = [[*zip(vary, combo), *zip(path, step)] for step in steps]
        out.append(LoadPath(f"p{k:04d}", doc, [weft_changes(problem, s) for s in settings],
                            problem.parametrisation,
                            labels=[{a.key: v for a, v in s} for s in settings]))
    return out


def study_name(name: str) -> str:
    """A study folder name: letters, digits, ``_ - .``, not starting with a dot."""
    if not re.fullmatch(r"[A-Za-z0-9_\-][A-Za-z0-9_.\-]*", name) or len(name) > 100:
        raise ArgumentError(f"--name {name}", "use letters, digits, '_', '-' and '.' "
                            "(not first), at most 100 characters")
    return name


def output_dir(out: str | Path, name: str) -> Path:
    """``OUT/<name>``: where the study writes (summary, CSV, picture, cache)."""
    return Path(out) / study_name(name)
