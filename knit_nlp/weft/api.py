"""The weft model from Python: build and solve a problem, or compare its full and reduced models.

    result = solve(problem)                              # the file's parametrisation
    result = solve(problem, Reduced((1, 5, 10), (1, 10)), continuation=4)
    result.success, result.energy.total, result.clamps[0].reaction, result.centrelines()
    cmp = compare(problem); cmp.distance_max, cmp.speedup_reduced
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ..jsonio import write_json
from ..provenance import source_record
from .solving.adaptive import solve_adaptive
from .transcription.condensed.nlp import build_condensed
from .transcription.full import build_nlp
from .model.params import WeftParams
from .model.parametrisation import Adaptive, Full, Parametrisation, Reduced
from .output.plot import plot_overlay
from .model.problem import WeftProblem
from .output.results import WeftResult
from .model.centrelines import SAMPLES
from .solving.solve import WeftSolver, solve as solve_nlp


def solve(problem: WeftProblem, parametrisation: Parametrisation | None = None, *,
          params: WeftParams | None = None, continuation: int | None = None,
          start: WeftResult | None = None, warm_from_reduced: bool = False,
          verbose: bool = False) -> WeftResult:
    """Build and solve one model of a problem.

    ``parametrisation``: ``Full()``, ``Reduced(...)`` or None for the file's own (reduced when
    it has ``[reduction]``). ``params``: parameter values (the file's by default).
    ``continuation``: reach the targets in this many warm-started steps. ``start``: start from
    another solved model's loops (lifted into this one). ``warm_from_reduced``: solve the
    reduced model first and start this (full) one from it; the result's JSON then carries
    ``warm_start``. ``verbose``: show IPOPT's iterations on one updating line of stderr.
    """
    param = problem.parametrisation if parametrisation is None else parametrisation
    if warm_from_reduced:
        if isinstance(param, Reduced):
            raise ValueError("warm_from_reduced starts the full model: use Full()")
        return _warm_from_reduced(problem, params, continuation, verbose)[1]
    if isinstance(param, Adaptive):
        return _adaptive(problem, param, params, continuation)
    t0 = time.perf_counter()
    # the reduced model is solved in its condensed form (README, "Full versus reduced")
    wnlp = build_condensed(problem, param) if isinstance(param, Reduced) else build_nlp(problem, param)
    solver = WeftSolver(wnlp, verbose=verbose)
    build_s = time.perf_counter() - t0
    x0 = None if start is None else wnlp.lift(start.coefficients, start.starts)
    params = params or wnlp.params
    rep = solve_nlp(wnlp, solver, params=params, x0=x0, continuation=continuation)
    if solver.progress is not None:
        solver.progress.done()
    return WeftResult(wnlp, rep, params, build_s, solver.violation(rep.x, params.vector()))


def _adaptive(problem: WeftProblem, cfg: Adaptive, params: WeftParams | None,
              continuation: int | None) -> WeftResult:
    """Adaptive representatives (``adaptive``); the result carries every step's grid."""
    if params is not None and not np.array_equal(params.vector(), WeftParams.of(problem).vector()):
        raise ValueError("adaptive representatives solve at the problem's own parameters")
    run = solve_adaptive(problem, cfg, continuation=continuation)
    viol = run.solver.violation(run.report.x, run.cnlp.p0)
    return WeftResult(run.cnlp, run.report, run.cnlp.params, run.build_s, viol,
                      {"adaptive": {"steps": [st.as_dict() for st in run.steps],
                                    "estimate": run.steps[-1].estimate}})


def _warm_from_reduced(problem: WeftProblem, params: WeftParams | None,
                       continuation: int | None,
                       verbose: bool = False) -> tuple[WeftResult, WeftResult]:
    """The reduced model (the file's representatives, or the corners), then the full model
    started from its lifted solution."""
    red = solve(problem, problem.reduction or Reduced(), params=params, continuation=continuation,
                verbose=verbose)
    full = solve(problem, Full(), params=params, continuation=continuation, start=red,
                 verbose=verbose)
    full.extra["warm_start"] = {"from": "reduced", "reduced_success": red.success,
                                "reduced_iterations": red.iterations,
                                "reduced_solve_s": red.report.solve_s}
    return red, full


@dataclass(repr=False)
class Comparison:
    """Full and reduced models of one problem side by side, and the full model warm-started
    from the reduced; distances between corresponding centreline points."""

    full: WeftResult
    reduced: WeftResult
    full_warm_from_reduced: WeftResult
    samples: int = SAMPLES

    @cached_property
    def _distance(self) -> np.ndarray:
        return np.linalg.norm(self.full.centrelines(self.samples)
                              - self.reduced.centrelines(self.samples), axis=-1)

    @property
    def distance_max(self) -> float:
        return float(self._distance.max())

    @property
    def distance_rms(self) -> float:
        return float(np.sqrt(np.mean(self._distance ** 2)))

    @property
    def energy_gap(self) -> float:
        """Reduced minus full stored energy (never negative at a shared minimum)."""
        return self.reduced.energy.total - self.full.energy.total

    @property
    def speedup_reduced(self) -> float:
        """Full (build + solve) time over reduced (build + solve) time."""
        def cost(r: WeftResult) -> float:
            return r.build_s + r.report.solve_s
        return cost(self.full) / cost(self.reduced)

    @property
    def success(self) -> bool:
        return all(r.success for r in self.models().values())

    def models(self) -> dict[str, WeftResult]:
        return {"full": self.full, "reduced": self.reduced,
                "full_warm_from_reduced": self.full_warm_from_reduced}

    def __repr__(self) -> str:
        return (f"Comparison({self.full.problem.name!r}: energy full {self.full.energy.total:.6g},"
                f" reduced {self.reduced.energy.total:.6g}; distance max {self.distance_max:.4g},"
                f" rms {self.distance_rms:.4g}; reduced {self.speedup_reduced:.2f}x as fast)")

    def to_json(self) -> dict[str, Any]:
        """``<problem>.compare.json``."""
        keys = ("success", "status", "n_parameters", "n_variables", "n_constraints",
                "iterations", "energy", "timings")
        return {"problem": self.full.problem.name,
                **({"source": src} if (src := source_record(self.full.problem.source)) else {}),
                "models": {name: {k: r.to_json()[k] for k in keys}
                           for name, r in self.models().items()},
                "distance": {"max": self.distance_max, "rms": self.distance_rms,
                             "samples_per_loop": self.samples},
                "energy_gap": self.energy_gap, "speedup_reduced": self.speedup_reduced,
                **({"adaptive": {**self.reduced.extra["adaptive"], "true_rms": self.distance_rms}}
                   if "adaptive" in self.reduced.extra else {})}

    def save(self, out_dir: Path | str) -> list[Path]:
        """``DIR/<problem>.compare.json`` and the overlay ``.compare.png``."""
        name = self.full.problem.name
        js = write_json(Path(out_dir) / f"{name}.compare.json", self.to_json())
        png = plot_overlay(Path(out_dir) / f"{name}.compare.png",
                           self.full.centrelines(self.samples),
                           self.reduced.centrelines(self.samples),
                           f"{name}: full (black) vs reduced, max distance {self.distance_max:.3g} "
                           f"{self.full.problem.units.length}", self.full.problem.units)
        return [js, png]


def compare(problem: WeftProblem, samples: int = SAMPLES) -> Comparison:
    """Solve the full model, the reduced one (the file's representatives, or the corners) and
    the full one warm-started from the reduced."""
    full = solve(problem, Full())
    red, warm = _warm_from_reduced(problem, None, None)
    return Comparison(full, red, warm, samples)
