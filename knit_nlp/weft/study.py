"""Many solves of one weft problem, and what a study worker runs for one weft point.

- :class:`WeftStudy`: a transcription (``transcribe``) and its IPOPT instance built once;
  ``study.params`` is the problem's :class:`~knit_nlp.weft.model.params.WeftParams`, whose
  ``with_`` names changes (clamp targets or displacements, rigid-clamp motions, material values,
  loads; numbered from 1); :meth:`WeftStudy.solve` re-solves, warm-started from a given point.
- :class:`AdaptiveStudy`: the adaptive-representatives strategy (``solving.adaptive``), which
  refines its grid afresh at every point (a grid fitted to one load is not another's).
- :class:`ContactStudy`: a problem with ``[yarn] radius``: the full model with yarn contact
  (``solving.contact``); the reduced and adaptive models refuse a radius.
- :func:`study` picks one for a parametrisation: the one place ``Adaptive`` and a yarn radius
  are told apart.
- :func:`prepare_point`, :func:`solve_point` and :func:`study_row`: a study point from plain
  data (a problem document, parameter changes, a warm start) and its summary row, for
  ``knit_nlp.studies``; :func:`animate_points`: a GIF of a study's solved points.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .model.centrelines import natural_centrelines
from .model.parametrisation import Adaptive, Full, Parametrisation, Reduced
from .model.params import WeftParams
from .model.problem import WeftProblem, parse_problem
from .output.results import WeftResult
from .solving.adaptive import solve_adaptive
from .solving.contact.rounds import ContactSolver
from .solving.contact.solve import refuse, solve_with_contact
from .solving.solve import DEFAULT_START, SolveReport, WeftSolver, solve
from .transcription.factory import transcribe
from .transcription.spatial import planar_only


class WeftStudy:
    """A weft problem's NLP, built once and re-solved for many parameter values."""

    def __init__(self, problem: WeftProblem, parametrisation: Parametrisation | None = None, *,
                 verbose: bool | None = False) -> None:
        t0 = time.perf_counter()
        self.problem = problem
        self.nlp = transcribe(problem, parametrisation)
        self.solver = WeftSolver(self.nlp, verbose=verbose)
        self.build_s = time.perf_counter() - t0
        self.builds = 1

    @property
    def params(self) -> WeftParams:
        """The problem's own parameter values; change them with ``with_(...)``."""
        return self.nlp.params

    def solve(self, params: WeftParams, x0: np.ndarray | None = None,
              continuation: int | None = None, start: str = DEFAULT_START) -> SolveReport:
        """Solve at ``params`` from ``x0`` (else from ``start``); falls back to continuation
        from the natural parameters when the direct solve fails."""
        return solve(self.nlp, self.solver, params=params, x0=x0, continuation=continuation,
                     start=start)

    def result(self, rep: SolveReport, params: WeftParams) -> WeftResult:
        """The typed result of a solution at ``params``."""
        return WeftResult(self.nlp, rep, params, self.build_s,
                          self.solver.violation(rep.x, params.vector()))

    def run(self, params: WeftParams | None = None, x0: np.ndarray | None = None,
            continuation: int | None = None, start_from: WeftResult | None = None,
            x0_params: WeftParams | None = None) -> WeftResult:
        """Solve at ``params`` (default: the problem's own) from ``x0`` (a solution at
        ``x0_params``, if known: only yarn contact uses them), or from another solved model's
        loops lifted into this one (``start_from``), and return the typed result."""
        params = params or self.params
        if start_from is not None:
            x0 = self.nlp.lift(start_from.coefficients, start_from.starts)
        rep = self.solve(params, x0, continuation)
        self.solver.progress.done()
        return self.result(rep, params)


class ContactStudy(WeftStudy):
    """The full model of a problem with ``[yarn] radius``: the paper's NLP built once (its
    solutions, reactions and loading paths read as without contact) and the contact NLP grown
    with the pairs the solves meet (``solving.contact``); results carry ``extra["contact"]``."""

    def __init__(self, problem: WeftProblem, *, verbose: bool | None = False) -> None:
        super().__init__(problem, Full(), verbose=verbose)
        self.contact = ContactSolver(self.nlp, problem.yarn.radius, verbose=verbose)
        self.block: dict[str, Any] = {}
        self._p_start: np.ndarray | None = None

    def solve(self, params: WeftParams, x0: np.ndarray | None = None,
              continuation: int | None = None, start: str = DEFAULT_START) -> SolveReport:
        """Solve with contact at ``params`` from ``x0`` (load steps from it), else from the
        paper's solution or the natural fabric (``solving.contact.solve``)."""
        rep, self.block = solve_with_contact(self.nlp, self.solver, self.contact, params,
                                             continuation, x0, self._p_start)
        return rep

    def result(self, rep: SolveReport, params: WeftParams) -> WeftResult:
        result = super().result(rep, params)
        result.build_s += self.contact.build_s
        result.extra["contact"] = self.block
        return result

    def run(self, params: WeftParams | None = None, x0: np.ndarray | None = None,
            continuation: int | None = None, start_from: WeftResult | None = None,
            x0_params: WeftParams | None = None) -> WeftResult:
        """As :meth:`WeftStudy.run`; load steps from ``start_from`` start at its parameters,
        from ``x0`` at ``x0_params`` (unknown: one step at the target, then the natural
        fabric)."""
        at = start_from.params if start_from is not None else x0_params
        self._p_start = None if at is None else at.vector()
        try:
            return super().run(params, x0, continuation, start_from)
        finally:
            self._p_start = None


class AdaptiveStudy:
    """Adaptive representatives (``solving.adaptive``) at any parameters; the result carries
    every step's grid under ``adaptive``."""

    def __init__(self, problem: WeftProblem, config: Adaptive) -> None:
        self.problem, self.config = problem, config

    @property
    def params(self) -> WeftParams:
        return WeftParams.of(self.problem)

    def run(self, params: WeftParams | None = None, x0: np.ndarray | None = None,
            continuation: int | None = None, start_from: WeftResult | None = None,
            x0_params: WeftParams | None = None) -> WeftResult:
        """Refine from the corners at ``params``; ``x0`` (a vector of another grid) and
        ``x0_params`` are not used, and a ``start_from`` is refused: the refinement starts from
        the corner form."""
        if start_from is not None:
            raise ValueError("start does not apply to adaptive representatives: they start "
                             "from the corner form")
        run = solve_adaptive(self.problem, self.config, continuation=continuation,
                             params=params)
        p = params or run.cnlp.params
        return WeftResult(run.cnlp, run.report, p, run.build_s,
                          run.solver.violation(run.report.x, p.vector()),
                          {"adaptive": {"steps": [st.as_dict() for st in run.steps],
                                        "estimate": run.steps[-1].estimate}})


def study(problem: WeftProblem, parametrisation: Parametrisation | None = None, *,
          verbose: bool | None = False) -> WeftStudy | AdaptiveStudy:
    """How ``problem`` is solved in ``parametrisation`` (None: the file's own): a fixed
    transcription built once, the adaptive strategy, or the full model with yarn contact
    (``[yarn] radius``; the reduced models refuse it, :func:`refuse`)."""
    param = problem.parametrisation if parametrisation is None else parametrisation
    if problem.yarn is not None and problem.yarn.spatial and isinstance(param, (Reduced, Adaptive)):
        raise planar_only(problem, "the reduced model")
    if problem.yarn is not None and not problem.yarn.spatial:
        if isinstance(param, (Reduced, Adaptive)):
            own = " (the file's [reduction])" if parametrisation is None else ""
            raise refuse(problem, f"the reduced model{own}")
        return ContactStudy(problem, verbose=verbose)
    if isinstance(param, Adaptive):
        return AdaptiveStudy(problem, param)
    return WeftStudy(problem, param, verbose=verbose)


def prepare_point(doc: dict[str, Any]) -> WeftStudy | AdaptiveStudy:
    """What a study worker builds once per document: the document's problem in its own
    parametrisation (``knit_nlp.studies`` keeps it for the points that follow)."""
    return study(parse_problem(doc, f"<study {doc.get('name', '')}>"), verbose=None)


def solve_point(built: WeftStudy | AdaptiveStudy, changes: dict[str, Any],
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
    return animate(gif, natural, shown, problem.units, fps)
