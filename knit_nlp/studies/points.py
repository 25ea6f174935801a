"""What a worker runs: one point of a study, rebuilt from plain data (worker side).

A task is a :class:`PointTask`: the problem as its TOML document (a dict; jacquard designs
inlined), the point's changes, the warm start (the previous point's solution vector and the
changes it was solved at, or None) and the per-point timeout. Nothing else is shipped: no
CasADi object, no file name a worker would have to read. The worker asks the document's model
(``knit_nlp.api.MODELS``, its ``study`` entry) to prepare the document (memoised per process,
so a worker that solves several points of one path builds once: for weft, the transcription
the document's own ``[reduction]`` names) and to solve the point, and returns a
:class:`PointOutcome`: the result JSON and the solution vector, or a reason.

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

from ..api import model_of

TIMEOUT_EXIT = 86          # the watchdog's exit code (seen in Dask's worker logs)
_PREPARED: "OrderedDict[str, Any]" = OrderedDict()   # per-process memo of prepared documents
_MEMO_SIZE = 4


def this_process() -> tuple[str, int]:
    """(host, pid): identifies the submitting process, so workers never kill it."""
    return socket.gethostname(), os.getpid()


@dataclass(frozen=True)
class PointTask:
    """One point to solve. ``changes``: what the model's ``study.solve`` takes (weft, keyword
    arguments of ``WeftParams.with_``, JSON-able, numbered from 1; jacquard, dotted document
    keys -> values)."""

    doc: dict[str, Any]
    changes: dict[str, Any]
    x0: np.ndarray | None = None
    timeout: float | None = None
    submitter: tuple[str, int] = ("", 0)
    attempt: int = 0          # differs on a rerun: Dask keys tasks by their arguments and would
    #                           otherwise hand back the lost attempt's error
    x0_changes: dict[str, Any] | None = None   # the changes x0 was solved at (the last point's)


@dataclass(frozen=True)
class PointOutcome:
    """A solved point (``result`` the result JSON, ``x`` the solution vector) or a failure
    (``result`` None, ``reason`` one line)."""

    result: dict[str, Any] | None
    x: np.ndarray | None
    reason: str = ""


def _prepared(doc: dict[str, Any]) -> Any:
    """The process's prepared document (the model's ``study.prepare``, memoised)."""
    key = hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()
    if key not in _PREPARED:
        _PREPARED[key] = model_of(doc).study.prepare(doc)
        while len(_PREPARED) > _MEMO_SIZE:
            _PREPARED.popitem(last=False)
    _PREPARED.move_to_end(key)
    return _PREPARED[key]


def solve_point(task: PointTask) -> PointOutcome:
    """Solve one point; errors raised by the solve come back as a failed outcome. Runs on a
    worker; a point that outlives ``task.timeout`` ends the worker process (module docstring)."""
    watchdog = None
    if task.timeout is not None and this_process() != tuple(task.submitter):
        watchdog = threading.Timer(task.timeout, os._exit, (TIMEOUT_EXIT,))
        watchdog.daemon = True
        watchdog.start()
    try:
        result, x = model_of(task.doc).study.solve(_prepared(task.doc), task.changes, task.x0,
                                                   task.x0_changes)
        return PointOutcome(result, x)
    except Exception as err:  # noqa: BLE001 - any solver error is this point's failure
        last = traceback.format_exception_only(type(err), err)[-1].strip()
        return PointOutcome(None, None, " ".join(last.split()))
    finally:
        if watchdog is not None:
            watchdog.cancel()
