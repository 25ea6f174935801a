"""The weft model's part of the command line: its ``knit-nlp solve`` flags and how they become
solve and save options, and its own commands (``control``, ``fit``, ``overlay``, ``calibrate``,
``check``).

Everything here is data or a function the model table (``knit_nlp.api.MODELS``) points to; the
command line (``knit_nlp.cli``) reads it from there. A new weft command is one ``Command`` in
:data:`COMMANDS` and one function that runs it.
"""
from __future__ import annotations

import json
import sys
from argparse import ArgumentTypeError, Namespace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ArgumentError, ProblemError, quoted, shown
from ..outdir import prepare_out
from ..provenance import source_record
from ..problems import resolve
from ..tomlio import load_toml
from .inverse.spec import has_control_keys, strip_control_keys
from .model.problem import MAX_CONTINUATION, WeftProblem, parse_problem
from .model.reach import overstretch
from .model.resize import parse_size, resized
from .output.check import SAMPLES, check, check_spatial, load_result_json
from .output.export import COLOURINGS, EXPORTS


def _steps(text: str) -> int:
    """``--continuation``: a whole number of steps in 1..MAX_CONTINUATION (argparse type)."""
    try:
        steps = int(text)
    except ValueError:
        raise ArgumentTypeError(f"expected a whole number of steps, got {quoted(text)}") from None
    if not 1 <= steps <= MAX_CONTINUATION:
        raise ArgumentTypeError(f"must be in 1..{MAX_CONTINUATION}, got {steps}")
    return steps


# (names, argparse keywords, group): flags of one group exclude each other
FLAGS = (
    (("--reduced",), {"action": "store_true", "help": "solve the reduced model"}, "model"),
    (("--full",), {"action": "store_true", "help": "solve the full model"}, "model"),
    (("--continuation",), {"type": _steps, "default": None, "metavar": "STEPS",
                           "help": "always reach the clamp targets in this many warm-started "
                                   f"steps (1..{MAX_CONTINUATION})"}, None),
    (("--warm-from-reduced",), {"action": "store_true",
                                "help": "start the full model from the lifted reduced solution"},
     None),
    (("--verbose",), {"action": "store_true",
                      "help": "show IPOPT's iterations on one updating line (stderr)"}, None),
    (("--colour",), {"choices": COLOURINGS, "default": None,
                     "help": "colour the deformed loops by course (default) or by displacement "
                             "magnitude"}, None),
    (("--animate",), {"action": "store_true",
                      "help": "with a continuation, also write a GIF of the loading path"}, None),
    (("--export",), {"nargs": "+", "choices": EXPORTS, "default": [],
                     "help": "also write the deformed centrelines as CSV and/or SVG"}, None),
    (("--yarn",), {"action": "store_true",
                   "help": "draw the yarn with its thickness ([yarn] radius) and mark the "
                           "active contacts"}, None),
    (("--size",), {"default": None, "metavar": "COURSESxWALES",
                   "help": "solve a shipped pull (diagonal_pull, wada_fig7, course_stretch) "
                           "resized, its pull scaled with it; the resized problem file is "
                           "written to --out (e.g. --size 30x30)"}, None),
)


def prepare(args: Namespace, path: Path, doc: dict[str, Any],
            ) -> tuple[Path, dict[str, Any], str] | None:
    """``solve --size``: the shipped pull resized (model/resize.py), the file it is to be
    written to (``<out>/<name>.toml``) and the flag; None without ``--size``."""
    if args.size is None:
        return None
    courses, wales = parse_size(args.size)
    new = resized(doc, str(path), courses, wales)
    return Path(args.out) / f"{new['name']}.toml", new, f"--size {args.size}"


def warn(problem: WeftProblem) -> str | None:
    """One line before a solve whose pull asks the crossing springs to stretch beyond a loop
    length (model/reach.py, ``overstretch``), else None."""
    targets = np.array([c.target for c in problem.clamps]).reshape(-1, 2)
    rigid = np.array([[*r.translation, r.rotation] for r in problem.rigid_clamps]).reshape(-1, 3)
    return overstretch(problem, targets, rigid) or None


def document(doc: dict[str, Any], path: Path) -> dict[str, Any]:
    """The document ``knit-nlp solve`` solves: a control file (docs/inverse.md) at its start
    targets, its control keys ignored with a note."""
    if not has_control_keys(doc):
        return doc
    print(f"knit-nlp: {path}: control keys (actuated, bounds, goal, opening, control) ignored; "
          "solving at the start targets (see 'knit-nlp control')", file=sys.stderr)
    return strip_control_keys(doc)


def solve_options(args: Namespace, problem: WeftProblem, path: Path) -> dict[str, Any]:
    """``knit_nlp.solve`` options from the flags; a combination that cannot work is a
    ProblemError (exit 2)."""
    if args.warm_from_reduced and (args.reduced or (not args.full and problem.reduction)):
        raise ArgumentError("--warm-from-reduced", f"starts the full model, and {shown(path, 200)} "
                            "solves the reduced one: add --full (not --reduced)")
    if args.animate and not (args.continuation or problem.solver.continuation):
        raise ArgumentError("--animate", f"draws a loading path, and {shown(path, 200)} has none: "
                            "add --continuation N (or [solver] continuation = N)")
    if args.yarn and problem.yarn is None:
        raise ProblemError(path, "yarn", "radius", "--yarn draws the yarn's thickness: add "
                           "[yarn] radius = r (length units) to the problem file")
    opts: dict[str, Any] = {"continuation": args.continuation,
                            "warm_from_reduced": args.warm_from_reduced, "verbose": args.verbose}
    if args.reduced or args.full:
        opts["reduced"] = bool(args.reduced)
    return opts


def save_options(args: Namespace) -> dict[str, Any]:
    """``WeftResult.save`` options from the flags."""
    return {"colour": args.colour or "course", "export": args.export, "animate": args.animate,
            "yarn": args.yarn}


# The inverse problems' commands import their modules when they run: those load scipy
# (optimize, sparse, interpolate: 1.5-2 s of a loaded machine's 3.8 s CLI import, measured with
# ``python -X importtime -c "import knit_nlp.cli"``), which ``knit-nlp solve`` never needs.

def run_control(args: Namespace) -> int:
    """``knit-nlp control``: write ``<problem>.control.json`` and ``.png`` and print readable
    lines (``control_summary``); exit 0 only for a converged, stable, forward-checked answer."""
    from .inverse import run
    path = resolve(args.problem)
    return run.control_file(path, load_toml(path), Path(args.out))


def run_fit(args: Namespace) -> int:
    from .inverse import run
    run.check_params(args.params)           # before the problems are looked up
    return run.fit_files([resolve(p) for p in args.problems], Path(args.observations),
                         args.params, Path(args.out), args.name)


def run_overlay(args: Namespace) -> int:
    from .inverse import run
    return run.overlay_file(Path(args.result), Path(args.image), args.match,
                            Path(args.observations) if args.observations else None,
                            resolve(args.problem) if args.problem else None, Path(args.out))


def _samples(text: str) -> int:
    """``check --samples``: a whole number in 16..5000 (argparse type)."""
    try:
        value = int(text)
    except ValueError:
        raise ArgumentTypeError(f"expected a whole number, got {quoted(text)}") from None
    if not 16 <= value <= 5000:
        raise ArgumentTypeError(f"must be in 16..5000, got {value}")
    return value


def run_check(args: Namespace) -> int:
    """``knit-nlp check``: one line on stdout and ``<result stem>.check.json`` in ``--out``;
    0 clean, 1 violations (bad input: ProblemError, exit 2)."""
    result_path = Path(args.result)
    result = load_result_json(result_path)
    _is_result(result, result_path)
    given = resolve(args.problem) if args.problem else None
    problem = _problem_of(result, result_path, given)
    if given is not None:
        _same_source(result, result_path, given, problem)
    if problem.yarn is not None and problem.yarn.spatial:     # all pairs of pieces in 3-D
        report = check_spatial(result, problem, args.samples, str(result_path))
    else:
        report = check(result, problem, args.samples, str(result_path))
    report.save(prepare_out(args.out, problem.name, ()), result_path)
    print(report.line())
    return 0 if report.ok else 1


def _is_result(result: Any, path: Path) -> None:
    """A weft result is a JSON object with ``loops`` (a solve's) or ``equilibrium`` (a
    control's); anything else is refused by what it is (``null`` was "not a regular file":
    its empty name led to the problems' folder)."""
    if isinstance(result, dict) and ("loops" in result or "equilibrium" in result):
        return
    what = ("an object without 'loops'" if isinstance(result, dict) else
            f"{json.dumps(result)[:40]}" if not isinstance(result, (list, dict)) else
            "a list")
    raise ProblemError(path, "", "", f"is not a weft result: it holds {what}, and a result is "
                       "an object with 'loops' (knit-nlp solve's) or 'equilibrium' (control's)")


def _natural_of(pr: WeftProblem) -> tuple:
    """What a check judges a result against, besides the radius: the fabric's size and its
    natural loop."""
    nat = pr.natural
    return (pr.courses, pr.wales, nat.length, nat.harmonics,
            tuple(np.round(np.ravel(nat.coeffs), 12).tolist()), round(nat.wale_spacing, 12),
            round(nat.rise, 12), round(nat.course_spacing, 12))


def _same_source(result: dict, result_path: Path, given: Path, problem: WeftProblem) -> None:
    """Refuse (exit 2) a ``--problem`` that is not the result's: the result records its
    source file's sha256. Another file is accepted when the recorded file is still there,
    unchanged, with the same fabric and natural loop as the given one (it may add or change
    [yarn] radius: a paper's result judged with a radius)."""
    record = result.get("source")
    if not isinstance(record, dict) or not isinstance(record.get("sha256"), str):
        return                                   # nothing recorded to compare with
    mine = source_record(given)
    if mine is None or mine["sha256"] == record["sha256"]:
        return
    recorded = Path(str(record.get("file", "")))
    there = source_record(recorded) if recorded.is_file() else None
    why = f"its recorded source {quoted(str(recorded))} is gone or changed"
    if there is not None and there["sha256"] == record["sha256"]:
        theirs = parse_problem(strip_control_keys(load_toml(recorded)), recorded)
        if _natural_of(theirs) == _natural_of(problem):
            return
        why = (f"its fabric or natural loop differs from that of {quoted(str(recorded))} "
               f"(loop length {problem.L:g} against {theirs.L:g}, {problem.courses} x "
               f"{problem.wales} loops against {theirs.courses} x {theirs.wales})")
    raise ProblemError(given, "", "", f"is not the problem {shown(result_path, 200)} was solved "
                       f"from (another sha256), and {why}: pass the problem it was solved "
                       "from")


def _problem_of(result: Any, result_path: Path, given: Path | None) -> WeftProblem:
    """The result's problem: ``given``, else its recorded source file, else a file named
    after it beside the result or among the named problems."""
    if given is None:
        name = str(result.get("problem", "")) if isinstance(result, dict) else ""
        source = result.get("source") if isinstance(result, dict) else None
        recorded = Path(source["file"]) if isinstance(source, dict) and isinstance(
            source.get("file"), str) else None
        if not name.strip() and recorded is None:
            raise ProblemError(result_path, "", "problem", "names no problem and records no "
                               "source file; pass --problem FILE")
        for candidate in (recorded, result_path.parent / f"{name}.toml"):
            if candidate is not None and candidate.is_file():
                given = candidate
                break
        else:
            try:
                given = resolve(name)
            except ProblemError:
                raise ProblemError(result_path, "", "problem", f"cannot find the problem file "
                                   f"{quoted(name)}; pass --problem FILE") from None
    doc = load_toml(given)
    if doc.get("model", "weft") != "weft":
        raise ProblemError(given, "", "model", "check is for weft results")
    return parse_problem(strip_control_keys(doc), given)


def run_calibrate(args: Namespace) -> int:
    from .inverse.calibration import command
    return command.run(args)


OUT = (("--out",), {"default": "results", "help": "output folder (default: results)"})
# (name, help, arguments (names, argparse keywords), run)
COMMANDS = (
    ("control", "weft: move actuated clamps so points reach goals",
     ((("problem",), {}), OUT), run_control),
    ("fit", "weft: fit material values to observed points",
     ((("problems",), {"nargs": "+", "metavar": "PROBLEM"}),
      (("--observations",), {"required": True, "metavar": "FILE.csv"}),
      (("--params",), {"nargs": "+", "default": ["k_a", "k_b", "R_f"]}),
      (("--name",), {"default": None, "help": "output name: <name>.fit.json, .fit.png "
                                              "(default: the load cases' names joined by +)"}),
      OUT), run_fit),
    ("overlay", "weft: draw a result over a photograph",
     ((("result",), {"metavar": "RESULT.json"}), (("image",), {"metavar": "IMAGE"}),
      (("--match",), {"action": "append", "default": [], "metavar": "C,W,POINT=PX,PY"}),
      (("--observations",), {"default": None, "metavar": "FILE.csv"}),
      (("--problem",), {"default": None, "help": "the result's problem file (to resolve point "
                                                 "labels; default: found by the result's name)"}),
      OUT), run_overlay),
    ("calibrate", "weft: fit material values on measured tensile tests and predict held-out ones",
     ((("spec",), {"metavar": "SPEC.toml",
                   "help": "a calibration spec: a weft problem file with [[test]] tables and a "
                           "[calibrate] table, or one under the named problems' folder, e.g. "
                           "real_fabric/acrylic_fit_x"}), OUT,
      (("--force",), {"action": "store_true",
                      "help": "overwrite results of another spec in --out"}),
      (("--breaks",), {"action": "store_true",
                       "help": "also where the model breaks: each measured value moved alone "
                               "from the answer against the targets (as [calibrate] breaks = "
                               "true; minutes in 3-D)"})), run_calibrate),
    ("check", "weft: count yarns passing through each other (crossings not in the natural "
     "fabric) and gaps below 2r in a result",
     ((("result",), {"metavar": "RESULT.json"}),
      (("--problem",), {"default": None, "help": "the result's problem file (default: its "
                                                 "recorded source, or found by its name)"}),
      (("--samples",), {"type": _samples, "default": SAMPLES, "metavar": "N",
                        "help": f"polyline samples per loop (default {SAMPLES}): the "
                                "crossing count's (at least 200, the solver's), and the gap "
                                "search's up to 4 per radius"}), OUT),
     run_check),
)
