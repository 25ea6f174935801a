"""Grips as users name them (issue 11): course/wale/edge shorthands, the head landmark,
direction + distance pulls and loads, [units], and the messages for bad grips."""
import json

import numpy as np
import pytest

from knit_nlp.cli import main
from knit_nlp.weft.api import solve
from knit_nlp.weft.model.problem import load_problem

FABRIC = "[fabric]\ncourses = 3\nwales = 4\n"
SHORT = FABRIC + """
[[clamp]]
edge = "top"
point = "head"
displacement = [0.0, 0.0]
[[clamp]]
loop = [1, 4]
point = "end"
direction = -45.0
distance = 2.0
"""
# the same grips written out by hand: s = L/2 = 5 for the head, the pull as a vector
LONG = FABRIC + "".join(f'[[clamp]]\nloop = [3, {j}]\npoint = 5.0\ndisplacement = [0.0, 0.0]\n'
                        for j in range(1, 5)) + f"""
[[clamp]]
loop = [1, 4]
point = "end"
displacement = [{float(2 / np.sqrt(2))!r}, {float(-2 / np.sqrt(2))!r}]
"""


def test_edge_shorthand_and_direction_equal_the_clamps_written_out(write_problem):
    short, long = load_problem(write_problem(SHORT, "s.toml")), load_problem(write_problem(LONG, "l.toml"))
    assert len(short.clamps) == len(long.clamps) == 5
    for a, b in zip(short.clamps, long.clamps):
        assert a.loop == b.loop and a.s == pytest.approx(b.s, abs=1e-12)
        np.testing.assert_allclose(a.target, b.target, atol=1e-12)
    rs, rl = solve(short), solve(long)
    assert rs.success and rl.success
    assert rs.energy.total == pytest.approx(rl.energy.total, rel=1e-9)
    np.testing.assert_allclose(rs.centrelines(), rl.centrelines(), atol=1e-7)
    # one entry per material point; the shorthand's entries name their table
    doc = rs.to_json()
    assert [c.get("group") for c in doc["clamps"]] == ["clamp[1]"] * 4 + [None]
    # equilibrium: the top grip's total reaction balances the pull
    top = sum(np.array(c["reaction"]) for c in doc["clamps"][:4])
    np.testing.assert_allclose(top, -np.array(doc["clamps"][4]["reaction"]), atol=1e-6)


def test_head_is_the_top_of_the_natural_loop(write_problem):
    pr = load_problem(write_problem(SHORT))
    s = np.linspace(0.0, pr.L, 2001)
    y = pr.natural.xy(s)[:, 1]
    assert s[np.argmax(y)] == pytest.approx(pr.clamps[0].s, abs=pr.L / 1000)
    assert pr.clamps[0].point == "head"


@pytest.mark.parametrize("edge,loops,point", [
    ("bottom", [(1, j) for j in range(1, 5)], None), ("top", [(3, j) for j in range(1, 5)], None),
    ("left", [(i, 1) for i in range(1, 4)], "start"), ("right", [(i, 4) for i in range(1, 4)], "end")])
def test_edges_name_the_outer_courses_and_wales(write_problem, edge, loops, point):
    given = "" if point else 'point = "B"\n'
    pr = load_problem(write_problem(FABRIC + f'[[clamp]]\nedge = "{edge}"\n{given}'
                                    'displacement = [0.0, 0.0]\n'))
    assert [c.loop for c in pr.clamps] == loops
    assert {c.point for c in pr.clamps} == {point or "B"}
    by_course = load_problem(write_problem(FABRIC + '[[clamp]]\ncourse = 2\npoint = "B"\n'
                                           'displacement = [0.0, 0.0]\n', "c.toml"))
    assert [c.loop for c in by_course.clamps] == [(2, j) for j in range(1, 5)]


def test_direction_degrees_vector_and_loads(write_problem):
    def clamp(direction: str) -> np.ndarray:
        pr = load_problem(write_problem(FABRIC + f'[[clamp]]\nloop = [1, 1]\npoint = "start"\n'
                                        f'direction = {direction}\ndistance = 3.0\n'))
        return pr.clamps[0].target - pr.natural_position((1, 1), 0.0)
    np.testing.assert_allclose(clamp("90.0"), [0.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(clamp("150"), 3 * np.array([-np.sqrt(3) / 2, 0.5]), atol=1e-12)
    np.testing.assert_allclose(clamp("[3.0, -4.0]"), [1.8, -2.4], atol=1e-12)
    held = '[[clamp]]\nedge = "top"\npoint = "head"\ndisplacement = [0, 0]\n'  # to pull against
    pr = load_problem(write_problem(FABRIC + held + '[[load]]\nedge = "bottom"\npoint = "head"\n'
                                    'direction = [0, -1]\nmagnitude = 0.2\n'))
    assert len(pr.loads) == 4
    for ld in pr.loads:
        np.testing.assert_allclose(ld.force, [0.0, -0.2], atol=1e-15)


def test_rigid_shorthand_equals_the_listed_points(write_problem):
    listed = ", ".join(f'{{loop = [1, {j}], point = "head"}}' for j in range(1, 5))
    a = load_problem(write_problem(FABRIC + f"[[rigid_clamp]]\npoints = [{listed}]\n"
                                   "translation = [0.0, -1.0]\n", "a.toml")).rigid_clamps[0]
    b = load_problem(write_problem(FABRIC + '[[rigid_clamp]]\nedge = "bottom"\npoint = "head"\n'
                                   "direction = -90\ndistance = 1.0\n", "b.toml")).rigid_clamps[0]
    assert a.points == b.points
    np.testing.assert_allclose(a.centre, b.centre)
    np.testing.assert_allclose(a.translation, b.translation, atol=1e-15)


CLAMP = '[[clamp]]\nloop = [1, 1]\npoint = "start"\n'
BAD = {
    "direction without distance": (CLAMP + "direction = 30.0\n", "[clamp[1]] distance"),
    "distance without direction": (CLAMP + "distance = 1.0\n", "[clamp[1]] direction"),
    "zero direction vector": (CLAMP + "direction = [0, 0]\ndistance = 1.0\n", "[clamp[1]] direction"),
    "negative distance": (CLAMP + "direction = 0\ndistance = -1.0\n", "[clamp[1]] distance"),
    "direction and displacement": (CLAMP + "direction = 0\ndistance = 1.0\ndisplacement = [1, 0]\n",
                                   "[clamp[1]] displacement"),
    "loop and course": (CLAMP.replace("loop = [1, 1]", "loop = [1, 1]\ncourse = 1")
                        + "displacement = [0, 0]\n", "[clamp[1]] course"),
    "course outside": ('[[clamp]]\ncourse = 4\npoint = "head"\ndisplacement = [0, 0]\n',
                       "[clamp[1]] course"),
    "wale outside": ('[[clamp]]\nwale = 0\npoint = "head"\ndisplacement = [0, 0]\n',
                     "[clamp[1]] wale"),
    "unknown edge": ('[[clamp]]\nedge = "middle"\npoint = "head"\ndisplacement = [0, 0]\n',
                     "[clamp[1]] edge"),
    "top edge needs a point": ('[[clamp]]\nedge = "top"\ndisplacement = [0, 0]\n', "[clamp[1]] point"),
    "one position for a course": ('[[clamp]]\ncourse = 1\npoint = "head"\nposition = [0, 0]\n',
                                  "[clamp[1]] position"),
    "edge over a held corner": (CLAMP + 'displacement = [0, 0]\n[[clamp]]\nedge = "left"\n'
                                'displacement = [0, 0]\n', "[clamp[2]] fix"),
    "rigid with points and course": ('[[rigid_clamp]]\ncourse = 1\npoint = "head"\n'
                                     'points = [{loop = [1, 1], point = "start"}]\n',
                                     "[rigid_clamp[1]] course"),
    "rigid with loop": ('[[rigid_clamp]]\nloop = [1, 1]\npoint = "head"\n', "[rigid_clamp[1]] loop"),
    "load force and direction": ('[[load]]\nloop = [1, 1]\npoint = "head"\nforce = [0, 1]\n'
                                 'direction = 0\nmagnitude = 1\n', "[load[1]] force"),
    "load magnitude alone": ('[[load]]\nloop = [1, 1]\npoint = "head"\nmagnitude = 1\n',
                             "[load[1]] direction"),
    "empty unit": ('[units]\nlength = ""\n', "[units] length"),
    "unit not a string": ("[units]\nforce = 1\n", "[units] force"),
    "unknown unit key": ('[units]\ntime = "s"\n', "[units] time"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_grips_are_one_line_exit_2(case, write_problem, tmp_path, capsys):
    text, expected = BAD[case]
    path = write_problem(FABRIC + text, "bad.toml")
    assert main(["solve", str(path), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and str(path) in err and expected in err, err
    assert not list(tmp_path.glob("*.json"))


def test_units_reach_json_summary_and_axes(write_problem, tmp_path, capsys):
    path = write_problem('[units]\nlength = "mm"\nforce = "N"\n' + SHORT, "u.toml")
    assert main(["solve", str(path), "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    doc = json.loads((tmp_path / "u.full.json").read_text())
    assert doc["units"] == {"length": "mm", "force": "N", "energy": "N·mm"}
    energy_line = next(l for l in out.splitlines() if l.strip().startswith("energy"))
    assert energy_line.endswith("[N·mm]")
    assert all(l.endswith("[N]") for l in out.splitlines() if "reaction" in l)
    default = json.loads(json.dumps(load_problem(write_problem(SHORT)).units.to_json()))
    assert default == {"length": "units", "force": "force units", "energy": "energy units"}
