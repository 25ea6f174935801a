"""The ``knit-nlp`` command line (spec/problem_files.md, "Command line").

Exit codes: 0 success, 1 solver did not converge (results still written, ``"success": false``),
2 bad problem file or bad arguments (one line naming file, table and key; no traceback).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .errors import ProblemError
from .problems import named_problems, resolve
from .tomlio import load_toml


class _Parser(argparse.ArgumentParser):
    """argparse that exits 2 with one line (its default already uses 2; keep the message short)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"knit-nlp: {message}", file=sys.stderr)
        raise SystemExit(2)


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="knit-nlp", description="Mechanics of knitted fabrics as nonlinear programs.")
    sub = parser.add_subparsers(dest="command", required=True)
    solve = sub.add_parser("solve", help="solve a problem file and write results")
    solve.add_argument("problem", help="a problem file, or the name of one in problems/")
    which = solve.add_mutually_exclusive_group()
    which.add_argument("--reduced", action="store_true", help="weft: solve the reduced model")
    which.add_argument("--full", action="store_true", help="weft: solve the full model")
    solve.add_argument("--out", default="results", help="output folder (default: results)")
    solve.add_argument("--continuation", type=int, default=None, metavar="STEPS",
                       help="weft: always reach the clamp targets in this many warm-started steps")
    solve.add_argument("--warm-from-reduced", action="store_true",
                       help="weft: start the full model from the lifted reduced solution")
    solve.add_argument("--solver", choices=["static", "explicit"], default=None,
                       help="jacquard: override [solver] method")
    solve.add_argument("--svg", action="store_true", help="jacquard: also write an SVG picture")
    compare = sub.add_parser("compare", help="solve full and reduced models and compare them")
    compare.add_argument("problem")
    compare.add_argument("--out", default="results")
    sub.add_parser("list", help="list the named problems")
    _inverse_parsers(sub)
    return parser


def _inverse_parsers(sub) -> None:
    """control, fit and overlay (spec/inverse_problems.md)."""
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
    from .weft.inverse import run
    if args.command == "control":
        path = resolve(args.problem)
        return run.control_file(path, load_toml(path), Path(args.out))
    if args.command == "fit":
        return run.fit_files([resolve(p) for p in args.problems], Path(args.observations),
                             args.params, Path(args.out))
    return run.overlay_file(Path(args.result), Path(args.image), args.match,
                            Path(args.observations) if args.observations else None,
                            resolve(args.problem) if args.problem else None, Path(args.out))


def _cmd_list() -> int:
    rows = named_problems()
    width = max((len(r[0]) for r in rows), default=4)
    for name, model, description in rows:
        print(f"{name:<{width}}  {model:<8}  {description}")
    return 0


def _cmd_solve(args: argparse.Namespace) -> int:
    path = resolve(args.problem)
    doc = load_toml(path)
    model = doc.get("model", "weft")
    out = Path(args.out)
    if model == "jacquard":
        if args.reduced or args.full or args.continuation is not None or args.warm_from_reduced:
            raise ProblemError(path, "", "model", "--reduced/--full/--continuation/"
                               "--warm-from-reduced apply to weft problems only")
        from .jacquard import solve_file
        return solve_file(path, doc, out, solver=args.solver, svg=args.svg)
    if model != "weft":
        raise ProblemError(path, "", "model", f"must be 'weft' or 'jacquard'; got {model!r}")
    if args.solver is not None or args.svg:
        raise ProblemError(path, "", "model", "--solver/--svg apply to jacquard problems only")
    from .weft.inverse.spec import has_control_keys, strip_control_keys
    if has_control_keys(doc):
        print(f"knit-nlp: {path}: control keys (actuated, bounds, goal, opening, control) ignored; "
              "solving at the start targets (see 'knit-nlp control')", file=sys.stderr)
        doc = strip_control_keys(doc)
    from .weft.run import solve_file as weft_solve
    reduced = True if args.reduced else False if args.full else None
    return weft_solve(path, doc, out, reduced=reduced, continuation=args.continuation,
                      warm_from_reduced=args.warm_from_reduced)


def _cmd_compare(args: argparse.Namespace) -> int:
    path = resolve(args.problem)
    doc = load_toml(path)
    from .weft.run import compare_file
    return compare_file(path, doc, Path(args.out))


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "list":
            return _cmd_list()
        if args.command == "solve":
            return _cmd_solve(args)
        if args.command in ("control", "fit", "overlay"):
            return _cmd_inverse(args)
        return _cmd_compare(args)
    except ProblemError as err:
        print(f"knit-nlp: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:                     # output piped into e.g. `head`: stop quietly
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
