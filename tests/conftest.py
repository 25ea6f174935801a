"""Shared helpers: write small problem files and solve them."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

from knit_nlp.weft.model.problem import load_problem
from knit_nlp.weft.api import solve as solve_problem
from knit_nlp.weft.model.parametrisation import Full, Reduced
from knit_nlp.weft.output.results import WeftResult

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


def solve_text(path: Path, reduced: bool = False) -> WeftResult:
    pr = load_problem(path)
    return solve_problem(pr, (pr.reduction or Reduced()) if reduced else Full())


def elastica_force(length: float, chord: float, R_f: float) -> float:
    """Pinned-pinned elastica, first mode: chord/ℓ = 2E(k)/K(k) − 1, P = 4K(k)² R_f / ℓ²."""
    m = brentq(lambda m: 2 * ellipe(m) / ellipk(m) - 1 - chord / length, 1e-12, 0.999)
    return 4 * ellipk(m) ** 2 * R_f / length ** 2


@pytest.fixture
def saved_figures(monkeypatch):
    """Record the axes transforms of every figure saved during the test (tests/imagecheck.py)."""
    from imagecheck import SavedFigures
    figs = SavedFigures()
    figs.install(monkeypatch)
    return figs


@pytest.fixture
def titles(monkeypatch):
    """Every Axes title set, with its colour (the pictures' titles state the answer's check)."""
    from matplotlib.axes import Axes
    seen: list[tuple[str, str]] = []
    real = Axes.set_title

    def set_title(self, label, *args, **kwargs):
        seen.append((label, kwargs.get("color", "black")))
        return real(self, label, *args, **kwargs)
    monkeypatch.setattr(Axes, "set_title", set_title)
    return seen
