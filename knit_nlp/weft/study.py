"""Many solves of one weft problem, and what a study worker runs for one weft point.

- :class:`WeftStudy`: the problem's forward equilibrium (``solving.variants.equilibrium``: a
  fixed transcription, the adaptive-representatives strategy, or the full model with yarn
  contact; built once) and the typed results of its solves. ``study.params`` is the problem's
  :class:`~knit_nlp.weft.model.params.WeftParams`, whose ``with_`` names changes (clamp targets
  or displacements, rigid-clamp motions, material values, loads; numbered from 1);
  :meth:`WeftStudy.solve` re-solves, warm-started from a given point.
- :func:`study` builds one for a parametrisation.
- :func:`prepare_point`, :func:`solve_point` and :func:`study_row`: a study point from plain
  data (a problem document, parameter changes, a warm start) and its summary row, for
  ``knit_nlp.studies``; :func:`animate_points`: a GIF of a study's solved points.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .model.centrelines import natural_centrelines
from .model.parametrisation import Parametrisation
from .model.params import WeftParams
from .model.problem import WeftProblem, parse_problem
from .output.results import WeftResult
from .solving.variants import equilibrium
from .solving.solve import DEFAULT_START, Solution, SolveReport
from .transcription.factory import transcribe


class WeftStudy:
    """A weft problem's forward equilibrium (``solving.variants.equilibrium``), built once and
    re-solved for many parameter values; :meth:`run` gives typed results (with yarn contact
    their ``contact`` block, with adaptive representatives their ``adaptive`` block)."""

    def __init__(self, problem: WeftProblem, parametrisation: Parametrisation | None = None, *,
                 verbose: bool | None = False) -> None:
        self.problem = problem
        self.eq = equilibrium(problem, parametrisation, verbose=verbose)

    @property
    def params(self) -> WeftParams:
        """The problem's own parameter values; change them with ``with_(...)``."""
        return self.eq.params

    @property
    def nlp(self):
        """The transcription solved (a fixed one; not for adaptive representatives)."""
        return self.eq.nlp

    @property
    def solver(self):
        return self.eq.solver

    @property
    def contact(self):
        """The contact solver (a problem with ``[yarn] radius``)."""
        return self.eq.contact

    def solve(self, params: WeftParams, x0: np.ndarray | None = None,
              continuation: int | None = None, start: str = DEFAULT_START,
              x0_params: WeftParams | None = None) -> Solution:
        """Solve at ``params`` from ``x0`` (at ``x0_params``, if known: yarn contact steps
        the load from there), else from ``start``; falls back to continuation from the
        natural parameters when the direct solve fails."""
        return self.eq.solve(params, x0, continuation=continuation, start=start,
                             x0_params=x0_params)

    def result(self, rep: SolveReport, params: WeftParams) -> WeftResult:
        """The typed result of a solution at ``params``."""
        return WeftResult.of(rep if isinstance(rep, Solution) else self.eq.solution(rep, params))

    def run(self, params: WeftParams | None = None, x0: np.ndarray | None = None,
            continuation: int | None = None, start_from: WeftResult | None = None,
            x0_params: WeftParams | None = None) -> WeftResult:
        """Solve at ``params`` (default: the problem's own) from ``x0`` (a solution at
        ``x0_params``, if known: only yarn contact uses them), or from another solved model's
        loops lifted into this one (``start_from``, at its parameters), and return the typed
        result."""
        params = params or self.params
        if start_from is not None:
            x0 = self.eq.lift(start_from.coefficients, start_from.starts)
            x0_params = start_from.params
        sol = self.solve(params, x0, continuation, x0_params=x0_params)
        self.eq.done()
        return WeftResult.of(sol)


def study(problem: WeftProblem, parametrisation: Parametrisation | None = None, *,
          verbose: bool | None = False) -> WeftStudy:
    """How ``problem`` is solved in ``parametrisation`` (None: the file's own): its
    :class:`WeftStudy` (the variant is chosen by ``solving.variants.equilibrium``)."""
    return WeftStudy(problem, parametrisation, verbose=verbose)


def prepare_point(doc: dict[str, Any]) -> WeftStudy:
    """What a study worker builds once per document: the document's problem in its own
    parametrisation (``knit_nlp.studies`` keeps it for the points that follow)."""
    return study(parse_problem(doc, f"<study {doc.get('name', '')}>"), verbose=None)


def solve_point(built: WeftStudy, changes: dict[str, Any],
                x0: np.ndarray | None, x0_changes: dict[str, Any] | None = None
                ) -> tuple[dict[str, Any], np.ndarray]:
    """One study point: the built problem at the parameters ``changes`` names
    (``WeftParams.with_`` keyword arguments), warm-started from ``x0`` (solved at the changes
    ``x0_changes``: yarn contact steps the load from there); the result JSON and the solution
    vector."""
    at = None if x0 is None or x0_changes is None else built.params.with_(**x0_changes)
    result = built.run(built.params.with_(**changes), x0=x0, x0_params=at)
    return result.to_json(), result.x


def study_row(result: dict[str, Any]) -> dict[str, Any]:
    """The values a study summary keeps of a weft result JSON: energy, iterations, each
    clamp's and rigid clamp's force, the largest of them, and ``grips``: the total force on the
    fabric of each grip (the clamps one shorthand table made summed, by the table's name; a
    single clamp by its table, ``clamp[N]``, or as ``clamp N`` when built in Python;
    ``rigid_clamp[N]``)."""
    forces = [c["reaction"] for c in result["clamps"]] + [r["force"] for r in
                                                          result["rigid_clamps"]]
    grips: dict[str, list[float]] = {}
    for q, c in enumerate(result["clamps"], start=1):
        name = c.get("group") or c.get("table") or f"clamp {q}"
        grips[name] = (np.add(grips[name], c["reaction"]) if name in grips
                       else np.asarray(c["reaction"], dtype=float))
    grips.update({f"rigid_clamp[{q}]": r["force"]
                  for q, r in enumerate(result["rigid_clamps"], start=1)})
    return {"energy": result["energy"], "iterations": result["iterations"],
            "clamps": [{"loop": c["loop"], "point": c["point"], "position": c["position"],
                        "reaction": c["reaction"]} for c in result["clamps"]],
            "rigid_clamps": [{"force": r["force"], "moment": r["moment"]}
                             for r in result["rigid_clamps"]],
            "grips": {k: [float(v) for v in f] for k, f in grips.items()},
            "largest_force": float(max(np.linalg.norm(f) for f in forces)) if forces else None}


def key_unit(problem: WeftProblem, key: str) -> str:
    """The unit of a sweep key's values (``knit-nlp sweep``'s picture): lengths for positions,
    displacements and translations, the problem's force for loads, k_a and k_b in force per
    length, R_f and moments in force × length (R_f × length), angles in rad."""
    u = problem.units
    field = key.split(".")[-2] if key.endswith((".x", ".y")) else key.split(".")[-1]
    return {"k_a": f"{u.force}/{u.length}", "k_b": f"{u.force}/{u.length}",
            "R_f": f"{u.force}·{u.length}²", "position": u.length, "displacement": u.length,
            "translation": u.length, "force": u.force, "moment": u.energy,
            "angle": "rad", "rotation": "rad"}.get(field, "")


def animate_points(gif: Path, problem: WeftProblem,
                   frames: Sequence[tuple[str, np.ndarray | None]], fps: int = 4) -> Path:
    """A GIF of solution vectors of ``problem`` (a study's points, e.g. a loading path through
    ``knit_nlp.studies.point_solution``): the natural loops, then each point's deformed loops
    in order, titled by their labels (a point without a solution, its worker lost, is left
    out). The vectors are those of the problem's own transcription, as study workers solve."""
    nlp = transcribe(problem)
    natural = natural_centrelines(problem)
    shown = [(f"{problem.name}: natural", natural)] + [(label, nlp.centrelines(x))
                                                       for label, x in frames if x is not None]
    from .output.plot import animate      # matplotlib only when drawing
    return animate(gif, natural, shown, problem.units, fps, problem=problem)
