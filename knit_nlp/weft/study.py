"""Studies: one NLP built once and re-solved for many clamp targets or material values.

- :class:`WeftStudy` builds a weft problem's NLP once; ``study.params`` is the problem's
  :class:`~knit_nlp.weft.params.WeftParams`, whose ``with_`` names changes (clamp targets or
  displacements, rigid-clamp motions, material values, loads; numbered from 1);
  :meth:`WeftStudy.solve` re-solves, warm-started from a given point.
- :func:`~knit_nlp.studies.runner.run_study` (re-exported here) runs named loading paths on a
  local process pool or a Dask cluster: see :mod:`knit_nlp.studies`.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from .transcription.full import build_nlp
from .model.params import WeftParams
from .model.parametrisation import Full, Parametrisation
from .model.problem import WeftProblem, parse_problem
from .output.results import WeftResult
from .solving.solve import SolveReport, WeftSolver, solve


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


# the study runner is shared by both models; its names stay importable from here
from ..studies.runner import (LoadPath, Progress, point_files, point_solution,  # noqa: E402
                              print_table, run_study)

__all__ = ["WeftStudy", "LoadPath", "Progress", "animate_path", "point_files", "point_solution",
           "print_table", "run_study"]


def animate_path(gif: Path, path: LoadPath, study_dir: Path, fps: int = 4) -> Path:
    """A GIF of a solved load path of a study written under ``study_dir``: the natural loops,
    then every point's deformed loops in order (labels in the frame titles; a point without a
    solution, its worker lost, is left out)."""
    from .output.plot import animate
    from .model.centrelines import natural_centrelines, solution_centrelines
    wnlp = build_nlp(parse_problem(path.doc, f"<{path.name}>"), path.parametrisation)
    natural = natural_centrelines(wnlp.problem)
    frames = [(f"{path.name}: natural", natural)]
    for k in range(len(path.points)):
        label = path.labels[k] if k < len(path.labels) else k
        x = point_solution(study_dir, path, k)
        if x is not None:
            frames.append((f"{path.name}: {label}", solution_centrelines(wnlp, x)))
    return animate(gif, natural, frames, wnlp.problem.units, fps)
