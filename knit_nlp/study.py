"""Studies: one NLP built once and re-solved for many clamp targets or material values.

- :class:`WeftStudy` builds a weft problem's NLP once; :meth:`WeftStudy.params` turns named
  changes (clamp targets or displacements, rigid-clamp motions, material values, loads) into the
  NLP's parameter vector; :meth:`WeftStudy.solve` re-solves, warm-started from a given point.
- :func:`run_study` runs named loading paths: points along one path run in order, each
  warm-started from the last; independent paths run in parallel processes. Each point's result
  is cached under ``results/<study>/points/``, so an interrupted study resumes where it stopped;
  ``summary.json`` collects every point (no timings, so a resumed study's summary equals an
  uninterrupted one's). One line of progress shows count, elapsed time and an estimate.
"""
from __future__ import annotations

import csv
import hashlib
import json
import multiprocessing as mp
import os
import queue as queue_errors
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .atomic import atomic_file
from .errors import ProblemError, quoted
from .jsonio import write_json
from .tomlio import finite_number
from .weft.nlp import build_nlp
from .weft.problem import WeftProblem, parse_problem
from .weft.results import result_dict
from .weft.solve import SolveReport, WeftSolver, solve


class WeftStudy:
    """A weft problem's NLP, built once and re-solved for many parameter values."""

    def __init__(self, problem: WeftProblem, reduced: bool = False) -> None:
        t0 = time.perf_counter()
        self.problem = problem
        self.wnlp = build_nlp(problem, reduced=reduced)
        self.solver = WeftSolver(self.wnlp)
        self.build_s = time.perf_counter() - t0
        self.builds = 1

    def params(self, targets: Mapping[int, Sequence[float]] | None = None,
               displacements: Mapping[int, Sequence[float]] | None = None,
               rigid: Mapping[int, Sequence[float]] | None = None,
               material: Mapping[str, float] | None = None,
               forces: Mapping[int, Sequence[float]] | None = None,
               moments: Mapping[int, float] | None = None) -> np.ndarray:
        """The parameter vector with the problem's values changed where named.

        ``targets`` / ``displacements``: clamp index -> absolute target / displacement from the
        natural position; ``rigid``: rigid-clamp index -> (tx, ty, rotation); ``material``:
        any of k_a, k_b, R_f; ``forces`` / ``moments``: load index -> value.
        """
        pr, pl = self.problem, self.wnlp.p
        p = self.wnlp.p0.copy()
        tgt = pl.get(p, "targets")
        for k, v in (targets or {}).items():
            tgt[:, self._index(k, pr.clamps, "clamp")] = self._values(v, 2, "clamp", "position")
        for k, v in (displacements or {}).items():
            c = pr.clamps[self._index(k, pr.clamps, "clamp")]
            tgt[:, int(k)] = (pr.natural_position(c.loop, c.s)
                              + self._values(v, 2, "clamp", "displacement"))
        pl.put(p, "targets", tgt)
        rig = pl.get(p, "rigid")
        for k, v in (rigid or {}).items():
            rig[:, self._index(k, pr.rigid_clamps, "rigid_clamp")] = self._values(
                v, 3, "rigid_clamp", "translation, rotation")
        pl.put(p, "rigid", rig)
        for name, v in (material or {}).items():
            if name not in ("k_a", "k_b", "R_f"):
                raise self._error("material", str(name), "unknown material value (allowed: "
                                  "k_a, k_b, R_f)")
            value = self._values([v], 1, "material", name)[0]
            if value < 0:
                raise self._error("material", name, f"must not be negative, got {value:g}")
            pl.put(p, name, value)
        f = pl.get(p, "forces")
        for k, v in (forces or {}).items():
            f[:, self._index(k, pr.loads, "load")] = self._values(v, 2, "load", "force")
        pl.put(p, "forces", f)
        mo = pl.get(p, "moments").ravel()
        for k, v in (moments or {}).items():
            mo[self._index(k, pr.loads, "load")] = self._values([v], 1, "load", "moment")[0]
        pl.put(p, "moments", mo)
        return p

    def _error(self, table: str, key: str, message: str) -> ProblemError:
        return ProblemError(self.problem.file, table, key, message)

    def _index(self, k: Any, items: Sequence[Any], table: str) -> int:
        """A 0-based index into the problem's clamps, rigid clamps or loads (an integer, or
        its decimal string as JSON keys are)."""
        if isinstance(k, str) and k.isdecimal() and len(k) < 10:
            k = int(k)
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k < len(items):
            raise self._error(table, "", f"no {table} with index {quoted(k)} (the problem has "
                              f"{len(items)}, indexed from 0)")
        return int(k)

    def _values(self, v: Any, length: int, table: str, key: str) -> np.ndarray:
        """``length`` finite numbers, as the file reader accepts them (tomlio.finite_number)."""
        values = np.atleast_1d(np.asarray(v, dtype=object)).ravel()
        if values.size != length:
            raise self._error(table, key, f"expected {length} numbers, got {values.size}")
        try:
            return np.array([finite_number(x.item() if isinstance(x, np.generic) else x)
                             for x in values])
        except ValueError as err:
            raise self._error(table, key, str(err)) from None

    def solve(self, p: np.ndarray, x0: np.ndarray | None = None) -> SolveReport:
        """Solve at parameters ``p`` from ``x0`` (the natural state if None); falls back to
        continuation from the natural parameters when the direct solve fails."""
        return solve(self.wnlp, self.solver, p=p, x0=x0)

    def result(self, rep: SolveReport, p: np.ndarray) -> dict[str, Any]:
        """The contract's result JSON for a solution at parameters ``p``."""
        return result_dict(self.wnlp, rep, self.solver.violation(rep.x, p), self.build_s, p=p)


@dataclass
class LoadPath:
    """Points solved in order, each warm-started from the last, on one problem.

    ``doc`` is the problem as a TOML-like dict (plain data, so it travels to worker processes);
    each point is a dict of :meth:`WeftStudy.params` keyword arguments (JSON-able).
    """

    name: str
    doc: dict[str, Any]
    points: list[dict[str, Any]]
    reduced: bool = False
    labels: list[Any] = field(default_factory=list)


def _key(path: LoadPath, index: int) -> str:
    """A hash of everything that determines a point: problem, model and the path up to it."""
    blob = json.dumps([path.doc, path.reduced, path.points[:index + 1]], sort_keys=True, default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def point_files(cache: Path, path: LoadPath, index: int) -> tuple[Path, Path]:
    """The cached result JSON and solution vector (.npy) of one point of a path."""
    stem = f"{path.name}.{index:04d}.{_key(path, index)}"
    return cache / f"{stem}.json", cache / f"{stem}.npy"


def point_solution(study_dir: Path, path: LoadPath, index: int) -> np.ndarray:
    """The solution vector of a solved point of a study written under ``study_dir``."""
    return np.load(point_files(study_dir / "points", path, index)[1])


def _summary_row(path: LoadPath, index: int, result: dict[str, Any]) -> dict[str, Any]:
    return {"path": path.name, "index": index,
            "label": path.labels[index] if index < len(path.labels) else index,
            "point": path.points[index], "success": result["success"], "status": result["status"],
            "energy": result["energy"], "iterations": result["iterations"],
            "clamps": [{"loop": c["loop"], "point": c["point"], "position": c["position"],
                        "reaction": c["reaction"]} for c in result["clamps"]],
            "rigid_clamps": [{"force": r["force"], "moment": r["moment"]}
                             for r in result["rigid_clamps"]]}


def _read_cached(js: Path, npy: Path) -> tuple[dict[str, Any], np.ndarray] | None:
    """A cached point's result and solution vector, or None if missing or damaged (a study
    killed by an older version mid-write, a disk error): such a point is solved again."""
    try:
        result = json.loads(js.read_text(encoding="utf-8"))
        x = np.load(npy, allow_pickle=False)
    except (OSError, ValueError, EOFError):      # JSONDecodeError and numpy's errors are ValueErrors
        return None
    if not isinstance(result, dict) or not {"success", "status", "energy", "iterations",
                                            "clamps", "rigid_clamps"} <= set(result):
        return None
    if x.dtype != np.float64 or x.ndim != 1:
        return None
    return result, x


def run_path(path: LoadPath, cache: Path, limit: int | None = None,
             tick: Callable[[], None] | None = None) -> list[dict[str, Any]]:
    """Solve one path in order with caching; at most ``limit`` new solves (None: all)."""
    cache.mkdir(parents=True, exist_ok=True)
    rows, x_prev, study, new = [], None, None, 0
    for index in range(len(path.points)):
        js, npy = point_files(cache, path, index)
        cached = _read_cached(js, npy)
        if cached is not None:
            result, x_prev = cached
        else:
            if limit is not None and new >= limit:
                break
            if study is None:
                study = WeftStudy(parse_problem(f"<study {path.name}>", path.doc), path.reduced)
            p = study.params(**path.points[index])
            rep = study.solve(p, x0=x_prev)
            result = study.result(rep, p)
            with atomic_file(npy) as fh:
                np.save(fh, rep.x)
            write_json(js, result)          # last: a point counts as cached once its JSON exists
            x_prev, new = rep.x, new + 1
        rows.append(_summary_row(path, index, result))
        if tick:
            tick()
    return rows


def _worker(args: tuple[LoadPath, Path, int | None, Any]) -> list[dict[str, Any]]:
    path, cache, limit, queue = args
    return run_path(path, cache, limit, tick=(lambda: queue.put(1)) if queue is not None else None)


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]],
              fields: Sequence[str] | None = None) -> Path:
    """A study table as CSV (columns ``fields``, default the first row's keys)."""
    with atomic_file(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(fields or rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


class Progress:
    """One line of progress on stderr: count, elapsed time, estimate of the time left."""

    def __init__(self, name: str, total: int, stream=None) -> None:
        self.name, self.total, self.done, self.t0 = name, total, 0, time.perf_counter()
        self.stream = stream or sys.stderr

    def tick(self) -> None:
        self.done += 1
        el = time.perf_counter() - self.t0
        left = el / self.done * (self.total - self.done)
        end = "\n" if self.done >= self.total else ""
        self.stream.write(f"\r{self.name}: {self.done}/{self.total} points, {el:.1f} s elapsed, "
                          f"~{left:.1f} s left   {end}")
        self.stream.flush()


def run_study(name: str, paths: Sequence[LoadPath], out_root: Path = Path("results"),
              workers: int | None = None, limit: int | None = None) -> dict[str, Any]:
    """Run (or resume) a study: paths in parallel, points along a path in order.

    Writes ``out_root/<name>/summary.json`` when every point is done; ``limit`` caps the new
    solves per path (for tests of resumption). Returns the summary.
    """
    out = out_root / name
    cache = out / "points"
    workers = workers or min(len(paths), os.cpu_count() or 1)
    progress = Progress(name, sum(len(p.points) for p in paths))
    if workers <= 1 or len(paths) <= 1:
        per_path = [run_path(p, cache, limit, progress.tick) for p in paths]
    else:
        ctx = mp.get_context("fork" if sys.platform != "win32" else "spawn")
        with ctx.Manager() as manager, ctx.Pool(workers) as pool:
            queue = manager.Queue()
            job = pool.map_async(_worker, [(p, cache, limit, queue) for p in paths])
            while not job.ready() or not queue.empty():
                try:
                    queue.get(timeout=0.2)
                    progress.tick()
                except queue_errors.Empty:
                    pass
            per_path = job.get()
    rows = [row for path_rows in per_path for row in path_rows]
    complete = len(rows) == progress.total
    summary = {"study": name, "complete": complete, "points": rows}
    if complete:
        write_json(out / "summary.json", summary)
    return summary
