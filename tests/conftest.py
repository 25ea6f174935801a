"""Shared helpers: write small problem files and solve them."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from knit_nlp.weft.problem import load_problem
from knit_nlp.weft.run import Solved, solve_problem

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS = ROOT / "problems"


@pytest.fixture
def write_problem(tmp_path: Path):
    """Write TOML text (dedented) to a file and return its path."""
    def write(text: str, name: str = "p.toml") -> Path:
        path = tmp_path / name
        path.write_text(textwrap.dedent(text))
        return path
    return write


def solve_text(path: Path, reduced: bool = False) -> Solved:
    return solve_problem(load_problem(path), reduced=reduced)
