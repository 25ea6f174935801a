"""Grids over problem-file keys, for ``knit-nlp sweep`` (docs/studies.md).

An axis is ``KEY=START:STOP:COUNT``: COUNT values evenly spaced from START to STOP, numbers or
``X,Y`` pairs for a whole vector (the points on the segment between the two vectors). Which keys
exist and what a point's changes are is the problem's model's (``knit_nlp.api.MODELS``, its
``study.check`` and ``study.changes``: ``knit_nlp.weft.keys``, ``knit_nlp.jacquard.study``).

``--vary`` axes form a grid of independent points (every combination). ``--path`` axes (models
that warm-start, all with the same COUNT) step together along a loading path, run in order and
warm-started, once per grid point. Every value is checked before anything is solved; a bad key
or range is an :class:`~knit_nlp.errors.ArgumentError` naming the argument (exit code 2).
"""
from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..api import Problem, model_of
from ..errors import ArgumentError
from .runner import LoadPath

NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_AXIS = re.compile(r"^(?P<key>[A-Za-z_][\w.\[\]]*)=(?P<start>[^:]+):(?P<stop>[^:]+):(?P<count>\d+)$")
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
    if not math.isfinite(float(text)):
        raise axis_error(f"{text.strip()!r} is not finite (beyond the largest float, about "
                         "1.8e308); give a finite number")
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
    with np.errstate(over="ignore", invalid="ignore"):   # -1e308:1e308: the step overflows
        values = [ends[0] + (ends[1] - ends[0]) * (k / (count - 1) if count > 1 else 0.0)
                  for k in range(count)]
    if not all(np.isfinite(v).all() for v in values):
        raise bad("the values from START to STOP are not all finite numbers; use a smaller range")
    plain = tuple(float(v[0]) if v.size == 1 else [float(c) for c in v] for v in values)
    return Axis(flag, text, m["key"], plain)


# -- the grid --------------------------------------------------------------------------------
def sweep_paths(doc: dict[str, Any], problem: Problem, vary: Sequence[Axis],
                path: Sequence[Axis]) -> list[LoadPath]:
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
    model = model_of(doc)
    if path and not model.study.warm:
        raise ArgumentError(f"--path {path[0].text}", f"{model.name} points are independent "
                            "solves (no warm start): use --vary")
    doc = model.study.ship(doc, problem)
    for axis in (*vary, *path):
        try:
            model.study.check(problem, doc, axis.key, axis.values)
        except ValueError as err:
            raise axis.error(str(err)) from None
    steps = list(zip(*(a.values for a in path))) if path else [()]
    out = []
    for k, combo in enumerate(itertools.product(*(a.values for a in vary))):
        settings = [[*zip(vary, combo), *zip(path, step)] for step in steps]
        out.append(LoadPath(f"p{k:04d}", doc,
                            [model.study.changes(problem, [(a.key, a.values, v) for a, v in s])
                             for s in settings],
                            labels=[{a.key: v for a, v in s} for s in settings]))
    return out


def study_name(name: str) -> str:
    """A study folder name: letters, digits, ``_ - .``, not starting with a dot."""
    if not re.fullmatch(r"[A-Za-z0-9_\-][A-Za-z0-9_.\-]*", name) or len(name) > 100:
        raise ArgumentError(f"--name {name}", "use letters, digits, '_', '-' and '.' "
                            "(not first), at most 100 characters")
    return name
