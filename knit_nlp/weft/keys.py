"""Problem-file keys of a weft problem that a sweep varies, as parameter changes
(``knit-nlp sweep``, docs/studies.md).

Keys are named as in the problem file: ``material.k_a`` | ``k_b`` | ``R_f``;
``clamp[N].position`` | ``displacement`` (vectors) | ``angle``; ``load[N].force`` (vector) |
``moment``; ``rigid_clamp[N].translation`` (vector) | ``rotation``. A vector key takes one
component (``clamp[2].displacement.x``, the other keeps the file's value) or both (values
[x, y]). A displacement is from the point's natural position whatever the file gives.

``N`` numbers the file's tables as the file does (the second ``[[clamp]]`` is ``clamp[2]``),
whether a table names one point or a course, wale or edge: a key into a shorthand table changes
every point it made (each point's displacement, angle, force or moment; a ``position`` would
stack them and is refused, as in the file).
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


def _points(pr: WeftProblem, table: str, number: int) -> list[int]:
    """0-based indices, among the problem's points of ``table`` (clamps, loads or rigid clamps),
    of the points the file's ``table[number]`` made; ``ValueError`` when it has no such table."""
    made = pr.tables(table)
    if not 1 <= number <= len(made):
        raise ValueError(f"{table}[{number}] does not exist: the problem file has {len(made)} "
                         f"[[{table}]] table(s), numbered from 1 in file order")
    return made[number - 1]


def _target(key: str, values: Sequence[Any],
            pr: WeftProblem) -> tuple[str, list[int], str, str | None]:
    """(table, 0-based point indices, field, component) of a weft key, checked against the
    problem; ``values`` (numbers, or [x, y] pairs) decide whether a whole vector is meant."""
    if key.startswith("material."):
        name = key[len("material."):]
        if name not in MATERIAL:
            raise ValueError(f"unknown key {key!r}; material keys are "
                             f"{', '.join('material.' + k for k in MATERIAL)}")
        return "material", [0], name, None
    m = _INDEXED.match(key)
    if not m or m[1] not in FIELDS or m[3] not in FIELDS[m[1]]:
        raise ValueError(f"unknown key {key!r}; use material.k_a|k_b|R_f, "
                         "clamp[N].position|displacement|angle, load[N].force|moment, "
                         "rigid_clamp[N].translation|rotation (vectors may add .x or .y)")
    table, number, fld, comp = m[1], int(m[2]), m[3], m[4]
    points = _points(pr, table, number)
    if fld == "position" and len(points) > 1:
        raise ValueError(f"{table}[{number}] grips {len(points)} points (a course, wale or "
                         f"edge): one position would stack them; vary {table}[{number}]"
                         ".displacement instead")
    vector = FIELDS[table][fld]
    if comp and not vector:
        raise ValueError(f"{table}.{fld} is a number; it has no .{comp}")
    pair = isinstance(values[0], list)
    if vector and not comp and not pair:
        raise ValueError(f"{table}.{fld} is a vector: give X,Y ends or add .x or .y to the key")
    if pair and (comp or not vector):
        raise ValueError(f"X,Y ends are for a whole vector key; {key!r} takes numbers")
    return table, points, fld, comp


def changes(pr: WeftProblem, settings: Sequence[tuple[str, Sequence[Any], Any]]) -> dict[str, Any]:
    """``WeftParams.with_`` keyword arguments (JSON-able) setting each key (with all its
    values, to tell vectors from components) to one value."""
    own = WeftParams.of(pr)
    targets, forces, rigid = {}, {}, {}
    out: dict[str, dict[str, Any]] = {}
    for key, values, value in settings:
        table, points, fld, comp = _target(key, values, pr)
        for q in points:
            _set(pr, own, out, (targets, forces, rigid), (table, q, fld, comp), value)
    for name, store in (("targets", targets), ("forces", forces), ("rigid", rigid)):
        if store:
            out[name] = {str(q + 1): v.tolist() for q, v in store.items()}
    return out


def _set(pr: WeftProblem, own: WeftParams, out: dict[str, Any],
         stores: tuple[dict[int, np.ndarray], ...], where: tuple[str, int, str, str | None],
         value: Any) -> None:
    """Record one point's change (``where``: table, 0-based point, field, component) in ``out``
    (numbers) or in ``stores`` (targets, forces, rigid motions, filled from the file's values)."""
    targets, forces, rigid = stores
    table, q, fld, comp = where
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


def check(pr: WeftProblem, doc: dict[str, Any], key: str, values: Sequence[Any]) -> None:
    """``ValueError`` (one line) unless every value of ``key`` is a valid change of ``pr``."""
    own = WeftParams.of(pr)
    for value in values:
        own.with_(**changes(pr, [(key, values, value)]))
