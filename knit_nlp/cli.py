"""The ``knit-nlp`` command line (spec/problem_files.md, "Command line").

Exit codes: 0 success, 1 solver did not converge (results still written, ``"success": false``),
2 bad problem file or bad arguments (one line naming file, table and key; no traceback).
Every check on the problem file and the arguments happens before anything is built or written.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from .errors import ProblemError, quoted, shown
from .problems import named_problems, resolve
from .tomlio import load_toml

MAX_CONTINUATION = 1000
OUTPUTS = {"weft": ("full", "reduced"), "compare": ("compare",), "jacquard": ("jacquard",)}


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
    solve.add_argument("--solver", choices=["static", "explicit"], default=None,
                       help="jacquard: override [solver] method")
    solve.add_argument("--svg", action="store_true", help="jacquard: also write an SVG picture")
    compare = sub.add_parser("compare", help="solve full and reduced models and compare them")
    compare.add_argument("problem")
    compare.add_argument("--out", default="results")
    sub.add_parser("list", help="list the named problems")
    return parser


def _cmd_list() -> int:
    rows = [(shown(n), shown(m), shown(d, 200)) for n, m, d in named_problems()]
    width = max((len(r[0]) for r in rows), default=4)
    for name, model, description in rows:
        print(f"{name:<{width}}  {model:<8}  {description}")
    return 0


def prepare_out(out: str, name: str, kinds: tuple[str, ...]) -> Path:
    """The output folder, created: refused (one line, exit 2) if it names a file, lies under a
    file, cannot be created or written, or holds a non-file where an output must go."""
    folder = Path(out)
    if not out or "\0" in out:
        raise ProblemError("--out", "", "", f"not a usable folder name: {quoted(out)}")
    try:
        if folder.exists() and not folder.is_dir():
            raise ProblemError(out, "", "", "--out names an existing file; give a folder")
        existing = next(p for p in (folder, *folder.parents) if p.exists())
        if not existing.is_dir():
            raise ProblemError(out, "", "", f"--out lies under {quoted(existing)}, which is "
                               "not a folder")
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ProblemError(out, "", "", f"cannot create the output folder "
                           f"({shown(err.strerror or err)})") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ProblemError(out, "", "", "cannot write into the output folder")
    for kind in kinds:
        for suffix in ("json", "npz", "png", "svg"):
            target = folder / f"{name}.{kind}.{suffix}"
            if target.exists() and not target.is_file():
                raise ProblemError(out, "", "", f"{quoted(target.name)} exists and is not a "
                                   "file; results cannot be written there")
    return folder


def _load(problem: str) -> tuple[Path, dict[str, Any], str]:
    path = resolve(problem)
    doc = load_toml(path)
    model = doc.get("model", "weft")
    if model not in ("weft", "jacquard"):
        raise ProblemError(path, "", "model", f"must be 'weft' or 'jacquard'; got {quoted(model)}")
    return path, doc, model


def _cmd_solve(args: argparse.Namespace) -> int:
    path, doc, model = _load(args.problem)
    if model == "jacquard":
        if args.reduced or args.full or args.continuation is not None or args.warm_from_reduced:
            raise ProblemError(path, "", "model", "--reduced/--full/--continuation/"
                               "--warm-from-reduced apply to weft problems only")
        from .jacquard import parse_problem as parse_jacquard, solve_file
        out = prepare_out(args.out, parse_jacquard(doc, path).name, OUTPUTS["jacquard"])
        return solve_file(path, doc, out, solver=args.solver, svg=args.svg)
    if args.solver is not None or args.svg:
        raise ProblemError(path, "", "model", "--solver/--svg apply to jacquard problems only")
    from .weft.problem import parse_problem as parse_weft
    from .weft.run import solve_file as weft_solve
    out = prepare_out(args.out, parse_weft(path, doc).name, OUTPUTS["weft"])
    reduced = True if args.reduced else False if args.full else None
    return weft_solve(path, doc, out, reduced=reduced, continuation=args.continuation,
                      warm_from_reduced=args.warm_from_reduced)


def _cmd_compare(args: argparse.Namespace) -> int:
    path, doc, model = _load(args.problem)
    if model != "weft":
        raise ProblemError(path, "", "model", "compare applies to weft problems only")
    from .weft.problem import parse_problem as parse_weft
    from .weft.run import compare_file
    out = prepare_out(args.out, parse_weft(path, doc).name, OUTPUTS["compare"])
    return compare_file(path, doc, out)


def main(argv: list[str] | None = None) -> int:
    try:
        args = _parser().parse_args(argv)
    except SystemExit as stop:              # --help (0) or a bad argument (2, one line)
        return int(stop.code or 0)
    try:
        if args.command == "list":
            return _cmd_list()
        if args.command == "solve":
            return _cmd_solve(args)
        return _cmd_compare(args)
    except ProblemError as err:
        print(f"knit-nlp: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:                     # output piped into e.g. `head`: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
