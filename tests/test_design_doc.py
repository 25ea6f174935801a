"""docs/design.md describes the package that exists (issue 38, item 6): its "Layout" block names
every folder of ``knit_nlp`` and every module in it, names no folder that is gone, and its
"Import graph" block is the graph between subpackages that the import statements make.

Both are read from the real tree, so a new subpackage or module turns this red until the page
names it."""
from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path

from test_architecture import import_graph

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "knit_nlp"
DESIGN = ROOT / "docs" / "design.md"


def section_block(heading: str) -> str:
    """The first ``text`` block under the ``## heading`` of docs/design.md."""
    text = DESIGN.read_text()
    start = text.index(f"\n## {heading}\n")
    end = text.find("\n## ", start + 1)
    section = text[start:end if end >= 0 else None]
    return re.search(r"^```text\n(.*?)^```", section, re.S | re.M)[1]


def layout() -> dict[str, str]:
    """Folder path relative to ``knit_nlp`` ("" for the package itself) -> the text that names
    its modules: a folder is a line whose first word ends in "/", nested by its indentation
    (two spaces a level), and its modules are named between its line and the next folder's."""
    folders: dict[str, str] = {}
    stack: list[tuple[int, str]] = []
    current = None
    for line in section_block("Layout").splitlines():
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip())
        first, _, rest = line.strip().partition(" ")
        if first.endswith("/"):
            while stack and stack[-1][0] >= indent:
                stack.pop()
            stack.append((indent, first.rstrip("/")))
            current = "/".join(name for _, name in stack[1:])    # below knit_nlp/
            folders[current] = rest
        else:
            assert current is not None, f"a line before the first folder: {line!r}"
            folders[current] += " " + line.strip()
    return folders


def package_folders() -> dict[str, list[str]]:
    """Every folder of knit_nlp that holds Python modules (with or without ``__init__.py``:
    ``weft/model/contact`` has none) -> its modules' names."""
    found: dict[str, list[str]] = defaultdict(list)
    for path in sorted(PACKAGE.rglob("*.py")):
        folder = path.parent.relative_to(PACKAGE).as_posix()
        modules = found["" if folder == "." else folder]
        if path.stem != "__init__":
            modules.append(path.stem)
    return found


def test_the_layout_names_every_folder_and_module_of_the_package():
    named, unnamed = layout(), []
    for folder, modules in package_folders().items():
        if folder not in named:
            unnamed.append(f"no line for the folder knit_nlp/{folder}/")
            continue
        missing = [m for m in modules if not re.search(rf"\b{m}\b", named[folder])]
        if missing:
            unnamed.append(f"knit_nlp/{folder}/ does not name {missing}")
    assert not unnamed, "docs/design.md, Layout: " + "; ".join(unnamed)


def test_the_layout_names_no_folder_that_is_gone():
    gone = [f for f in layout() if not (PACKAGE / f).is_dir()]
    assert not gone, f"docs/design.md, Layout: folders that do not exist: {gone}"


STAGES = ("model", "transcription", "solving", "output", "inverse")


def group(module: str) -> str:
    """The group of docs/design.md's import graph that a module of knit_nlp belongs to."""
    parts = module.split(".")
    if len(parts) == 1:
        return "knit_nlp/__init__"
    if parts[1] in ("api", "cli", "jacquard", "studies"):
        return parts[1]
    if parts[1] == "weft":
        return f"weft.{parts[2]}" if len(parts) > 2 and parts[2] in STAGES else "weft"
    return "shared"


def test_the_import_graph_is_the_packages():
    drawn = {}
    for line in section_block("Import graph").splitlines():
        source, _, targets = line.partition(" -> ")
        drawn[source.strip()] = {t.strip() for t in targets.split(",")}
    real: dict[str, set[str]] = defaultdict(set)
    for module, targets in import_graph().items():
        for target in targets:
            if group(module) != group(target):
                real[group(module)].add(group(target))
    assert drawn == dict(real), "docs/design.md, Import graph: " + "; ".join(
        f"{a} -> {', '.join(sorted(real[a]))}" for a in sorted(real) if drawn.get(a) != real[a])
