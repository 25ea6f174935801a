"""The front door: load any problem, solve it, compare models; both models behind one table.

    import knit_nlp
    r = knit_nlp.solve("wada_fig7")          # a named problem, a path, or a loaded problem
    r.success, r.energy.total, r.clamps[0].reaction, r.to_json(), r.save("results")
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Union

from .errors import ProblemError, quoted
from .jacquard.problem import JacquardProblem, parse_problem as parse_jacquard
from .jacquard.result import JacquardResult
from .problems import resolve
from .tomlio import load_toml
from .weft.api import Comparison
from .weft.model.parametrisation import Adaptive, Full, Parametrisation, Reduced
from .weft.model.problem import WeftProblem, parse_problem as parse_weft
from .weft.output.results import WeftResult

Problem = Union[WeftProblem, JacquardProblem]
Result = Union[WeftResult, JacquardResult]


def _solve_weft(problem: WeftProblem, reduced: bool | Parametrisation | None = None,
                **options: Any) -> WeftResult:
    from .weft.api import solve
    param = (None if reduced is None else reduced if isinstance(reduced, (Full, Reduced, Adaptive))
             else (problem.reduction or Reduced()) if reduced else Full())
    return solve(problem, param, **options)


def _solve_jacquard(problem: JacquardProblem, solver: str | None = None) -> JacquardResult:
    from .jacquard.api import solve
    return solve(problem, solver)


def _compare_weft(problem: WeftProblem) -> Comparison:
    from .weft.api import compare
    return compare(problem)


@dataclass(frozen=True)
class Model:
    """One model's entry points: reading a document, solving, comparing (None: not offered)."""

    name: str
    parse: Callable[[dict[str, Any], str | Path], Any]
    solve: Callable[..., Any]
    compare: Callable[..., Any] | None
    options: tuple[str, ...]        # keyword options ``solve`` accepts


MODELS: dict[str, Model] = {
    "weft": Model("weft", parse_weft, _solve_weft, _compare_weft,
                  ("reduced", "params", "continuation", "start", "warm_from_reduced",
                   "verbose")),
    "jacquard": Model("jacquard", parse_jacquard, _solve_jacquard, None, ("solver",)),
}


def parse_problem(doc: dict[str, Any], source: str | Path) -> Problem:
    """A checked problem of the model the document names (``model``, default ``weft``)."""
    model = doc.get("model", "weft")
    if model not in MODELS:
        raise ProblemError(source, "", "model", f"must be one of {', '.join(map(repr, MODELS))};"
                           f" got {quoted(model)}")
    return MODELS[model].parse(doc, source)


def load_problem(name_or_path: str | Path) -> Problem:
    """Read and check a problem file: a path, or the name of a shipped problem
    (``knit-nlp list``). Bad input raises :class:`~knit_nlp.errors.ProblemError`."""
    path = resolve(str(name_or_path))
    return parse_problem(load_toml(path), path)


def _problem(problem_or_name: Problem | str | Path) -> Problem:
    if isinstance(problem_or_name, (WeftProblem, JacquardProblem)):
        return problem_or_name
    return load_problem(problem_or_name)


def solve(problem_or_name: Problem | str | Path, *, reduced: bool | Parametrisation | None = None,
          solver: str | None = None, **options: Any) -> Result:
    """Solve a problem (a loaded one, a path or a shipped name) and return its typed result.

    Weft: ``reduced`` None (the file's choice), True (its representatives, or the corners),
    False, or a ``Full()``/``Reduced(...)``; options ``params``, ``continuation``, ``start``,
    ``warm_from_reduced``. Jacquard: ``solver`` "static" (default) or "explicit".
    """
    problem = _problem(problem_or_name)
    model = MODELS[problem.model]
    given = dict(options, **({"reduced": reduced} if reduced is not None else {}),
                 **({"solver": solver} if solver is not None else {}))
    wrong = sorted(set(given) - set(model.options))
    if wrong:
        raise ValueError(f"{', '.join(wrong)} do(es) not apply to {model.name} problems; "
                         f"options: {', '.join(model.options)}")
    return model.solve(problem, **given)


def compare(problem_or_name: WeftProblem | str | Path) -> Comparison:
    """Full and reduced models of a weft problem side by side (:class:`Comparison`)."""
    problem = _problem(problem_or_name)
    model = MODELS[problem.model]
    if model.compare is None:
        raise ValueError(f"compare is for weft problems; {problem.name!r} is a {model.name} problem")
    return model.compare(problem)
