"""The ``knit-nlp`` command line (README, "Command line").

Exit codes: 0 success, 1 solver did not converge (results still written, ``"success": false``),
2 bad problem file or bad arguments (one line naming file, table and key; no traceback).
Commands dispatch by the problem's model through :data:`knit_nlp.api.MODELS`; which flags
apply to which model is said once, in :data:`FLAGS`.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .api import MODELS, load_problem, parse_problem
from .errors import ProblemError, quoted, shown
from .problems import named_problems, resolve
from .provenance import check_overwrite
from .weft.export import EXPORTS
from .weft.plot import COLOURINGS

MAX_CONTINUATION = 1000
# the middle part of the output names each command writes: <name>.<kind>.<suffix>
OUTPUTS = {"weft": ("full", "reduced"), "compare": ("compare",), "jacquard": ("jacquard",)}

# CLI flag -> the model it applies to
FLAGS = {"--reduced": "weft", "--full": "weft", "--continuation": "weft",
         "--warm-from-reduced": "weft", "--verbose": "weft", "--colour": "weft",
         "--animate": "weft", "--export": "weft", "--solver": "jacquard", "--svg": "jacquard"}


class _Parser(argparse.ArgumentParser):
    """argparse that exits 2 with one line (its default already uses 2; keep the message short
    and printable: arguments are echoed escaped)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"knit-nlp: {shown(message, 300)}", file=sys.stderr)
        raise SystemExit(2)


def _steps(text: str) -> int:
    """``--continuation``: a whole number of steps in 1..MAX_CONTINUATION."""
    try:
        steps = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of steps, got "
                                         f"{quoted(text)}") from None
    if not 1 <= steps <= MAX_CONTINUATION:
        raise argparse.ArgumentTypeError(f"must be in 1..{MAX_CONTINUATION}, got {steps}")
    return steps


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="knit-nlp", description="Mechanics of knitted fabrics as nonlinear programs.")
    parser.add_argument("--version", action="version", version=f"knit-nlp {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    solve = sub.add_parser("solve", help="solve a problem file and write results")
    solve.add_argument("problem", help="a problem file, or the name of one in problems/")
    which = solve.add_mutually_exclusive_group()
    which.add_argument("--reduced", action="store_true", help="weft: solve the reduced model")
    which.add_argument("--full", action="store_true", help="weft: solve the full model")
    solve.add_argument("--out", default="results", help="output folder (default: results)")
    solve.add_argument("--continuation", type=_steps, default=None, metavar="STEPS",
                       help="weft: always reach the clamp targets in this many warm-started "
                       f"steps (1..{MAX_CONTINUATION})")
    solve.add_argument("--warm-from-reduced", action="store_true",
                       help="weft: start the full model from the lifted reduced solution")
    solve.add_argument("--verbose", action="store_true",
                       help="weft: show IPOPT's iterations on one updating line (stderr)")
    solve.add_argument("--colour", choices=COLOURINGS, default=None,
                       help="weft: colour the deformed loops by course (default) or by "
                       "displacement magnitude")
    solve.add_argument("--animate", action="store_true",
                       help="weft: with a continuation, also write a GIF of the loading path")
    solve.add_argument("--export", nargs="+", choices=EXPORTS, default=[],
                       help="weft: also write the deformed centrelines as CSV and/or SVG")
    solve.add_argument("--force", action="store_true",
                       help="overwrite results of another problem in --out")
    solve.add_argument("--solver", choices=["static", "explicit"], default=None,
                       help="jacquard: override [solver] method")
    solve.add_argument("--svg", action="store_true", help="jacquard: also write an SVG picture")
    compare = sub.add_parser("compare", help="weft: solve full and reduced models and compare them")
    compare.add_argument("problem")
    compare.add_argument("--out", default="results")
    compare.add_argument("--force", action="store_true",
                         help="overwrite results of another problem in --out")
    sub.add_parser("list", help="list the named problems")
    _sweep_parser(sub)
    _inverse_parsers(sub)
    _calibrate_parser(sub)
    return parser


def _sweep_parser(sub: Any) -> None:
    from .studies.executors import add_executor_arguments

    sweep = sub.add_parser("sweep", help="solve a grid of problem-file values (README, Sweeps)")
    sweep.add_argument("problem", help="a problem file, or the name of one in problems/")
    sweep.add_argument("--vary", action="append", default=[], metavar="KEY=START:STOP:COUNT",
                       help="a grid axis of independent points (repeat for a grid)")
    sweep.add_argument("--path", action="append", default=[], metavar="KEY=START:STOP:COUNT",
                       help="weft: a loading-path axis, solved in order and warm-started (repeat: "
                            "the axes step together)")
    sweep.add_argument("--name", default=None, help="study name (default: sweep_<problem>)")
    sweep.add_argument("--out", default="results", help="output folder (default: results)")
    add_executor_arguments(sweep)


def _inverse_parsers(sub) -> None:
    """control, fit and overlay (README, "Deformation control and identification")."""
    ctl = sub.add_parser("control", help="weft: move actuated clamps so points reach goals")
    ctl.add_argument("problem")
    ctl.add_argument("--out", default="results")
    fit = sub.add_parser("fit", help="weft: fit material values to observed points")
    fit.add_argument("problems", nargs="+", metavar="PROBLEM")
    fit.add_argument("--observations", required=True, metavar="FILE.csv")
    fit.add_argument("--params", nargs="+", default=["k_a", "k_b", "R_f"])
    fit.add_argument("--out", default="results")
    ov = sub.add_parser("overlay", help="weft: draw a result over a photograph")
    ov.add_argument("result", metavar="RESULT.json")
    ov.add_argument("image", metavar="IMAGE")
    ov.add_argument("--match", action="append", default=[], metavar="C,W,POINT=PX,PY")
    ov.add_argument("--observations", default=None, metavar="FILE.csv")
    ov.add_argument("--problem", default=None, help="the result's problem file (to resolve point "
                    "labels; default: found by the result's name)")
    ov.add_argument("--out", default="results")


def _cmd_inverse(args: argparse.Namespace) -> int:
    """``control``, ``fit`` and ``overlay`` (weft only; knit_nlp.weft.inverse.run)."""
    from .tomlio import load_toml
    from .weft.inverse import run
    check_out(args.out)
    if args.command == "control":
        path = resolve(args.problem)
        return run.control_file(path, load_toml(path), Path(args.out))
    if args.command == "fit":
        return run.fit_files([resolve(p) for p in args.problems], Path(args.observations),
                             args.params, Path(args.out))
    return run.overlay_file(Path(args.result), Path(args.image), args.match,
                            Path(args.observations) if args.observations else None,
                            resolve(args.problem) if args.problem else None, Path(args.out))


def _cmd_list(args: argparse.Namespace) -> int:
    rows = [(shown(n), shown(m), shown(d, 200)) for n, m, d in named_problems()]
    width = max((len(r[0]) for r in rows), default=4)
    for name, model, description in rows:
        print(f"{name:<{width}}  {model:<8}  {description}")
    return 0


def _given_flags(args: argparse.Namespace) -> list[str]:
    """The model-specific flags given on the command line."""
    values = {"--reduced": args.reduced, "--full": args.full,
              "--continuation": args.continuation is not None,
              "--warm-from-reduced": args.warm_from_reduced, "--verbose": args.verbose,
              "--colour": args.colour is not None, "--animate": args.animate,
              "--export": bool(args.export),
              "--solver": args.solver is not None, "--svg": args.svg}
    return [flag for flag, given in values.items() if given]


def _solve_options(args: argparse.Namespace, model: str) -> dict[str, Any]:
    if model == "weft":
        opts: dict[str, Any] = {"continuation": args.continuation,
                                "warm_from_reduced": args.warm_from_reduced,
                                "verbose": args.verbose}
        if args.reduced or args.full:
            opts["reduced"] = bool(args.reduced)
        return opts
    return {"solver": args.solver}


def _cmd_solve(args: argparse.Namespace) -> int:
    path = resolve(args.problem)
    problem = _problem_for_solve(path)
    wrong = [f for f in _given_flags(args) if FLAGS[f] != problem.model]
    if wrong:
        raise ProblemError(path, "", "model", f"{'/'.join(wrong)} apply to {FLAGS[wrong[0]]} "
                           f"problems only; this is a {problem.model} problem")
    if args.warm_from_reduced and args.reduced or (
            args.warm_from_reduced and not args.full and getattr(problem, "reduction", None)):
        raise ProblemError(path, "", "", "--warm-from-reduced starts the full model: add --full")
    if args.animate and not (args.continuation or getattr(problem.solver, "continuation", None)):
        raise ProblemError(path, "", "", "--animate draws a loading path: add --continuation N")
    out = prepare_out(args.out, problem.name, OUTPUTS[problem.model])
    check_overwrite(out.glob(f"{problem.name}.*.json"), path, args.force)
    result = MODELS[problem.model].solve(problem, **_solve_options(args, problem.model))
    with np.errstate(invalid="ignore", over="ignore"):  # a diverged run: NaN figures (null)
        paths = result.save(out, **_save_options(args, problem.model))
        print(_summary(problem.model)(result, paths))
    return 0 if result.success else 1


def _problem_for_solve(path: Path):
    """The problem to solve; a control file (spec/inverse_problems.md) is solved at its start
    targets, its control keys ignored with a note."""
    from .tomlio import load_toml
    from .weft.inverse.spec import has_control_keys, strip_control_keys
    doc = load_toml(path)
    if has_control_keys(doc):
        print(f"knit-nlp: {path}: control keys (actuated, bounds, goal, opening, control) ignored; "
              "solving at the start targets (see 'knit-nlp control')", file=sys.stderr)
        doc = strip_control_keys(doc)
    return parse_problem(doc, path)


def _save_options(args: argparse.Namespace, model: str) -> dict[str, Any]:
    if model == "weft":
        return {"colour": args.colour or "course", "export": args.export,
                "animate": args.animate}
    return {"svg": True} if args.svg else {}


def _summary(model: str):
    if model == "weft":
        from .weft.summary import solve_summary
    else:
        from .jacquard.summary import solve_summary
    return solve_summary


def _cmd_compare(args: argparse.Namespace) -> int:
    path = resolve(args.problem)
    problem = load_problem(path)
    compare = MODELS[problem.model].compare
    if compare is None:
        raise ProblemError(path, "", "model", f"compare is for weft problems; this is a "
                           f"{problem.model} problem")
    from .weft.summary import compare_summary
    out = prepare_out(args.out, problem.name, OUTPUTS["compare"])
    check_overwrite(out.glob(f"{problem.name}.*.json"), path, args.force)
    cmp = compare(problem)
    print(compare_summary(cmp, cmp.save(out)))
    return 0 if cmp.success else 1


def _cmd_sweep(args: argparse.Namespace) -> int:
    from .studies import overview, sweep
    from .studies.runner import print_table, run_with_options
    from .tomlio import load_toml

    path = resolve(args.problem)
    doc = load_toml(path)
    problem = load_problem(path)
    name = sweep.study_name(args.name or f"sweep_{problem.name}")
    vary = [sweep.parse_axis("--vary", a) for a in args.vary]
    along = [sweep.parse_axis("--path", a) for a in args.path]
    paths = sweep.sweep_paths(doc, problem, vary, along)
    prepare_out(str(Path(args.out) / name), "sweep", ())
    summary = run_with_options(name, paths, Path(args.out), args)
    keys = [a.key for a in (*vary, *along)]
    out = Path(args.out) / name
    rows = overview.table_rows(summary, keys)
    csv = overview.write_table(out / "sweep.csv", rows)
    png = overview.plot_overview(out / "sweep.png", summary, keys,
                                 f"{problem.name}: {len(rows)} points")
    print_table([{**r, "point": f"{r['path']}.{r['index']}"} for r in rows],
                [("point", "point", ""), *((k, k, "") for k in keys),
                 ("energy_total", "U total", ".6g"), ("iterations", "it", ""),
                 ("success", "ok", "")])
    failed = sum(not r["success"] for r in rows)
    print(f"{len(rows) - failed} of {len(rows)} points converged; wrote {out / 'summary.json'}, "
          f"{csv}, {png}")
    return 0 if failed == 0 else 1


def _calibrate_parser(sub: Any) -> None:
    """``calibrate`` (weft.calibration.command: its own module, hooked in here)."""
    from .weft.calibration.command import add_parser
    add_parser(sub)


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from .weft.calibration.command import run
    check_out(args.out)
    return run(args, prepare_out, check_overwrite)


COMMANDS = {"list": _cmd_list, "solve": _cmd_solve, "compare": _cmd_compare, "sweep": _cmd_sweep,
            "control": _cmd_inverse, "fit": _cmd_inverse, "overlay": _cmd_inverse,
            "calibrate": _cmd_calibrate}


def check_out(out: str) -> Path:
    """The output folder, checked without creating anything: refused (one line, exit 2) if it
    names a file, lies under a file, or its nearest existing folder cannot be written."""
    folder = Path(out)
    if not out or "\0" in out:
        raise ProblemError("--out", "", "", f"not a usable folder name: {quoted(out)}")
    try:
        if folder.exists() and not folder.is_dir():
            raise ProblemError(out, "", "", "--out names an existing file; give a folder")
        existing = next(p for p in (folder, *folder.absolute().parents) if p.exists())
    except OSError as err:
        raise ProblemError(out, "", "", f"cannot create the output folder "
                           f"({shown(err.strerror or err)})") from None
    if not existing.is_dir():
        raise ProblemError(out, "", "", f"--out lies under {quoted(existing)}, which is "
                           "not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ProblemError(out, "", "", f"cannot create the output folder (cannot write into "
                           f"{quoted(existing)})")
    return folder


def prepare_out(out: str, name: str, kinds: tuple[str, ...]) -> Path:
    """The output folder, checked (:func:`check_out`) and created; also refused if it holds a
    non-file where an output must go. Called after the problem is read and checked, before
    solving: bad input writes nothing."""
    folder = check_out(out)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ProblemError(out, "", "", f"cannot create the output folder "
                           f"({shown(err.strerror or err)})") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ProblemError(out, "", "", "cannot write into the output folder")
    for kind in kinds:
        for suffix in ("json", "npz", "png", "svg", "csv", "gif"):
            target = folder / f"{name}.{kind}.{suffix}"
            if target.exists() and not target.is_file():
                raise ProblemError(out, "", "", f"{quoted(target.name)} exists and is not a "
                                   "file; results cannot be written there")
    return folder


def main(argv: list[str] | None = None) -> int:
    try:
        args = _parser().parse_args(argv)
    except SystemExit as stop:              # --help (0) or a bad argument (2, one line)
        return int(stop.code or 0)
    try:
        return COMMANDS[args.command](args)
    except ProblemError as err:
        print(f"knit-nlp: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:                     # output piped into e.g. `head`: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
