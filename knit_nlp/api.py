"""The front door and the model table: load any problem, solve it, compare models.

    import knit_nlp
    r = knit_nlp.solve("wada_fig7")          # a named problem, a path, or a loaded problem
    r.success, r.energy.total, r.clamps[0].reaction, r.to_json(), r.save("results")

Weft problems go to :func:`knit_nlp.weft.api.solve` (imported below as ``solve_weft``),
jacquard problems to :func:`knit_nlp.jacquard.api.solve`. Everything that differs between the
two models (how a file is read, the Python options, the command-line flags and commands, the
output names, the summary printed, how a study point is solved and summarised, which sweep keys
exist, whether a loading path is warm-started) is one :class:`Model` entry of :data:`MODELS`;
the command line (``cli``) and the studies (``studies``) only read the entry.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Union

from .errors import ProblemError, quoted
from .jacquard import commands as jacquard_commands, study as jacquard_study
from .jacquard.api import solve as solve_jacquard
from .jacquard.problem import JacquardProblem, parse_problem as parse_jacquard
from .jacquard.result import JacquardResult
from .jacquard.summary import solve_summary as jacquard_summary
from .problems import resolve
from .tomlio import load_toml, type_name
from .weft import commands as weft_commands, keys as weft_keys, study as weft_study
from .weft.api import check_compare, compare as compare_weft, solve as solve_weft
from .weft.model.parametrisation import Adaptive, Full, Parametrisation, Reduced
from .weft.model.problem import WeftProblem, parse_problem as parse_weft
from .weft.output.comparison import Comparison
from .weft.output.results import WeftResult
from .weft.output.summary import compare_summary, solve_summary as weft_summary

if TYPE_CHECKING:
    from .weft.inverse.calibration import CalibrationResult, CalibrationSpec

Problem = Union[WeftProblem, JacquardProblem]
Result = Union[WeftResult, JacquardResult]
DEFAULT_MODEL = "weft"      # a problem file without ``model``


@dataclass(frozen=True)
class Study:
    """How a model's study points are solved and summarised (``knit_nlp.studies``).

    ``prepare(doc)`` is built once per document in a worker; ``solve(prepared, changes, x0,
    x0_changes)`` gives (result JSON, solution vector) from the warm start x0 (solved at the
    changes ``x0_changes``; both None without one); ``row(result JSON)`` the values a summary
    keeps; ``warm``: points along a path start from the last one's solution; ``ship(doc, problem)``
    the document workers get; ``check(problem, doc, key, values)`` raises ``ValueError`` for a
    key a sweep cannot vary; ``changes(problem, [(key, values, value), ...])`` a point's
    changes; ``key_unit(problem, key)`` the unit of a key's values (the sweep picture's axis)."""

    prepare: Callable[[dict], Any]
    solve: Callable[..., tuple[dict, Any]]
    row: Callable[[dict], dict]
    warm: bool
    ship: Callable[[dict, Any], dict]
    check: Callable[..., None]
    changes: Callable[..., dict]
    key_unit: Callable[[Any, str], str]


@dataclass(frozen=True)
class Model:
    """One model's entry: reading a document, solving from Python and from the command line,
    output names and summaries, studies, and the model's own commands."""

    name: str
    parse: Callable[[dict[str, Any], str | Path], Any]
    solve: Callable[..., Any]
    options: tuple[str, ...]          # keyword options ``solve`` accepts
    compare: Callable[..., Any] | None
    compare_summary: Callable[..., str] | None
    document: Callable[[dict, Path], dict]      # the document ``knit-nlp solve`` solves
    flags: tuple                      # ``knit-nlp solve`` flags: (names, argparse keywords, group)
    solve_options: Callable[..., dict]          # (args, problem, path) -> ``solve`` options
    save_options: Callable[..., dict]           # args -> ``Result.save`` options
    outputs: tuple[str, ...]          # the <kind> of output names <problem>.<kind>.<suffix>
    summary: Callable[..., str]       # (result, paths written) -> what ``solve`` prints
    study: Study
    commands: tuple = ()              # (name, help, arguments, run): the model's own commands
    compare_check: Callable[..., list[int]] | None = None   # (problem, grids) -> checked k values
    prepare: Callable[..., tuple[Path, dict, str] | None] | None = None
    # (args, path, doc) -> (path, doc, flag): a document ``knit-nlp solve``'s flags rebuild
    # (weft: ``--size``), written to that path in --out as the result's source; None: as read
    warn: Callable[[Any], str | None] | None = None   # problem -> one warning line before a solve


def _solve_weft(problem: WeftProblem, reduced: bool | Parametrisation | None = None,
                **options: Any) -> WeftResult:
    """``reduced``: None (the file's choice), True (its representatives, or the corners),
    False, or a parametrisation."""
    if reduced is None or isinstance(reduced, (Full, Reduced, Adaptive)):
        param = reduced
    elif isinstance(reduced, bool):
        param = (problem.reduction or Reduced()) if reduced else Full()
    else:
        raise ValueError(f"reduced must be True, False, None, Full(), Reduced(...) or "
                         f"Adaptive(...); got {quoted(reduced)}")
    return solve_weft(problem, param, **options)


MODELS: dict[str, Model] = {
    "weft": Model(
        "weft", parse_weft, _solve_weft,
        ("reduced", "params", "continuation", "start", "warm_from_reduced", "verbose"),
        compare_weft, compare_summary, weft_commands.document, weft_commands.FLAGS,
        weft_commands.solve_options, weft_commands.save_options, ("full", "reduced"),
        weft_summary,
        Study(weft_study.prepare_point, weft_study.solve_point, weft_study.study_row, True,
              lambda doc, problem: doc, weft_keys.check, weft_keys.changes,
              weft_study.key_unit),
        weft_commands.COMMANDS, check_compare, weft_commands.prepare, weft_commands.warn),
    "jacquard": Model(
        "jacquard", parse_jacquard, solve_jacquard, ("solver",), None, None,
        jacquard_commands.document, jacquard_commands.FLAGS, jacquard_commands.solve_options,
        jacquard_commands.save_options, ("jacquard",), jacquard_summary,
        Study(jacquard_study.prepare_point, jacquard_study.solve_point,
              jacquard_study.study_row, False, jacquard_study.shippable_doc,
              jacquard_study.check, jacquard_study.changes, jacquard_study.key_unit)),
}


def model_of(doc: dict[str, Any], source: str | Path = "<document>") -> Model:
    """The entry of the model a document names (``model``, default ``weft``)."""
    name = doc.get("model", DEFAULT_MODEL)
    if not isinstance(name, str) or name not in MODELS:
        got = quoted(name) if isinstance(name, str) else f"{type_name(name)} {quoted(name)}"
        raise ProblemError(source, "", "model", f"must be one of {', '.join(map(repr, MODELS))}"
                           f" (a string, e.g. model = \"{DEFAULT_MODEL}\"); got {got}")
    return MODELS[name]


def parse_problem(doc: dict[str, Any], source: str | Path) -> Problem:
    """A checked problem of the model the document names (``model``, default ``weft``)."""
    return model_of(doc, source).parse(doc, source)


def load_problem(name_or_path: str | Path) -> Problem:
    """Read and check a problem file: a path, or the name of a shipped problem
    (``knit-nlp list``). Bad input raises :class:`~knit_nlp.errors.ProblemError`."""
    path = resolve(str(name_or_path))
    return parse_problem(load_toml(path), path)


def _problem(problem_or_name: Problem | str | Path) -> Problem:
    if isinstance(problem_or_name, (WeftProblem, JacquardProblem)):
        return problem_or_name
    if not isinstance(problem_or_name, (str, Path)):
        raise ValueError(f"expected a problem, a path or a shipped problem's name; got "
                         f"{quoted(problem_or_name)}")
    return load_problem(problem_or_name)


def solve(problem_or_name: Problem | str | Path, *, reduced: bool | Parametrisation | None = None,
          solver: str | None = None, **options: Any) -> Result:
    """Solve a problem (a loaded one, a path or a shipped name) and return its typed result.

    Weft: ``reduced`` None (the file's choice), True (its representatives, or the corners),
    False, or a ``Full()``/``Reduced(...)``/``Adaptive(...)``; options ``params``,
    ``continuation``, ``start``, ``warm_from_reduced``, ``verbose``. Jacquard: ``solver``
    "static" or "explicit" (default: the file's ``[solver] method``). A bad argument raises
    ``ValueError`` naming it; a bad file, :class:`~knit_nlp.errors.ProblemError`.
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


def compare(problem_or_name: WeftProblem | str | Path, *, warm: bool = False,
            grids: Sequence[int] = ()) -> Comparison:
    """Full and reduced models of a weft problem side by side (:class:`Comparison`), with a
    verdict; ``warm``: also solve the full model started from the reduced answer; ``grids``:
    also the even k × k grids for each k, each against the full model (``Comparison.frontier``,
    ``Comparison.fastest_ok``: the fastest within the verdict's limits)."""
    problem = _problem(problem_or_name)
    model = MODELS[problem.model]
    if model.compare is None:
        raise ValueError(f"compare is for weft problems; {problem.name!r} is a {model.name} problem")
    return model.compare(problem, warm=warm, grids=grids)


def calibrate(spec_or_path: CalibrationSpec | str | Path) -> CalibrationResult:
    """Fit weft material values on measured tensile tests and predict held-out ones: a
    calibration spec (a path, a shipped spec's name such as ``real_fabric/acrylic_fit_x``, or
    a loaded :class:`~knit_nlp.weft.inverse.calibration.CalibrationSpec`) in, a typed
    :class:`~knit_nlp.weft.inverse.calibration.CalibrationResult` out (``knit-nlp calibrate``;
    docs/real_fabric.md). The calibration's modules are imported here, when it runs: they load
    scipy (optimize, sparse, interpolate), 1.5-2 s of the front door's import under load that
    solving never needs."""
    from .weft.inverse.calibration import calibrate as calibrate_weft
    return calibrate_weft(spec_or_path)
