"""Jacquard study points (``knit_nlp.studies``, ``knit-nlp sweep``): the document keys a sweep
varies, one point solved from plain data, and its summary row.

Keys are dotted document keys: ``ground.stiffness`` | ``pretension``;
``fall_plate`` | ``inlay`` ``.stiffness`` | ``.pretension`` ``.longitudinal`` | ``thick`` |
``thin``. Every point is an independent solve (no warm start): a point's changes are written
into the document, which is parsed and solved afresh.
"""
from __future__ import annotations

import json
from typing import Any, Sequence

import numpy as np

from ..errors import ProblemError
from ..outcome import Energy
from .api import solve
from .problem import SYMBOLS, SYSTEMS, JacquardProblem, parse_problem

KEYS = (["ground.stiffness", "ground.pretension"]
        + [f"{s}.{what}.{kind}" for s in SYSTEMS for what in ("stiffness", "pretension")
           for kind in ("longitudinal", "thick", "thin")])


def set_key(doc: dict[str, Any], key: str, value: Any) -> dict[str, Any]:
    """A copy of ``doc`` with the dotted table key ``key`` (e.g. ``fall_plate.stiffness.thick``)
    set to ``value``; missing tables are created."""
    out = json.loads(json.dumps(doc))
    *tables, last = key.split(".")
    node = out
    for name in tables:
        node = node.setdefault(name, {})
    node[last] = value
    return out


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


def check(pr: JacquardProblem, doc: dict[str, Any], key: str, values: Sequence[Any]) -> None:
    """``ValueError`` (one line) unless every value of ``key`` makes a valid problem."""
    if key not in KEYS:
        raise ValueError(f"unknown key {key!r}; jacquard keys are ground.stiffness, "
                         f"ground.pretension, {{{','.join(SYSTEMS)}}}.{{stiffness,pretension}}."
                         f"{{longitudinal,thick,thin}}")
    if isinstance(values[0], list):
        raise ValueError(f"{key!r} takes numbers, not X,Y pairs")
    for value in values:
        try:
            parse_problem(set_key(doc, key, value), "<sweep>")
        except ProblemError as err:
            raise ValueError(err.message) from None


def changes(pr: JacquardProblem, settings: Sequence[tuple[str, Sequence[Any], Any]]
            ) -> dict[str, Any]:
    """A point's changes: dotted document key -> value."""
    return {key: value for key, _, value in settings}


def prepare_point(doc: dict[str, Any]) -> dict[str, Any]:
    """Nothing to build ahead: each point parses its own document."""
    return doc


def solve_point(doc: dict[str, Any], changes: dict[str, Any], x0: np.ndarray | None,
                x0_changes: dict[str, Any] | None = None) -> tuple[dict[str, Any], np.ndarray]:
    """One study point: the document with ``changes`` written in, solved by its own method;
    the result JSON and the final positions (``x0`` and ``x0_changes`` are not used: no warm
    start)."""
    for key, value in changes.items():
        doc = set_key(doc, key, value)
    result = solve(parse_problem(doc, f"<study {doc.get('name', '')}>"))
    return result.to_json(), np.asarray(result.positions).ravel()


def study_row(result: dict[str, Any]) -> dict[str, Any]:
    """The values a study summary keeps of a jacquard result JSON (``energy`` read as either
    the Energy object or the plain number older results hold) and ``grips``: each pulled
    edge's reaction, the total force its grip applies to the fabric."""
    return {"energy": Energy.from_json(result["energy"]).to_json(),
            "iterations": result.get("iterations") or result.get("steps"),
            "residual_force": result["residual_force"],
            "grips": {f"{q['edge']} edge": [float(v) for v in q["reaction"]]
                      for q in result.get("pulls", [])}}


def key_unit(problem: JacquardProblem, key: str) -> str:
    """The unit of a sweep key's values: stiffnesses in force per mm, pretensions are ratios."""
    return f"{problem.units.force}/{problem.units.length}" if ".stiffness" in key else "-"

