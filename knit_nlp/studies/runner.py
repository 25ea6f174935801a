"""Running a study from the submitting process: paths in parallel, points along a path in order.

:func:`run_study` hands points to any :class:`concurrent.futures.Executor` (a local process pool
by default, Dask with ``open_executor``). The submitting process keeps each path's order: it
submits point k + 1 of a path when point k has returned, with point k's solution as the warm
start. It alone writes the cache (``results/<study>/points/``), from the results workers return,
so workers need no shared disk and a study interrupted anywhere resumes from every point that
came back. ``summary.json`` (rows in path order, no timings) equals an uninterrupted run's.

Failures: a solve that raises or does not converge is a row with ``success`` false. A point whose
worker is lost (crash, or the per-point timeout's watchdog, :mod:`.points`) is rerun alone,
since a lost process pool or a dead Dask worker takes every point it held with it; past its
timeout when alone, or lost ``SOLO_ATTEMPTS`` times alone (a rerun may meet a worker that had
just died), it is recorded as failed with the reason, not cached, and its path goes on from the
last solved point. A broken local pool is replaced by a new one of the same size.
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from collections import deque
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, Executor, Future, wait
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ..api import model_of
from ..atomic import atomic_file
from ..errors import ArgumentError, ProblemError
from ..jsonio import write_json
from ..outdir import prepare_out
from .executors import capacity, local_pool, open_executor
from .points import PointOutcome, PointTask, solve_point, this_process

ABANDON_SLACK_S = 30.0     # beyond the timeout, when an executor that cannot stop a worker is given up on
SOLO_ATTEMPTS = 3          # a point lost this many times when alone is recorded as failed
SOLO_BACKOFF_S = 1.0       # wait before the k-th solo attempt: k times this (workers restart)


@dataclass
class LoadPath:
    """Points solved in order on one problem, each warm-started from the last where the model
    warm-starts (its ``study.warm``; jacquard points are independent solves).

    ``doc`` is the problem as a TOML-like dict (plain data, shipped to workers; it says how the
    problem is solved, e.g. a weft ``[reduction]``); each point is what the model's
    ``study.solve`` takes: for weft a dict of :meth:`WeftParams.with_` keyword arguments
    (JSON-able; clamps, loads and rigid clamps numbered from 1), for jacquard dotted document
    keys -> values.
    """

    name: str
    doc: dict[str, Any]
    points: list[dict[str, Any]]
    labels: list[Any] = field(default_factory=list)


def _key(path: LoadPath, index: int) -> str:
    """A hash of everything that determines a point: the problem (its model and
    parametrisation included) and the path up to it."""
    blob = json.dumps([path.doc, path.points[:index + 1]], sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def read_cached(js: Path, npy: Path) -> tuple[dict[str, Any], np.ndarray] | None:
    """A cached point's result and solution vector, or None if missing or damaged (a study
    killed by an older version mid-write, a disk error): such a point is solved again."""
    try:
        result = json.loads(js.read_text(encoding="utf-8"))
        x = np.load(npy, allow_pickle=False)
    except (OSError, ValueError, EOFError):      # JSONDecodeError and numpy's errors are ValueErrors
        return None
    if not isinstance(result, dict) or not {"success", "status"} <= set(result):
        return None
    if not np.issubdtype(x.dtype, np.floating):
        return None
    return result, x


def point_files(cache: Path, path: LoadPath, index: int) -> tuple[Path, Path]:
    """The cached result JSON and solution vector (.npy) of one point of a path."""
    stem = f"{path.name}.{index:04d}.{_key(path, index)}"
    return cache / f"{stem}.json", cache / f"{stem}.npy"


def point_solution(study_dir: Path, path: LoadPath, index: int) -> np.ndarray | None:
    """The solution vector of a point of a study written under ``study_dir`` (None for a point
    without one: its worker was lost or its solve raised)."""
    npy = point_files(study_dir / "points", path, index)[1]
    return np.load(npy) if npy.exists() else None


def _row(path: LoadPath, index: int, result: dict[str, Any] | None,
         status: str = "", reason: str = "") -> dict[str, Any]:
    """A summary row: the point, and its result's main values (or why it has none)."""
    row = {"path": path.name, "index": index,
           "label": path.labels[index] if index < len(path.labels) else index,
           "point": path.points[index]}
    if result is None:
        return {**row, "success": False, "status": status, "reason": reason}
    row.update(success=result["success"], status=result["status"])
    row.update(model_of(path.doc).study.row(result))
    return row


def print_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[tuple[str, str, str]]) -> None:
    """A study table on one screen: ``columns`` are (key, header, format spec); booleans print as
    ``y`` / ``NO``."""
    cells = [[("y" if r[key] else "NO") if isinstance(r[key], bool) else format(r[key], fmt)
              for key, _, fmt in columns] for r in rows]
    widths = [max([len(head) + 1, 7] + [len(c[k]) + 2 for c in cells])
              for k, (_, head, _) in enumerate(columns)]
    print("".join(f"{head:>{w}}" for (_, head, _), w in zip(columns, widths)))
    for line in cells:
        print("".join(f"{c:>{w}}" for c, w in zip(line, widths)))


class Progress:
    """One line of progress on stderr: count, failures, elapsed time, estimate of the time left."""

    def __init__(self, name: str, total: int, stream=None) -> None:
        self.name, self.total, self.done, self.failed = name, total, 0, 0
        self.t0, self.stream = time.perf_counter(), stream or sys.stderr

    def tick(self, ok: bool = True) -> None:
        self.done += 1
        self.failed += not ok
        el = time.perf_counter() - self.t0
        left = el / self.done * (self.total - self.done)
        end = "\n" if self.done >= self.total else ""
        failed = f" ({self.failed} failed)" if self.failed else ""
        self.stream.write(f"\r{self.name}: {self.done}/{self.total} points{failed}, {el:.1f} s "
                          f"elapsed, ~{left:.1f} s left   {end}")
        self.stream.flush()


@dataclass
class _PathState:
    """Where one path stands: its next point, warm start, rows so far, new solves."""

    path: LoadPath
    next: int = 0
    x: np.ndarray | None = None
    x_changes: dict[str, Any] | None = None   # the point x was solved at
    rows: list[dict[str, Any]] = field(default_factory=list)
    new: int = 0
    busy: bool = False
    solo: int = 0                        # solo attempts of the current point that were lost
    not_before: float = 0.0              # when its next solo attempt may start

    @property
    def warm(self) -> bool:
        return model_of(self.path.doc).study.warm

    def solved(self, x: np.ndarray) -> None:
        """The current point was solved to x: the next one's warm start, with its changes
        (none where the model does not warm-start)."""
        self.x, self.x_changes = (x, self.path.points[self.next]) if self.warm else (None, None)


def _worker_lost(err: BaseException) -> bool:
    """Did the executor lose the worker running the point (a broken local pool, a process
    pool's lost process, a Dask worker that died: ``distributed.KilledWorker``)?"""
    return isinstance(err, BrokenExecutor) or type(err).__name__ == "KilledWorker"


def _one_line(err: BaseException) -> str:
    return f"{type(err).__name__}: {' '.join(str(err).split())}"[:300]


class _Run:
    """The submitting side of one study (module docstring)."""

    def __init__(self, paths: Sequence[LoadPath], cache: Path, executor: Executor, own: bool,
                 timeout: float | None, limit: int | None, progress: Progress,
                 on_point: Callable[[dict[str, Any]], None] | None) -> None:
        self.states = [_PathState(p) for p in paths]
        self.cache, self.executor, self.own = cache, executor, own
        self.timeout, self.limit, self.progress, self.on_point = timeout, limit, progress, on_point
        self.flight: dict[Future, tuple[_PathState, float, bool]] = {}
        self.suspects: deque[_PathState] = deque()
        self.lost_points = 0
        self.submitted = 0

    # -- recording ---------------------------------------------------------------------------
    def _record(self, st: _PathState, row: dict[str, Any]) -> None:
        st.rows.append(row)
        st.next += 1
        st.busy, st.solo = False, 0
        self.progress.tick(bool(row["success"]))
        if self.on_point:
            self.on_point(row)

    def _solved(self, st: _PathState, out: PointOutcome) -> None:
        if out.result is None:
            self._record(st, _row(st.path, st.next, None, "Solve_Error", out.reason))
            return
        js, npy = point_files(self.cache, st.path, st.next)
        with atomic_file(npy) as fh:
            np.save(fh, out.x)
        write_json(js, out.result)          # last: a point counts as cached once its JSON exists
        st.solved(out.x)
        self._record(st, _row(st.path, st.next, out.result))

    def replay_cache(self) -> None:
        """Rows of every point already cached, up to each path's first missing point."""
        for st in self.states:
            while st.next < len(st.path.points):
                cached = read_cached(*point_files(self.cache, st.path, st.next))
                if cached is None:          # missing or damaged: solved (again) from here
                    break
                result, x = cached
                st.solved(x)
                self._record(st, _row(st.path, st.next, result))

    # -- submitting --------------------------------------------------------------------------
    def _ready(self) -> list[_PathState]:
        return [st for st in self.states if not st.busy and st.next < len(st.path.points)
                and (self.limit is None or st.new < self.limit)]

    def _submit(self, st: _PathState, alone: bool) -> None:
        self.submitted += 1
        task = PointTask(st.path.doc, st.path.points[st.next], st.x, self.timeout,
                         this_process(), self.submitted, st.x_changes)
        try:
            fut = self.executor.submit(solve_point, task)
        except BrokenExecutor:          # a local pool that lost a process: replace it
            self._renew()
            fut = self.executor.submit(solve_point, task)
        st.busy, st.new = True, st.new + 1
        self.flight[fut] = (st, time.perf_counter(), alone)

    def _renew(self) -> None:
        """Replace a broken local pool by a new one of the same size."""
        size = capacity(self.executor)
        if self.own:
            self.executor.shutdown(wait=False, cancel_futures=True)
        self.executor, self.own = local_pool(size), True

    def _fill(self) -> None:
        if self.suspects:
            if not self.flight and time.perf_counter() >= self.suspects[0].not_before:
                self._submit(self.suspects.popleft(), alone=True)
            return
        ready = self._ready()
        free = capacity(self.executor) - len(self.flight) if ready else 0
        for st in ready[:max(free, 0)]:
            self._submit(st, alone=False)

    # -- collecting --------------------------------------------------------------------------
    def _lost(self, st: _PathState, started: float, alone: bool, err: BaseException) -> None:
        self.lost_points += 1
        took = time.perf_counter() - started
        timed_out = self.timeout is not None and took >= self.timeout
        st.solo += alone
        if not alone or (not timed_out and st.solo < SOLO_ATTEMPTS):
            # maybe a bystander of another point's loss, or sent to a worker that had just
            # died: rerun it alone, after a pause that lets lost workers restart
            st.new -= 1
            st.not_before = time.perf_counter() + SOLO_BACKOFF_S * st.solo
            self.suspects.append(st)
            return
        if timed_out:
            reason = f"no result within the {self.timeout:g} s per-point timeout; worker stopped"
            status = "Study_Timeout"
        else:
            reason = (f"worker lost {st.solo} times when solving this point alone, last after "
                      f"{took:.1f} s: {_one_line(err)}")[:300]
            status = "Worker_Lost"
        self._record(st, _row(st.path, st.next, None, status, reason))

    def _collect(self, done: set[Future]) -> None:
        for fut in done:
            st, started, alone = self.flight.pop(fut)
            try:
                out = fut.result()
            except Exception as err:   # noqa: BLE001 - the executor's, not the solve's
                if _worker_lost(err):
                    self._lost(st, started, alone, err)
                else:                  # e.g. a cluster without knit_nlp: rerunning won't help
                    self._record(st, _row(st.path, st.next, None, "Executor_Error",
                                          _one_line(err)))
            else:
                self._solved(st, out)

    def _abandon_overdue(self) -> None:
        """Give up on points an executor could not stop (a thread pool): recorded as timed out."""
        if self.timeout is None:
            return
        now = time.perf_counter()
        for fut, (st, started, _) in list(self.flight.items()):
            if now - started > self.timeout + ABANDON_SLACK_S:
                del self.flight[fut]
                self._record(st, _row(st.path, st.next, None, "Study_Timeout",
                                      f"no result within the {self.timeout:g} s per-point "
                                      f"timeout; abandoned (the executor could not stop it)"))

    def run(self) -> None:
        while True:
            self._fill()
            if not self.flight:
                if not self.suspects:
                    return
                time.sleep(max(0.0, self.suspects[0].not_before - time.perf_counter()))
                continue
            done, _ = wait(list(self.flight), timeout=1.0, return_when=FIRST_COMPLETED)
            self._collect(done)
            self._abandon_overdue()


def run_study(name: str, paths: Sequence[LoadPath], out_root: Path = Path("results"),
              workers: int | None = None, limit: int | None = None, *,
              executor: Executor | None = None, timeout: float | None = 600.0,
              on_point: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Run (or resume) a study: paths in parallel, points along a path in order.

    ``executor``: any :class:`concurrent.futures.Executor` (default: a local process pool of
    ``workers`` processes, all cores); ``timeout``: seconds per point before its worker is
    stopped and the point recorded as failed (None: wait for ever); ``limit`` caps the new solves
    per path (for tests of resumption); ``on_point(row)`` is called as each point's row arrives.
    Writes ``out_root/<name>/summary.json`` when every point has a row. Returns the summary.
    """
    out = out_root / name
    cache = out / "points"
    cache.mkdir(parents=True, exist_ok=True)
    progress = Progress(name, sum(len(p.points) for p in paths))
    own = executor is None
    executor = executor or local_pool(workers or max(1, min(len(paths), os.cpu_count() or 1)))
    run = _Run(paths, cache, executor, own, timeout, limit, progress, on_point)
    try:
        run.replay_cache()
        run.run()
    finally:
        if run.own:
            run.executor.shutdown(wait=True, cancel_futures=True)
    rows = [row for st in run.states for row in st.rows]
    complete = len(rows) == progress.total
    summary = {"study": name, "complete": complete, "points": rows}
    if complete:
        write_json(out / "summary.json", summary)
    summary["lost_points"] = run.lost_points
    return summary


def prepare_study(out_root: Path, name: str, files: tuple[str, ...] = ()) -> Path:
    """The study's folder ``out_root/name``, checked and created before anything is solved
    (:func:`~knit_nlp.outdir.prepare_out`): refused in one line if ``summary.json`` or one of
    ``files`` exists there and is not a file, or ``points`` (the cache) is not a folder, so a
    study that could not write its results does not run and leave its cache behind."""
    out = prepare_out(str(out_root / name), name, (), files=("summary.json", *files))
    if (out / "points").exists() and not (out / "points").is_dir():
        raise ProblemError(out_root / name, "", "", "'points' exists and is not a folder; the "
                           "study's cache goes there: remove it or choose another --out")
    return out


def run_with_options(name: str, paths: Sequence[LoadPath], out_root: Path, options: Any,
                     prog: str | None = None) -> dict[str, Any]:
    """:func:`run_study` with the parsed ``--workers/--scheduler/--timeout`` of a study command
    (:func:`~knit_nlp.studies.executors.add_executor_arguments`). A scheduler that cannot be
    reached raises :class:`ArgumentError`, or with ``prog`` (a script's name) is one line
    ``prog: message`` on stderr and exit code 2."""
    workers = options.workers or max(1, min(len(paths), os.cpu_count() or 1))
    try:
        with open_executor(options.scheduler, workers) as executor:
            return run_study(name, paths, out_root, executor=executor, timeout=options.timeout)
    except ArgumentError as err:
        if prog is None:
            raise
        print(f"{prog}: {err}", file=sys.stderr)
        raise SystemExit(2) from None
