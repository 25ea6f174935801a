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
        if path.suffix == ".toml" or path.exists() or os.sep in name_or_path:
            return path
        named = problems_dir() / f"{name_or_path}.toml"
        if named.exists():
            return named
    except (OSError, ValueError):        # a NUL or an over-long name
        pass
    raise ProblemError(name_or_path, "", "", f"no such problem file or named problem "
                       f"(named problems live in {problems_dir()}; see 'knit-nlp list')")


def named_problems() -> list[tuple[str, str, str]]:
    """(name, model, description) of every problem in the named-problem folder."""
    rows = []
    for path in sorted(problems_dir().glob("*.toml")):
        try:
            doc = load_toml(path)
        except ProblemError as err:
            rows.append((path.stem, "?", f"unreadable: {err.message}"))
            continue
        rows.append((path.stem, str(doc.get("model", "weft")), str(doc.get("description", ""))))
    return rows
