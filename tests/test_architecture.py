"""The package's shape: no import cycles, model-specific choices only in the model table, no
trace of the lifted reduced model, no docstring that points outside the repository."""
from __future__ import annotations

import ast
import re
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "knit_nlp"


def module_name(path: Path, root: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(root: Path = ROOT, package: str = "knit_nlp") -> dict[str, set[str]]:
    """module -> the package modules it imports: every import statement anywhere in the file
    (module level, inside functions, under ``if TYPE_CHECKING``), relative ones resolved;
    ``from pkg import name`` counts as importing ``pkg.name`` when that is a module."""
    files = {module_name(p, root): p for p in (root / package).rglob("*.py")}
    graph: dict[str, set[str]] = defaultdict(set)
    for mod, path in files.items():
        base = mod.split(".") if path.name == "__init__.py" else mod.split(".")[:-1]
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    up = base[:len(base) - (node.level - 1)]
                    name = ".".join(up + ([node.module] if node.module else []))
                else:
                    name = node.module or ""
                targets = [f"{name}.{a.name}" if f"{name}.{a.name}" in files else name
                           for a in node.names]
            else:
                continue
            for target in targets:
                while target not in files and "." in target:
                    target = target.rsplit(".", 1)[0]
                if target in files and target != mod:
                    graph[mod].add(target)
    for mod in files:
        graph.setdefault(mod, set())
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                found.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_package_imports_form_no_cycle():
    graph = import_graph()
    assert len(graph) > 60                                  # every module was read
    assert "knit_nlp.weft.solving.solve" in graph["knit_nlp.weft.study"]
    assert cycles(graph) == []


def test_a_cycle_is_found_wherever_its_import_hides(tmp_path):
    """The walk sees imports inside functions and under TYPE_CHECKING, relative and absolute:
    a copy of the package with one such import added has a cycle."""
    import shutil
    shutil.copytree(PACKAGE, tmp_path / "knit_nlp",
                    ignore=shutil.ignore_patterns("__pycache__"))
    assert cycles(import_graph(tmp_path)) == []
    basis = tmp_path / "knit_nlp" / "weft" / "model" / "basis.py"
    for added in ("\ndef _late():\n    from ..api import solve  # noqa\n",
                  "\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                  "    from knit_nlp.weft.study import WeftStudy  # noqa\n"):
        original = basis.read_text()
        basis.write_text(original + added)
        found = cycles(import_graph(tmp_path))
        assert any("knit_nlp.weft.model.basis" in c for c in found), added
        basis.write_text(original)


def test_the_front_door_imports_weft_solve_at_module_top():
    tree = ast.parse((PACKAGE / "api.py").read_text())
    top = [n for n in tree.body if isinstance(n, ast.ImportFrom)]
    assert any(n.module == "weft.api" and any(a.name == "solve" for a in n.names) for n in top)


MODEL_NAME_TEST = re.compile(r"""==\s*["'](weft|jacquard)["']|["'](weft|jacquard)["']\s*(==|!=|in\b)""")


@pytest.mark.parametrize("path", sorted([PACKAGE / "cli.py", *(PACKAGE / "studies").glob("*.py")]),
                         ids=lambda p: p.name)
def test_only_the_model_table_tells_models_apart(path):
    """cli.py and studies/ read model entries (knit_nlp.api.MODELS); they never compare a
    model's name."""
    text = path.read_text()
    assert not MODEL_NAME_TEST.search(text)
    assert '"weft"' not in text and '"jacquard"' not in text


def test_no_lifted_reduced_model_remains():
    for path in PACKAGE.rglob("*.py"):
        text = path.read_text()
        for name in ("coeff_map", "reduction_map", "continuity=", "NLPSizes"):
            assert name not in text, (path, name)


def test_docstrings_cite_no_readme_heading_and_no_file_outside_the_repository():
    for path in PACKAGE.rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"README|\.\./shared|\bspec/", text), path
        for cited in re.findall(r"\b(docs/[\w./-]+\.md)", text):
            assert (ROOT / cited).is_file(), (path, cited)


PIPELINE = ("model", "transcription", "solving", "output", "inverse")


def test_weft_subpackages_import_only_earlier_stages_of_the_pipeline():
    """model -> transcription -> solving -> output -> inverse: a stage imports itself and the
    stages before it (and the shared modules), never a later stage or the weft front doors."""
    for mod, targets in import_graph().items():
        parts = mod.split(".")
        if len(parts) < 3 or parts[1] != "weft" or parts[2] not in PIPELINE:
            continue
        for target in targets:
            tp = target.split(".")
            if tp[1] in ("api", "cli", "studies", "jacquard"):
                raise AssertionError(f"{mod} imports the front door or another model: {target}")
            if tp[1] == "weft":
                assert len(tp) > 2 and tp[2] in PIPELINE, (mod, target)
                assert PIPELINE.index(tp[2]) <= PIPELINE.index(parts[2]), (mod, target)


def constructing_modules(names: tuple[str, ...], root: Path = PACKAGE) -> set[str]:
    """The package modules with a call of any of ``names`` (a class built there)."""
    found = set()
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Call):
                f = node.func
                name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(
                    f, ast.Attribute) else None
                if name in names:
                    found.add(module_name(path, root.parent))
    return found


def test_one_forward_equilibrium_builds_the_solvers():
    """The IPOPT instances and the contact solver of a weft problem are built in two modules
    only (the solver's own, with the equilibrium of a fixed transcription, and the contact
    equilibrium's), so a new model variant joins one equilibrium (``solving.variants``), not
    several stacks (issue 38: six modules built them)."""
    assert constructing_modules(("WeftSolver", "ContactSolver")) == {
        "knit_nlp.weft.solving.solve", "knit_nlp.weft.solving.contact.equilibrium"}


def private_imports(root: Path = PACKAGE) -> list[tuple[str, str]]:
    """(module, name) for every ``from <package module> import _name``: a private name used
    outside its module."""
    found = []
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.ImportFrom) and (node.level or (node.module or "").startswith(
                    root.name)):
                found += [(module_name(path, root.parent), a.name) for a in node.names
                          if a.name.startswith("_") and not a.name.startswith("__")]
    return found


def test_no_private_name_is_imported_from_another_module(tmp_path):
    """A name another module needs is public (issue 38: seven private names crossed modules,
    a public parser among them); the walk sees such an import wherever it is."""
    assert private_imports() == []
    bad = tmp_path / "knit_nlp"
    bad.mkdir()
    (bad / "a.py").write_text("def _helper():\n    pass\n")
    (bad / "b.py").write_text("def f():\n    from .a import _helper  # noqa\n")
    assert private_imports(bad) == [("knit_nlp.b", "_helper")]


# third-party objects read where their library has no public accessor (matplotlib's side titles
# and suptitle, a process pool's size, the interpreter's immediate exit in a watchdog)
THIRD_PARTY_PRIVATE = {("knit_nlp.figures", "ax._left_title"), ("knit_nlp.figures", "ax._right_title"),
                       ("knit_nlp.figures", "fig._suptitle"),
                       ("knit_nlp.studies.executors", "executor._max_workers"),
                       ("knit_nlp.studies.points", "os._exit")}


def private_reads(root: Path = PACKAGE) -> set[tuple[str, str]]:
    """(module, expression) for every ``obj._name`` whose ``obj`` is not ``self`` or ``cls``:
    a private attribute read (or written) from outside its object."""
    found = set()
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if (isinstance(node, ast.Attribute) and node.attr.startswith("_")
                    and not node.attr.startswith("__")
                    and not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls"))):
                found.add((module_name(path, root.parent), ast.unparse(node)))
    return found


def test_no_module_reads_another_objects_private_attribute(tmp_path):
    """An object another needs to read offers it publicly (issue 38: the condensed lifting read
    ``model._cache``); only third-party objects without a public accessor are read privately.
    The walk sees a read through any name and any chain (``self.model._cache`` too)."""
    assert private_reads() == THIRD_PARTY_PRIVATE
    bad = tmp_path / "knit_nlp"
    bad.mkdir()
    (bad / "a.py").write_text("def f(model, self):\n    return model._cache, self.other._x, "
                              "self._mine\n")
    assert private_reads(bad) == {("knit_nlp.a", "model._cache"), ("knit_nlp.a", "self.other._x")}


def test_few_file_names_are_reused_inside_weft():
    """At most three file names of ``weft/`` name two modules (issue 38: six did, e.g. two
    ``crossings.py`` for the crossing springs' points and for yarns crossing in contact)."""
    names: dict[str, list[Path]] = defaultdict(list)
    for path in (PACKAGE / "weft").rglob("*.py"):
        if path.name != "__init__.py":
            names[path.name].append(path)
    reused = sorted(name for name, paths in names.items() if len(paths) > 1)
    assert len(reused) <= 3, reused
