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

from .jsonio import write_json
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
            tgt[:, int(k)] = v
        for k, v in (displacements or {}).items():
            c = pr.clamps[int(k)]
            tgt[:, int(k)] = pr.natural_position(c.loop, c.s) + np.asarray(v, dtype=float)
        pl.put(p, "targets", tgt)
        rig = pl.get(p, "rigid")
        for k, v in (rigid or {}).items():
            rig[:, int(k)] = v
        pl.put(p, "rigid", rig)
        for name, v in (material or {}).items():
            if name not in ("k_a", "k_b", "R_f"):
                raise KeyError(f"unknown material value {name!r}")
            pl.put(p, name, v)
        f = pl.get(p, "forces")
        for k, v in (forces or {}).items():
            f[:, int(k)] = v
        pl.put(p, "forces", f)
        mo = pl.get(p, "moments").ravel()
        for k, v in (moments or {}).items():
            mo[int(k)] = v
        pl.put(p, "moments", mo)
        return p

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
                study = WeftStudy(parse_problem(f"<study {path.name}>", path.doc), path.reduced)
            p = study.params(**path.points[index])
            rep = study.solve(p, x0=x_prev)
            result = study.result(rep, p)
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


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]],
              fields: Sequence[str] | None = None) -> Path:
    """A study table as CSV (columns ``fields``, default the first row's keys)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
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
