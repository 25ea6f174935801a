"""The shared load cases (knit_nlp.weft.model.cases) are the shipped problems' cases: one definition of
each pull, checked against the files (which round the targets)."""
from __future__ import annotations

import numpy as np
import pytest

from knit_nlp.tomlio import load_toml
from knit_nlp.weft.model.cases import EQ28_TARGET, course_pull, diagonal_pull, eq28_map
from knit_nlp.weft.model.problem import load_problem

from conftest import PROBLEMS


def test_diagonal_pull_at_5x5_is_eq28_itself():
    target = diagonal_pull(5)["clamp"][1]["position"]
    np.testing.assert_allclose(target, EQ28_TARGET, atol=1e-12)
    stretch, turn = eq28_map()
    assert stretch == pytest.approx(1.883076, abs=1e-6)
    assert np.degrees(turn) == pytest.approx(25.2573, abs=1e-4)


def test_shipped_diagonal_pull_is_the_case_at_10x10():
    pr = load_problem(PROBLEMS / "diagonal_pull.toml")
    case = diagonal_pull(10)
    assert (pr.courses, pr.wales) == (10, 10)
    np.testing.assert_allclose(pr.clamps[1].target, case["clamp"][1]["position"], atol=0.05)
    assert pr.clamps[1].point == case["clamp"][1]["point"] == "H"


def test_shipped_wada_fig7_is_the_case_at_5x5():
    doc = load_toml(PROBLEMS / "wada_fig7.toml")
    assert doc["clamp"][1]["position"] == pytest.approx(diagonal_pull(5)["clamp"][1]["position"])


def test_shipped_course_stretch_is_the_course_case():
    pr = load_problem(PROBLEMS / "course_stretch.toml")
    case = course_pull(8, m=6)
    assert len(pr.clamps) == len(case["clamp"])
    for clamp, c in zip(sorted(pr.clamps, key=lambda c: (c.loop, c.s)),
                        sorted(case["clamp"], key=lambda c: (tuple(c["loop"]), c["point"] == "end"))):
        assert list(clamp.loop) == c["loop"]
        nat = pr.natural_position(clamp.loop, clamp.s)
        np.testing.assert_allclose(clamp.target - nat, c["displacement"], atol=1e-4)
        assert [d for d, f in zip("xy", clamp.fix) if f] == c["fix"]
