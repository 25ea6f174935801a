"""Hand-made mutation testing: does the test suite notice small deliberate bugs?

Each mutant changes one place of one module (via ``ast``): an operator flip (``+``↔``-``,
``*``↔``/``, ``<``↔``<=``, ``>``↔``>=``, ``==``↔``!=``, ``and``↔``or``, ``+=``↔``-=``), a dropped
term (``a + b`` → ``a``, ``a - b`` → ``a``), a dropped unary minus (``-x`` → ``x``) or a changed
numeric constant (``c`` → ``c + 1`` for integers, ``2c`` (or 1 for 0) for floats). The mutant is
written into a temporary copy of the checkout and the test files that guard that module are
run against it (``pytest -x``, with a time limit); a mutant the tests pass is a *survivor*.

    python scripts/mutate.py                          # the three default modules
    python scripts/mutate.py knit_nlp/weft/output/results.py --tests tests/test_envelope.py
    python scripts/mutate.py --list                   # print the mutants, run nothing
    python scripts/mutate.py --lines 40-60 --json results/mutate.json
    python scripts/mutate.py knit_nlp/weft/transcription/full.py --only 12 40   # re-run two mutants
    python scripts/mutate.py knit_nlp/weft/model/contact/*.py --sample 6 --budget 600

``GUARDS`` names the test files of a module or of a pattern of modules (calibration, contact,
the checker, control); ``--sample K`` takes K mutants evenly spread over each module's list,
``--budget S`` starts no mutant after S seconds (the rest are reported as not run).

Docstrings, type annotations and the numbers in ``raise``/error messages are not mutated.
Mutants whose source is unchanged by ``ast.unparse`` (equivalent spellings) are skipped.
"""
from __future__ import annotations

import argparse
import ast
import copy
import fnmatch
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# The modules mutated when none is named.
DEFAULT = ["knit_nlp/weft/output/results.py", "knit_nlp/weft/transcription/full.py",
           "knit_nlp/jacquard/springs.py"]

# The test files that guard each module, or each module matching a pattern (run in this order;
# the fast, specific ones first; ``guards`` takes a module's own entry before a pattern's).
GUARDS = {
    "knit_nlp/weft/output/results.py": ["tests/test_envelope.py", "tests/test_weft_rigid.py",
                                 "tests/test_weft_equilibrium.py", "tests/test_cli.py",
                                 "tests/test_study.py"],
    "knit_nlp/weft/transcription/full.py": ["tests/test_envelope.py", "tests/test_elastica.py",
                             "tests/test_weft_equilibrium.py", "tests/test_weft_rigid.py",
                             "tests/test_weft_reduction.py", "tests/test_weft_geometry.py",
                             "tests/test_cli.py"],
    "knit_nlp/jacquard/springs.py": ["tests/test_explicit_order.py",
                                     "tests/test_jacquard_static.py",
                                     "tests/test_jacquard_physics.py",
                                     "tests/test_jacquard_pull.py",
                                     "tests/test_jacquard_cli.py",
                                     "tests/test_jacquard_images.py"],
    "knit_nlp/weft/output/check.py": ["tests/test_contact_check_input.py",
                                      "tests/test_contact_zones.py",
                                      "tests/test_contact_bounded.py",
                                      "tests/test_contact_told.py", "tests/test_contact_radii.py",
                                      "tests/test_inverse_told.py"],
    "knit_nlp/weft/inverse/control.py": ["tests/test_inverse_control.py",
                                         "tests/test_inverse_told.py",
                                         "tests/test_check_control.py",
                                         "tests/test_contact_control.py"],
    "knit_nlp/weft/model/contact/*.py": ["tests/test_contact_zones.py",
                                         "tests/test_contact_check_input.py",
                                         "tests/test_contact_bounded.py",
                                         "tests/test_contact_radii.py",
                                         "tests/test_contact_told.py", "tests/test_contact.py",
                                         "tests/test_check_cost.py"],
    "knit_nlp/weft/solving/rounds3d.py": ["tests/test_weft3d_windows.py",
                                          "tests/test_weft3d_flip.py"],
    "knit_nlp/weft/model/spatial/repulsion.py": ["tests/test_weft3d_windows.py",
                                                 "tests/test_weft3d_check_repulsion.py",
                                                 "tests/test_weft3d_flip.py"],
    "knit_nlp/weft/model/spatial/friction.py": ["tests/test_weft3d_friction.py",
                                                "tests/test_calibration_friction.py"],
    "knit_nlp/weft/solving/starts.py": ["tests/test_load_steps.py"],
    "scripts/periodic_cell.py": ["tests/test_periodic_cell.py"],
    "knit_nlp/weft/inverse/calibration/*.py": ["tests/test_calibration_input.py",
                                               "tests/test_calibration_checks.py",
                                               "tests/test_calibration_verdict.py",
                                               "tests/test_calibration_compression.py",
                                               "tests/test_calibration_model.py",
                                               "tests/test_calibration_friction.py",
                                               "tests/test_inverse_told.py"],
}


def guards(rel: str) -> list[str] | None:
    """The test files that guard a module: its own ``GUARDS`` entry, else the first pattern
    it matches (None: no entry; the whole suite is run)."""
    if rel in GUARDS:
        return GUARDS[rel]
    return next((tests for pattern, tests in GUARDS.items() if fnmatch.fnmatch(rel, pattern)),
                None)


def sample(todo: list, k: int | None) -> list:
    """``k`` of a module's mutants evenly spread over its list (first and last included), or
    all of them."""
    if k is None or len(todo) <= k:
        return todo
    if k <= 1:
        return todo[:k]
    return [todo[round(q * (len(todo) - 1) / (k - 1))] for q in range(k)]

BINOP_SWAP = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult,
              ast.FloorDiv: ast.Mult, ast.Pow: ast.Mult}
CMP_SWAP = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt,
            ast.Eq: ast.NotEq, ast.NotEq: ast.Eq, ast.Is: ast.IsNot, ast.IsNot: ast.Is,
            ast.In: ast.NotIn, ast.NotIn: ast.In}
SYMBOL = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.FloorDiv: "//",
          ast.Pow: "**", ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==",
          ast.NotEq: "!=", ast.Is: "is", ast.IsNot: "is not", ast.In: "in", ast.NotIn: "not in",
          ast.And: "and", ast.Or: "or"}


@dataclass
class Mutant:
    """One change: where, what, and (after running) what the tests said."""

    file: str
    index: int            # position among this file's mutation sites
    line: int
    description: str
    outcome: str = ""     # killed | survived | timeout | error
    seconds: float = 0.0
    failed_test: str = ""


def _skipped_nodes(tree: ast.AST) -> set[int]:
    """ids of nodes never mutated: docstrings, annotations, raise statements."""
    skip: set[int] = set()

    def mark(node: ast.AST | None) -> None:
        if node is not None:
            skip.update(id(n) for n in ast.walk(node))
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            mark(node.returns)
            for a in node.args.args + node.args.kwonlyargs + node.args.posonlyargs:
                mark(a.annotation)
        if isinstance(node, ast.AnnAssign):
            mark(node.annotation)
        if isinstance(node, ast.Raise):
            mark(node)
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef)) and node.body \
                and isinstance(node.body[0], ast.Expr) \
                and isinstance(node.body[0].value, ast.Constant):
            mark(node.body[0])
    return skip


def _sites(tree: ast.AST) -> list[tuple[ast.AST, str, str]]:
    """Every (node, kind, description) mutation site of a module, in a fixed order."""
    skip = _skipped_nodes(tree)
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.BinOp) and type(node.op) in BINOP_SWAP:
            op = type(node.op)
            out.append((node, "binop", f"{SYMBOL[op]} -> {SYMBOL[BINOP_SWAP[op]]}"))
            if op in (ast.Add, ast.Sub):
                out.append((node, "drop_right", f"a {SYMBOL[op]} b -> a"))
        elif isinstance(node, ast.AugAssign) and type(node.op) in (ast.Add, ast.Sub):
            op = type(node.op)
            out.append((node, "augassign", f"{SYMBOL[op]}= -> {SYMBOL[BINOP_SWAP[op]]}="))
        elif isinstance(node, ast.Compare):
            for k, op in enumerate(node.ops):
                if type(op) in CMP_SWAP:
                    out.append((node, f"cmp{k}", f"{SYMBOL[type(op)]} -> {SYMBOL[CMP_SWAP[type(op)]]}"))
        elif isinstance(node, ast.BoolOp):
            op = type(node.op)
            out.append((node, "boolop", f"{SYMBOL[op]} -> {'or' if op is ast.And else 'and'}"))
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            out.append((node, "drop_minus", "-x -> x"))
        elif isinstance(node, ast.Constant) and type(node.value) in (int, float):
            v = node.value
            new = v + 1 if isinstance(v, int) else (2 * v if v != 0 else 1.0)
            out.append((node, f"const:{new!r}", f"{v!r} -> {new!r}"))
    return out


def _apply(node: ast.AST, kind: str) -> ast.AST | None:
    """The replacement of ``node`` for a mutation kind (None: replace by nothing)."""
    new = copy.copy(node)
    if kind == "binop":
        new.op = BINOP_SWAP[type(node.op)]()
    elif kind == "drop_right":
        return node.left
    elif kind == "augassign":
        new.op = BINOP_SWAP[type(node.op)]()
    elif kind.startswith("cmp"):
        k = int(kind[3:])
        new.ops = list(node.ops)
        new.ops[k] = CMP_SWAP[type(node.ops[k])]()
    elif kind == "boolop":
        new.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
    elif kind == "drop_minus":
        return node.operand
    elif kind.startswith("const:"):
        new.value = ast.literal_eval(kind[6:])
    return new


class _Replace(ast.NodeTransformer):
    def __init__(self, target: ast.AST, replacement: ast.AST) -> None:
        self.target, self.replacement = target, replacement

    def visit(self, node: ast.AST) -> ast.AST:
        if node is self.target:
            return self.replacement
        return super().visit(node)


def mutants(rel: str) -> list[tuple[Mutant, str]]:
    """Every mutant of one module with its source text (unchanged spellings dropped)."""
    source = (ROOT / rel).read_text()
    base = ast.unparse(ast.parse(source))
    out = []
    for index in range(len(_sites(ast.parse(source)))):
        tree = ast.parse(source)                     # a fresh tree per mutant
        node, kind, desc = _sites(tree)[index]
        mutated = _Replace(node, _apply(node, kind)).visit(tree)
        text = ast.unparse(ast.fix_missing_locations(mutated))
        if text != base:
            out.append((Mutant(rel, index, node.lineno, desc), text))
    return sorted(out, key=lambda pair: (pair[0].line, pair[0].index))


def _copy_checkout(dest: Path) -> None:
    for name in ("knit_nlp", "tests", "problems", "scripts", "pyproject.toml"):
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, dest / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        elif src.exists():
            shutil.copy2(src, dest / name)


def run_tests(workdir: Path, tests: list[str], timeout: float) -> tuple[str, float, str]:
    """(outcome, seconds, first failing test) of ``pytest -x`` on ``tests`` in ``workdir``."""
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "MPLBACKEND": "Agg"}
    env.pop("PYTHONPATH", None)
    t0 = time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider",
                               *tests], cwd=workdir, env=env, capture_output=True, text=True,
                              timeout=timeout)
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - t0, ""
    seconds = time.perf_counter() - t0
    failed = next((ln.split()[1] for ln in proc.stdout.splitlines() if ln.startswith(("FAILED", "ERROR"))), "")
    if proc.returncode == 0:
        return "survived", seconds, ""
    if proc.returncode in (1,):
        return "killed", seconds, failed
    return "error", seconds, failed or proc.stdout[-200:]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", default=DEFAULT, help="modules, relative to the checkout")
    ap.add_argument("--tests", nargs="+", help="test files to run (default: GUARDS[module])")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per mutant")
    ap.add_argument("--lines", help="only mutants on lines A-B")
    ap.add_argument("--only", type=int, nargs="+", help="only the mutants with these #indices")
    ap.add_argument("--sample", type=int, help="only K mutants per module, evenly spread")
    ap.add_argument("--budget", type=float, help="start no mutant after this many seconds")
    ap.add_argument("--list", action="store_true", help="list the mutants and stop")
    ap.add_argument("--json", type=Path, help="write every mutant's outcome here")
    args = ap.parse_args(argv)
    lo, hi = (int(v) for v in args.lines.split("-")) if args.lines else (0, 10 ** 9)
    todo = [pair for rel in args.files for pair in sample(
        [(m, text) for m, text in mutants(rel) if lo <= m.line <= hi
         and (args.only is None or m.index in args.only)], args.sample)]
    if args.list:
        for m, _ in todo:
            print(f"{m.file}:{m.line}: #{m.index} {m.description}")
        print(f"{len(todo)} mutants")
        return 0
    done: list[Mutant] = []
    start, skipped = time.perf_counter(), 0
    with tempfile.TemporaryDirectory(prefix="knit_mutate_") as tmp:
        work = Path(tmp)
        _copy_checkout(work)
        for rel in args.files:
            tests = args.tests or guards(rel) or ["tests"]
            mine = [x for x in todo if x[0].file == rel]
            if args.budget is not None and time.perf_counter() - start > args.budget:
                skipped += len(mine)
                continue
            original = (work / rel).read_text()
            (work / rel).write_text(ast.unparse(ast.parse(original)))   # baseline: same spelling as mutants
            outcome, seconds, _ = run_tests(work, tests, args.timeout)
            print(f"baseline {rel}: {outcome} in {seconds:.1f} s ({' '.join(tests)})", flush=True)
            if outcome != "survived":
                print(f"  the unmutated tests do not pass; skipping {rel}", flush=True)
                (work / rel).write_text(original)
                continue
            for m, text in mine:
                if args.budget is not None and time.perf_counter() - start > args.budget:
                    skipped += 1
                    continue
                (work / rel).write_text(text)
                m.outcome, m.seconds, m.failed_test = run_tests(work, tests, args.timeout)
                (work / rel).write_text(original)
                done.append(m)
                print(f"{m.outcome:>8} {m.seconds:6.1f} s  {m.file}:{m.line} #{m.index} {m.description}"
                      f"  {m.failed_test}", flush=True)
    survivors = [m for m in done if m.outcome != "killed"]
    print(f"\n{len(done)} mutants: {len(done) - len(survivors)} killed, "
          f"{sum(m.outcome == 'survived' for m in done)} survived, "
          f"{sum(m.outcome == 'timeout' for m in done)} timed out, "
          f"{sum(m.outcome == 'error' for m in done)} errors"
          + (f"; {skipped} not run (--budget {args.budget:g} s)" if skipped else "")
          + f"; {time.perf_counter() - start:.0f} s")
    for m in survivors:
        print(f"  {m.outcome}: {m.file}:{m.line} #{m.index} {m.description}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps([asdict(m) for m in done], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
