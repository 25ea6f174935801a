"""Problem-file keys of a weft problem that a sweep varies, as parameter changes
(``knit-nlp sweep``, docs/studies.md).

Keys are named as in the problem file: ``material.k_a`` | ``k_b`` | ``R_f``;
``clamp[N].position`` | ``displacement`` (vectors) | ``angle``; ``load[N].force`` (vector) |
``moment``; ``rigid_clamp[N].translation`` (vector) | ``rotation``. A vector key takes one
component (``clamp[2].displacement.x``, the other keeps the file's value) or both (values
[x, y]). A displacement is from the point's natural position whatever the file gives.
"""
from __future__ import annotations

import re
from typing import Any, Sequence

import numpy as np

from .model.params import MATERIAL, WeftParams
from .model.problem import WeftProblem

_INDEXED = re.compile(r"^(clamp|load|rigid_clamp)\[(\d+)\]\.(\w+)(?:\.([xy]))?$")
# indexed tables: field -> is it a vector
FIELDS = {"clamp": {"position": True, "displacement": True, "angle": False},
          "load": {"force": True, "moment": False},
          "rigid_clamp": {"translation": True, "rotation": False}}


def _target(key: str, values: Sequence[Any], pr: WeftProblem) -> tuple[str, int, str, str | None]:
    """(table, 0-based index, field, component) of a weft key, checked against the problem;
    ``values`` (numbers, or [x, y] pairs) decide whether a whole vector is meant."""
    if key.startswith("material."):
        name = key[len("material."):]
        if name not in MATERIAL:
            raise ValueError(f"unknown key {key!r}; material keys are "
                             f"{', '.join('material.' + k for k in MATERIAL)}")
        return "material", 0, name, None
    m = _INDEXED.match(key)
    if not m or m[1] not in FIELDS or m[3] not in FIELDS[m[1]]:
        raise ValueError(f"unknown key {key!r}; use material.k_a|k_b|R_f, "
                         "clamp[N].position|displacement|angle, load[N].force|moment, "
                         "rigid_clamp[N].translation|rotation (vectors may add .x or .y)")
    table, number, fld, comp = m[1], int(m[2]), m[3], m[4]
    count = {"clamp": len(pr.clamps), "load": len(pr.loads),
             "rigid_clamp": len(pr.rigid_clamps)}[table]
    if not 1 <= number <= count:
        raise ValueError(f"{table}[{number}] does not exist: the problem has {count} {table} "
                         f"table(s), numbered from 1")
    vector = FIELDS[table][fld]
    if comp and not vector:
        raise ValueError(f"{table}.{fld} is a number; it has no .{comp}")
    pair = isinstance(values[0], list)
    if vector and not comp and not pair:
        raise ValueError(f"{table}.{fld} is a vector: give X,Y ends or add .x or .y to the key")
    if pair and (comp or not vector):
        raise ValueError(f"X,Y ends are for a whole vector key; {key!r} takes numbers")
    return table, number - 1, fld, comp


def changes(pr: WeftProblem, settings: Sequence[tuple[str, Sequence[Any], Any]]) -> dict[str, Any]:
    """``WeftParams.with_`` keyword arguments (JSON-able) setting each key (with all its
    values, to tell vectors from components) to one value."""
    own = WeftParams.of(pr)
    targets, forces, rigid = {}, {}, {}
    out: dict[str, dict[str, Any]] = {}
    for key, values, value in settings:
        table, q, fld, comp = _target(key, values, pr)
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


def check(pr: WeftProblem, doc: dict[str, Any], key: str, values: Sequence[Any]) -> None:
    """``ValueError`` (one line) unless every value of ``key`` is a valid change of ``pr``."""
    own = WeftParams.of(pr)
    for value in values:
        own.with_(**changes(pr, [(key, values, value)]))
