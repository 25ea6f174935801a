"""Grips no configuration satisfies are refused before any solve (one line, exit 2): targets of
one course farther apart than the inextensible yarn between them, and a net load along a
coordinate nothing holds."""
from __future__ import annotations

import time

import numpy as np
import pytest

from knit_nlp.cli import main
from knit_nlp.errors import ProblemError
from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.model.problem import load_problem

ONE_COURSE = """
[fabric]
courses = {m}
wales = 3
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [{far}, 3]
point = "end"
position = [{x}, {y}]
"""


def _length(write_problem) -> float:
    return load_problem(write_problem(ONE_COURSE.format(m=1, far=1, x=5.0, y=0.0))).L


@pytest.mark.parametrize("factor, refused", [(0.999, False), (1.001, True)])
def test_the_reach_of_one_course_is_its_yarn_length(write_problem, factor, refused):
    """Start of loop (1, 1) to end of loop (1, 3) is 3L of yarn: a target pair 0.1 % short of
    3L apart is accepted, 0.1 % beyond is refused, whatever the direction."""
    L = _length(write_problem)
    d = 3 * L * factor / np.sqrt(2)
    path = write_problem(ONE_COURSE.format(m=1, far=1, x=d, y=-d))
    if refused:
        with pytest.raises(ProblemError, match=r"\[clamp\[2\]\] position: is out of reach: .* "
                           r"course 1 with 30 .* move the targets closer"):
            load_problem(path)
    else:
        assert load_problem(path).clamps[1].target[0] == pytest.approx(d)


def test_points_of_different_courses_are_joined_by_springs_and_never_refused(write_problem):
    """Between courses only the interlocking springs act, which stretch without bound."""
    pr = load_problem(write_problem(ONE_COURSE.format(m=2, far=2, x=500.0, y=500.0)))
    assert len(pr.clamps) == 2


def test_an_impossible_edge_pull_is_refused_in_well_under_a_second(write_problem, capsys):
    """The issue's case: a 3000 pull on a 30 wide fabric ran silently until killed."""
    path = write_problem("""
        [fabric]
        courses = 3
        wales = 3
        [[clamp]]
        edge = "left"
        point = "start"
        displacement = [0.0, 0.0]
        [[clamp]]
        edge = "right"
        point = "end"
        displacement = [3000.0, 0.0]
        """)
    t0 = time.perf_counter()
    assert main(["solve", str(path), "--out", str(path.parent / "o")]) == 2
    assert time.perf_counter() - t0 < 0.5
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "[clamp[2]] displacement: is out of reach" in err[0]
    assert not (path.parent / "o").exists()


def test_a_rigid_clamp_translated_out_of_reach_is_refused(write_problem):
    path = write_problem("""
        [fabric]
        courses = 2
        wales = 3
        [[rigid_clamp]]
        edge = "left"
        point = "start"
        [[rigid_clamp]]
        edge = "right"
        point = "end"
        translation = [0.0, 400.0]
        """)
    with pytest.raises(ProblemError, match=r"\[rigid_clamp\[2\]\] translation: is out of reach"):
        load_problem(path)


def test_a_sweep_value_out_of_reach_is_refused_before_solving(write_problem, capsys):
    path = write_problem(ONE_COURSE.format(m=2, far=1, x=20.0, y=0.0))
    code = main(["sweep", str(path), "--path", "clamp[2].position.x=20:100:3", "--workers", "1",
                 "--out", str(path.parent / "o")])
    assert code == 2
    assert "is out of reach" in capsys.readouterr().err
    assert not (path.parent / "o").exists()
    with pytest.raises(ValueError, match="clamp\\[2\\] position is out of reach"):
        WeftParams.of(load_problem(path)).with_(targets={2: [100.0, 0.0]})


LOAD = """
[fabric]
courses = 2
wales = 2
{clamp}
[[load]]
loop = [2, 2]
point = "end"
force = [{fx}, {fy}]
{other}
"""
HOLD_Y = '[[clamp]]\nloop = [1, 1]\npoint = "start"\nfix = ["y"]\nposition = [0.0, 0.0]'
OPPOSITE = '[[load]]\nloop = [1, 1]\npoint = "start"\nforce = [-1.0, 0.0]'


@pytest.mark.parametrize("clamp, fx, fy, other, refused", [
    ("", 1.0, 0.0, "", "net x force is 1"),
    (HOLD_Y, 1.0, 0.0, "", "nothing holds the fabric in x"),
    (HOLD_Y, 0.0, 1.0, "", None),
    ("", 1.0, 0.0, OPPOSITE, None),
])
def test_a_load_with_nothing_to_push_against_is_refused(write_problem, clamp, fx, fy, other,
                                                        refused):
    path = write_problem(LOAD.format(clamp=clamp, fx=fx, fy=fy, other=other))
    if refused:
        with pytest.raises(ProblemError, match=rf"\[load\[1\]\] force: has no equilibrium: .*"
                           rf"{refused}"):
            load_problem(path)
    else:
        assert load_problem(path).loads


def test_fit_with_a_load_case_that_nothing_holds_is_refused_at_once(write_problem, capsys):
    """The issue's case: fit ran 491 s, then crashed drawing fit.png."""
    case = write_problem(LOAD.format(clamp="", fx=1.0, fy=0.0, other="").replace(
        "[fabric]", 'name = "free"\n[fabric]'), "free.toml")
    obs = case.parent / "obs.csv"
    obs.write_text("case,course,wale,point,x,y\nfree,2,2,H,1.0,1.0\n")
    t0 = time.perf_counter()
    assert main(["fit", str(case), "--observations", str(obs), "--params", "k_b",
                 "--out", str(case.parent / "o")]) == 2
    assert time.perf_counter() - t0 < 1.0
    err = capsys.readouterr().err.strip()
    assert "free.toml: [load[1]] force: has no equilibrium" in err and len(err.splitlines()) == 1
    assert not (case.parent / "o").exists()
