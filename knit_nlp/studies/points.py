"""What a worker runs: one point of a study, rebuilt from plain data (worker side).

A task is a :class:`PointTask`: the problem as its TOML document (a dict; jacquard designs
inlined), the weft parametrisation, the point's changes, the warm start (the previous point's
solution vector, or None) and the per-point timeout. Nothing else is shipped: no CasADi
object, no file name a worker would have to read. The worker parses the document, builds the
NLP (memoised per process, so a worker that solves several points of one path builds once) and
returns a :class:`PointOutcome`: the result JSON and the solution vector, or a reason.

A watchdog thread ends the worker *process* (``os._exit``) when a point outlives its timeout:
CasADi releases the GIL while IPOPT runs, so the thread fires even inside a solve, and ending
the process is the only way to stop C code. The executor sees a lost worker (a broken local pool,
or Dask's nanny restarting the worker) and the submitting process records the point as failed.
The watchdog is armed only in a process other than the submitter's (never in a thread pool).
"""
from __future__ import annotations

import hashlib
import json
import os
import socket
import threading
import traceback
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..weft.model.parametrisation import Full, Parametrisation

TIMEOUT_EXIT = 86          # the watchdog's exit code (seen in Dask's worker logs)
_STUDIES: "OrderedDict[str, Any]" = OrderedDict()   # per-process memo of built weft NLPs
_MEMO_SIZE = 4


def this_process() -> tuple[str, int]:
    """(host, pid): identifies the submitting process, so workers never kill it."""
    return socket.gethostname(), os.getpid()


@dataclass(frozen=True)
class PointTask:
    """One point to solve. ``changes``: weft, keyword arguments of ``WeftParams.with_``
    (JSON-able, numbered from 1); jacquard, dotted document keys -> values."""

    doc: dict[str, Any]
    changes: dict[str, Any]
    x0: np.ndarray | None = None
    parametrisation: Parametrisation = Full()
    timeout: float | None = None
    submitter: tuple[str, int] = ("", 0)
    attempt: int = 0          # differs on a rerun: Dask keys tasks by their arguments and would
    #                           otherwise hand back the lost attempt's error


@dataclass(frozen=True)
class PointOutcome:
    """A solved point (``result`` the result JSON, ``x`` the solution vector) or a failure
    (``result`` None, ``reason`` one line)."""

    result: dict[str, Any] | None
    x: np.ndarray | None
    reason: str = ""


def _doc_key(doc: dict[str, Any], parametrisation: Parametrisation) -> str:
    blob = json.dumps([doc, repr(parametrisation)], sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()


def weft_study(doc: dict[str, Any], parametrisation: Parametrisation):
    """The process's built :class:`~knit_nlp.weft.study.WeftStudy` of ``doc`` (memoised)."""
    from ..weft.model.problem import parse_problem
    from ..weft.study import WeftStudy

    key = _doc_key(doc, parametrisation)
    if key not in _STUDIES:
        _STUDIES[key] = WeftStudy(parse_problem(doc, f"<study {doc.get('name', '')}>"),
                                  parametrisation)
        while len(_STUDIES) > _MEMO_SIZE:
            _STUDIES.popitem(last=False)
    _STUDIES.move_to_end(key)
    return _STUDIES[key]


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


def _solve_weft(task: PointTask) -> PointOutcome:
    study = weft_study(task.doc, task.parametrisation)
    params = study.params.with_(**task.changes)
    rep = study.solve(params, x0=task.x0)
    return PointOutcome(study.result(rep, params).to_json(), rep.x)


def _solve_jacquard(task: PointTask) -> PointOutcome:
    from ..jacquard.api import solve
    from ..jacquard.problem import parse_problem

    doc = task.doc
    for key, value in task.changes.items():
        doc = set_key(doc, key, value)
    result = solve(parse_problem(doc, f"<study {doc.get('name', '')}>"))
    return PointOutcome(result.to_json(), np.asarray(result.positions).ravel())


def solve_point(task: PointTask) -> PointOutcome:
    """Solve one point; errors raised by the solve come back as a failed outcome. Runs on a
    worker; a point that outlives ``task.timeout`` ends the worker process (module docstring)."""
    watchdog = None
    if task.timeout is not None and this_process() != tuple(task.submitter):
        watchdog = threading.Timer(task.timeout, os._exit, (TIMEOUT_EXIT,))
        watchdog.daemon = True
        watchdog.start()
    try:
        if task.doc.get("model", "weft") == "jacquard":
            return _solve_jacquard(task)
        return _solve_weft(task)
    except Exception as err:  # noqa: BLE001 - any solver error is this point's failure
        last = traceback.format_exception_only(type(err), err)[-1].strip()
        return PointOutcome(None, None, " ".join(last.split()))
    finally:
        if watchdog is not None:
            watchdog.cancel()
