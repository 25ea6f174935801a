"""Finding problem files: a path, or a name of a file in the named-problem folder.

The named problems are the checkout's top-level ``problems/`` folder; an installed package
(``pip install .``) carries a copy as the package data ``knit_nlp.problem_data`` (mapped from
``problems/`` in pyproject.toml), found with :mod:`importlib.resources`.
"""
from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

from .errors import ProblemError
from .tomlio import load_toml

DATA_FOLDER = "problem_data"


def packaged_problems(package: str = "knit_nlp") -> Path | None:
    """The named problems shipped as package data (``<package>/problem_data``, a folder of
    data files, no Python), if this is an installed package; None otherwise."""
    folder = resources.files(package).joinpath(DATA_FOLDER)
    return Path(str(folder)) if folder.is_dir() else None


def problems_dir() -> Path:
    """The named-problem folder: ``$KNIT_NLP_PROBLEMS``, else ``problems/`` of the checkout the
    package runs from (tests, an editable install), else the installed package data, else
    ``problems/`` in the working directory."""
    env = os.environ.get("KNIT_NLP_PROBLEMS")
    if env:
        return Path(env)
    beside = Path(__file__).resolve().parent.parent / "problems"
    if beside.is_dir():
        return beside
    return packaged_problems() or Path.cwd() / "problems"


def resolve(name_or_path: str) -> Path:
    """A problem file path from a path or a bare name (``diagonal_pull`` -> problems/diagonal_pull.toml)."""
    path = Path(name_or_path)
    try:
        if path.exists():
            return path
        named = problems_dir() / f"{name_or_path}.toml"      # also folder/name ('knit-nlp list')
        if path.suffix != ".toml" and not path.is_absolute() and named.is_file():
            return named
        if path.suffix == ".toml" or os.sep in name_or_path:
            return path
    except (OSError, ValueError):        # a NUL or an over-long name
        pass
    raise ProblemError(name_or_path, "", "", f"no such problem file or named problem "
                       f"(named problems live in {problems_dir()}; see 'knit-nlp list')")


def named_problems(folders: bool = False) -> list[tuple[str, str, str]]:
    """(name, model, description) of every problem in the named-problem folder; with
    ``folders``, also of those one folder down (named ``folder/stem``, which :func:`resolve`
    accepts; a calibration spec's model is ``calibrate``, the command that reads it) and one
    row per folder, model ``folder``, naming its other files."""
    top = problems_dir()
    rows = [_row(path.stem, path) for path in sorted(top.glob("*.toml"))]
    if folders:
        for folder in sorted(p for p in top.iterdir() if p.is_dir() and p.name[0] not in "._"):
            files = sorted(folder.glob("*.toml"))
            other = sorted(p.name for p in folder.iterdir() if p.suffix != ".toml" and p.is_file())
            rows.append((f"{folder.name}/", "folder", f"{len(files)} problem file{'s' * (len(files) != 1)}; also "
                         + (", ".join(other) or "nothing else")))
            rows += [_row(f"{folder.name}/{path.stem}", path) for path in files]
    return rows


def _row(name: str, path: Path) -> tuple[str, str, str]:
    try:
        doc = load_toml(path)
    except ProblemError as err:
        return name, "?", f"unreadable: {err.message}"
    model = "calibrate" if "calibrate" in doc else str(doc.get("model", "weft"))
    return name, model, str(doc.get("description", ""))
