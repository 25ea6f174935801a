"""The ``knit-nlp`` command line.

Exit codes: 0 success, 1 solver did not converge (results still written, ``"success": false``),
2 bad problem file or bad arguments (one line naming file, table and key; no traceback).
Commands dispatch by the problem's model through :data:`knit_nlp.api.MODELS`: each model's
entry gives its ``solve`` flags, how they become options, its output names and summary, and its
own commands (``control``, ``fit``, ``overlay`` are the weft model's).
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from . import __version__
from .api import MODELS, Model, load_problem, model_of
from .errors import ArgumentError, ProblemError, shown
from .problems import named_problems, resolve
from .outdir import check_out, prepare_out
from .provenance import check_overwrite
from .studies import overview, sweep
from .studies.executors import add_executor_arguments
from .studies.runner import prepare_study, print_table, run_with_options
from .tomlio import load_toml, toml_text


class _Parser(argparse.ArgumentParser):
    """argparse that exits 2 with one line (its default already uses 2; keep the message short
    and printable: arguments are echoed escaped)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        print(f"knit-nlp: {shown(message, 300)}", file=sys.stderr)
        raise SystemExit(2)


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="knit-nlp", description="Mechanics of knitted fabrics as nonlinear programs.")
    parser.add_argument("--version", action="version", version=f"knit-nlp {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    solve = sub.add_parser("solve", help="solve a problem file and write results")
    solve.add_argument("problem", help="a problem file, or the name of one in problems/")
    solve.add_argument("--out", default="results", help="output folder (default: results)")
    solve.add_argument("--force", action="store_true",
                       help="overwrite results of another problem in --out")
    for model in MODELS.values():
        groups: dict[str, Any] = {}
        for names, options, group in model.flags:
            if group is not None and group not in groups:   # one group per name, made once
                groups[group] = solve.add_mutually_exclusive_group()
            target = solve if group is None else groups[group]
            target.add_argument(*names, **{**options, "help": f"{model.name}: {options['help']}"})
    solve.set_defaults(run=_cmd_solve)
    compare = sub.add_parser("compare", help="solve full and reduced models and compare them "
                             "(models that offer it: "
                             f"{', '.join(m.name for m in MODELS.values() if m.compare)})")
    compare.add_argument("problem")
    compare.add_argument("--out", default="results")
    compare.add_argument("--force", action="store_true",
                         help="overwrite results of another problem in --out")
    compare.add_argument("--warm", action="store_true",
                         help="also solve the full model started from the reduced answer "
                              "(finds another local minimum; costs about one more full solve)")
    compare.add_argument("--grids", type=int, nargs="+", default=[], metavar="K",
                         help="also solve the even K x K reduced grids (2: the corner form) and "
                              "print accuracy against time for each, with the fastest within "
                              "the verdict's limits")
    compare.set_defaults(run=_cmd_compare)
    sub.add_parser("list", help="list the named problems (and those in their folders)").set_defaults(run=_cmd_list)
    _sweep_parser(sub)
    for model in MODELS.values():
        for name, help_text, arguments, run in model.commands:
            cmd = sub.add_parser(name, help=help_text)
            for names, options in arguments:
                cmd.add_argument(*names, **options)
            cmd.set_defaults(run=_model_command(run))
    return parser


def _sweep_parser(sub: Any) -> None:
    sweep_cmd = sub.add_parser("sweep", help="solve a grid of problem-file values (docs/studies.md)")
    sweep_cmd.add_argument("problem", help="a problem file, or the name of one in problems/")
    sweep_cmd.add_argument("--vary", action="append", default=[], metavar="KEY=START:STOP:COUNT",
                           help="a grid axis of independent points (repeat for a grid)")
    sweep_cmd.add_argument("--path", action="append", default=[], metavar="KEY=START:STOP:COUNT",
                           help="a loading-path axis, solved in order and warm-started (repeat: "
                                "the axes step together; models with warm starts only)")
    sweep_cmd.add_argument("--name", default=None, help="study name (default: sweep_<problem>)")
    sweep_cmd.add_argument("--out", default="results", help="output folder (default: results)")
    add_executor_arguments(sweep_cmd)
    sweep_cmd.set_defaults(run=_cmd_sweep)


def _model_command(run: Any) -> Any:
    """A model's own command: its ``--out`` checked first (nothing written on bad input)."""
    def command(args: argparse.Namespace) -> int:
        check_out(args.out)
        return run(args)
    return command


def _cmd_list(args: argparse.Namespace) -> int:
    rows = [(shown(n), shown(m), shown(d, 200)) for n, m, d in named_problems(folders=True)]
    width = max((len(r[0]) for r in rows), default=4)
    kind = max((len(r[1]) for r in rows), default=8)
    for name, model, description in rows:
        print(f"{name:<{width}}  {model:<{kind}}  {description}")
    return 0


def _flag_given(args: argparse.Namespace, names: tuple[str, ...], options: dict[str, Any]) -> bool:
    value = getattr(args, names[0].lstrip("-").replace("-", "_"))
    default = options.get("default", False if options.get("action") == "store_true" else None)
    return value != default


def _foreign_flags(args: argparse.Namespace, model: Model) -> list[tuple[str, str]]:
    """(flag, its model) for every flag given that belongs to another model."""
    return [(names[0], other.name) for other in MODELS.values() if other is not model
            for names, options, _ in other.flags if _flag_given(args, names, options)]


def _cmd_solve(args: argparse.Namespace) -> int:
    path = resolve(args.problem)
    doc = load_toml(path)
    model = model_of(doc, path)
    wrong = _foreign_flags(args, model)
    rebuilt = None if wrong or model.prepare is None else model.prepare(args, path, doc)
    if rebuilt is not None:                     # a document the flags rebuilt (weft: --size)
        path, doc, flag = rebuilt
    problem = model.parse(model.document(doc, path), path)
    if rebuilt is not None:                     # checked: now written, as the result's source
        _write_problem(args, path, doc, flag)
    if wrong:
        flags = " ".join(f for f, _ in wrong)
        own = ", ".join(names[0] for names, _, _ in model.flags)
        raise ArgumentError(flags, f"{'applies' if len(wrong) == 1 else 'apply'} to "
                            f"{wrong[0][1]} problems only, and {shown(path, 200)} is a "
                            f"{model.name} problem: drop {flags} ({model.name} flags: {own})")
    options = model.solve_options(args, problem, path)
    out = prepare_out(args.out, problem.name, model.outputs)
    warning = None if model.warn is None else model.warn(problem)
    if warning:
        print(f"knit-nlp: {shown(path, 200)}: warning: {warning}", file=sys.stderr)
    check_overwrite(out.glob(f"{problem.name}.*.json"), path, args.force)
    result = model.solve(problem, **options)
    with np.errstate(invalid="ignore", over="ignore"):  # a diverged run: NaN figures (null)
        paths = result.save(out, **model.save_options(args))
        print(model.summary(result, paths))
    return 0 if result.success else 1


def _write_problem(args: argparse.Namespace, target: Path, doc: dict[str, Any], flag: str,
                   ) -> None:
    """Write a problem the flags rebuilt (``flag``, e.g. ``--size 30x30``; refused in one line
    over a file with other content unless --force), the source its result records."""
    from .atomic import write_text
    text = toml_text(doc)
    prepare_out(args.out, doc["name"], ())
    if target.exists() and (not target.is_file() or target.read_bytes() != text.encode()
                            and not args.force):
        raise ArgumentError(flag, f"{target} exists with other content: "
                            "remove it, choose another --out, or pass --force")
    write_text(target, text)
    print(f"wrote {target}: {doc['description']}")


def _cmd_compare(args: argparse.Namespace) -> int:
    path = resolve(args.problem)
    problem = load_problem(path)
    model = MODELS[problem.model]
    if model.compare is None:
        raise ProblemError(path, "", "model", f"compare is not offered for {model.name} "
                           f"problems; it is for {', '.join(m.name for m in MODELS.values() if m.compare)}")
    try:                                  # before --out is made: nothing written on refusal
        grids = model.compare_check(problem, args.grids)
    except ProblemError:
        raise
    except ValueError as err:
        raise ArgumentError(f"--grids {' '.join(map(str, args.grids))}", str(err)) from None
    out = prepare_out(args.out, problem.name, ("compare",))
    check_overwrite(out.glob(f"{problem.name}.*.json"), path, args.force)
    cmp = model.compare(problem, warm=args.warm, grids=grids)
    print(model.compare_summary(cmp, cmp.save(out)))
    return 0 if cmp.success else 1


def _cmd_sweep(args: argparse.Namespace) -> int:
    path = resolve(args.problem)
    doc = load_toml(path)
    problem = load_problem(path)
    name = sweep.study_name(args.name or f"sweep_{problem.name}")
    vary = [sweep.parse_axis("--vary", a) for a in args.vary]
    along = [sweep.parse_axis("--path", a) for a in args.path]
    paths = sweep.sweep_paths(doc, problem, vary, along)
    prepare_study(Path(args.out), name, ("sweep.csv", "sweep.png"))
    summary = run_with_options(name, paths, Path(args.out), args)
    keys = [a.key for a in (*vary, *along)]
    out = Path(args.out) / name
    rows = overview.table_rows(summary, keys)
    csv = overview.write_table(out / "sweep.csv", rows)
    unit = MODELS[problem.model].study.key_unit
    png = overview.plot_overview(out / "sweep.png", summary, keys,
                                 f"{problem.name}: {len(rows)} points", problem.units,
                                 {k: unit(problem, k) for k in keys})
    print_table([{**r, "point": f"{r['path']}.{r['index']}"} for r in rows],
                [("point", "point", ""), *((k, k, "") for k in keys),
                 ("energy_total", "U total", ".6g"), ("iterations", "it", ""),
                 ("success", "ok", "")])
    failed = sum(not r["success"] for r in rows)
    print(f"{len(rows) - failed} of {len(rows)} points converged; wrote {out / 'summary.json'}, "
          f"{csv}, {png}")
    return 0 if failed == 0 else 1


def main(argv: list[str] | None = None) -> int:
    try:
        args = _parser().parse_args(argv)
    except SystemExit as stop:              # --help (0) or a bad argument (2, one line)
        return int(stop.code or 0)
    try:
        return args.run(args)
    except ProblemError as err:
        print(f"knit-nlp: {err}", file=sys.stderr)
        return 2
    except BrokenPipeError:                     # output piped into e.g. `head`: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    raise SystemExit(main())
