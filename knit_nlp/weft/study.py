"""Studies: one NLP built once and re-solved for many clamp targets or material values.

- :class:`WeftStudy` builds a weft problem's NLP once; ``study.params`` is the problem's
  :class:`~knit_nlp.weft.params.WeftParams`, whose ``with_`` names changes (clamp targets or
  displacements, rigid-clamp motions, material values, loads; numbered from 1);
  :meth:`WeftStudy.solve` re-solves, warm-started from a given point.
- :func:`run_study` runs named loading paths: points along one path run in order, each
  warm-started from the last; independent paths run in parallel processes. Each point's result
  is cached under ``results/<study>/points/``, so an interrupted study resumes where it stopped;
  ``summary.json`` collects every point (no timings, so a resumed study's summary equals an
  uninterrupted one's). One line of progress shows count, elapsed time and an estimate.
"""
from __future__ import annotations

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

from ..jsonio import write_json
from .nlp import build_nlp
from .params import WeftParams
from .parametrisation import Full, Parametrisation
from .problem import WeftProblem, parse_problem
from .results import WeftResult
from .solve import SolveReport, WeftSolver, solve


class WeftStudy:
    """A weft problem's NLP, built once and re-solved for many parameter values."""

    def __init__(self, problem: WeftProblem, parametrisation: Parametrisation = Full()) -> None:
        t0 = time.perf_counter()
        self.problem = problem
        self.nlp = build_nlp(problem, parametrisation)
        self.solver = WeftSolver(self.nlp)
        self.build_s = time.perf_counter() - t0
        self.builds = 1

    @property
    def params(self) -> WeftParams:
        """The problem's own parameter values; change them with ``with_(...)``."""
        return self.nlp.params

    def solve(self, params: WeftParams, x0: np.ndarray | None = None) -> SolveReport:
        """Solve at ``params`` from ``x0`` (the natural state if None); falls back to
        continuation from the natural parameters when the direct solve fails."""
        return solve(self.nlp, self.solver, params=params, x0=x0)

    def result(self, rep: SolveReport, params: WeftParams) -> WeftResult:
        """The typed result of a solution at ``params``."""
        return WeftResult(self.nlp, rep, params, self.build_s,
                          self.solver.violation(rep.x, params.vector()))


@dataclass
class LoadPath:
    """Points solved in order, each warm-started from the last, on one problem.

    ``doc`` is the problem as a TOML-like dict (plain data, so it travels to worker processes);
    each point is a dict of :meth:`WeftParams.with_` keyword arguments (JSON-able; clamps,
    loads and rigid clamps numbered from 1).
    """

    name: str
    doc: dict[str, Any]
    points: list[dict[str, Any]]
    parametrisation: Parametrisation = Full()
    labels: list[Any] = field(default_factory=list)


def _key(path: LoadPath, index: int) -> str:
    """A hash of everything that determines a point: problem, model and the path up to it."""
    blob = json.dumps([path.doc, repr(path.parametrisation), path.points[:index + 1]],
                      sort_keys=True, default=str)
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


def run_path(path: LoadPath, cache: Path, limit: int | None = None,
             tick: Callable[[], None] | None = None) -> list[dict[str, Any]]:
    """Solve one path in order with caching; at most ``limit`` new solves (None: all)."""
    cache.mkdir(parents=True, exist_ok=True)
    rows, x_prev, study, new = [], None, None, 0
    for index in range(len(path.points)):
        js, npy = point_files(cache, path, index)
        if js.exists():
            result = json.loads(js.read_text())
            x_prev = np.load(npy)
        else:
            if limit is not None and new >= limit:
                break
            if study is None:
                study = WeftStudy(parse_problem(path.doc, f"<study {path.name}>"),
                                  path.parametrisation)
            p = study.params.with_(**path.points[index])
            rep = study.solve(p, x0=x_prev)
            result = study.result(rep, p).to_json()
            np.save(npy, rep.x)
            write_json(js, result)
            x_prev, new = rep.x, new + 1
        rows.append(_summary_row(path, index, result))
        if tick:
            tick()
    return rows


def _worker(args: tuple[LoadPath, Path, int | None, Any]) -> list[dict[str, Any]]:
    path, cache, limit, queue = args
    return run_path(path, cache, limit, tick=(lambda: queue.put(1)) if queue is not None else None)


def print_table(rows: Sequence[Mapping[str, Any]], columns: Sequence[tuple[str, str, str]]) -> None:
    """A study table on one screen: ``columns`` are (key, header, format spec); booleans print as
    ``y`` / ``NO``."""
    widths = [max(len(head) + 1, 7) for _, head, _ in columns]
    print("".join(f"{head:>{w}}" for (_, head, _), w in zip(columns, widths)))
    for r in rows:
        cells = [("y" if r[key] else "NO") if isinstance(r[key], bool) else format(r[key], fmt)
                 for key, _, fmt in columns]
        print("".join(f"{c:>{w}}" for c, w in zip(cells, widths)))


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


def animate_path(gif: Path, path: LoadPath, study_dir: Path, fps: int = 4) -> Path:
    """A GIF of a solved load path of a study written under ``study_dir``: the natural loops,
    then every point's deformed loops in order (labels in the frame titles)."""
    from .plot import animate
    from .sampling import natural_centrelines, solution_centrelines
    wnlp = build_nlp(parse_problem(path.doc, f"<{path.name}>"), path.parametrisation)
    natural = natural_centrelines(wnlp.problem)
    frames = [(f"{path.name}: natural", natural)]
    for k in range(len(path.points)):
        label = path.labels[k] if k < len(path.labels) else k
        frames.append((f"{path.name}: {label}",
                       solution_centrelines(wnlp, point_solution(study_dir, path, k))))
    return animate(gif, natural, frames, wnlp.problem.units, fps)
