"""Pulled edges (``[[pull]]``) of the jacquard model: closed forms, the two solvers against each
other, the reaction against the stored energy, the rope law, and the file checks."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from knit_nlp.errors import ProblemError
from knit_nlp.jacquard import load_problem, parse_problem, solve_explicit, solve_static
from knit_nlp.jacquard.springs import edge_particles
from knit_nlp.jacquard.summary import solve_summary
from knit_nlp.tomlio import load_toml

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"
STRETCH = PROBLEMS / "jacquard_diamond_stretch.toml"


def _with_pull(path: Path, displacement, edge: str = "top", **fabric):
    doc = load_toml(path)
    doc["fabric"].update({"boundary": "fixed", "fixed_edges": ["bottom", "top"], **fabric})
    doc["pull"] = [{"edge": edge, "displacement": list(displacement)}]
    return parse_problem(doc, path)


def _chain_reaction(p, displacement) -> np.ndarray:
    """All-net fabric, top pulled by (dx, dy): every wale is a straight chain of N-1 equal rope
    springs (pillar and both longitudinal springs, rest length rho h), so the grip's force is
    M k (l - rho h)+ along the chain, l = |(dx, (N-1) h + dy)| / (N-1)."""
    k = p.ground_stiffness + sum(s.stiffness["longitudinal"] for s in p.systems)
    chord = np.array([displacement[0], (p.courses - 1) * p.h + displacement[1]])
    length = np.hypot(*chord) / (p.courses - 1)
    return p.wales * k * max(length - p.ground_pretension * p.h, 0.0) * chord / np.hypot(*chord)


@pytest.mark.parametrize("solver", [solve_static, solve_explicit])
def test_sheared_chains_match_the_closed_form(solver):
    u = (0.4, 0.25)
    p = _with_pull(PROBLEMS / "jacquard_all_net.toml", u)
    r = solver(p)
    assert r.success
    reaction = r.pulls()[0]["reaction"]
    assert np.allclose(reaction, _chain_reaction(p, u), rtol=1e-6, atol=1e-8)
    # the top row really moved, the bottom row did not
    x = r.positions
    assert np.allclose(x[edge_particles(p, "top")] - r.network.natural[edge_particles(p, "top")], u)
    assert np.allclose(x[edge_particles(p, "bottom")], r.network.natural[edge_particles(p, "bottom")])


@pytest.mark.parametrize("dy", [-0.2, -0.5, -0.9, -1.0, 0.0, 0.3])
def test_rope_springs_pull_but_never_push(dy):
    """Tension only: pushing the top down past the chains' slack gives no force at all
    (a two-sided spring would push back), and the reaction is never compressive. At
    dy = -h the top row starts on the row below it: a zero-length spring, no NaN."""
    p = _with_pull(PROBLEMS / "jacquard_all_net.toml", (0.0, dy))
    r = solve_static(p)
    assert r.success
    reaction = r.pulls()[0]["reaction"]
    assert np.allclose(reaction, _chain_reaction(p, (0.0, dy)), atol=1e-6)
    assert reaction[1] >= -1e-9
    if dy <= -0.9:     # (N-1) h + dy < rho (N-1) h: every chain slack
        assert abs(reaction[1]) < 1e-6 and r.energy.total < 1e-10


def test_static_and_explicit_agree_on_the_stretched_diamond():
    p = load_problem(STRETCH)
    rs, re = solve_static(p), solve_explicit(p)
    assert rs.success and re.success
    assert rs.constraints["length_limits"] == 0      # nothing binds: one smooth equilibrium
    assert np.max(np.abs(rs.positions - re.positions)) < 1e-5 * p.w
    a, b = rs.pulls()[0]["reaction"], re.pulls()[0]["reaction"]
    assert np.allclose(a, b, rtol=1e-5, atol=1e-8)
    assert a[1] > 1.0          # it takes a real force to stretch it


def test_reaction_is_the_derivative_of_the_stored_energy():
    """Envelope theorem: dE*/du = reaction, by central differences in both directions."""
    u, step = np.array([0.1, 0.3]), 1e-4
    r = solve_static(_with_pull(STRETCH, u))
    assert r.success and r.constraints["length_limits"] == 0
    for axis in (0, 1):
        e = np.eye(2)[axis] * step
        hi, lo = (solve_static(_with_pull(STRETCH, u + s * e)) for s in (1, -1))
        slope = (hi.energy.total - lo.energy.total) / (2 * step)
        assert slope == pytest.approx(r.pulls()[0]["reaction"][axis], rel=1e-4, abs=1e-6)


def test_reaction_does_work_equal_to_the_stored_energy():
    """Quasi-static loading u = s u_end, s = 0..1: the trapezoid rule on reaction . du equals
    the stored energy gained (to the rule's O(ds^2) error)."""
    u_end = np.array([0.15, 0.3])
    s = np.linspace(0.0, 1.0, 9)
    runs = [solve_static(_with_pull(STRETCH, t * u_end)) for t in s]
    assert all(r.success for r in runs)
    power = np.array([r.pulls()[0]["reaction"] @ u_end for r in runs])
    work = float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(s)))
    stored = runs[-1].energy.total - runs[0].energy.total
    assert stored > 0.5
    assert work == pytest.approx(stored, rel=2e-3)


def test_a_left_edge_excludes_the_corners():
    p = _with_pull(PROBLEMS / "jacquard_all_net.toml", (0.1, 0.0), edge="left",
                   fixed_edges=["bottom", "top", "left"])
    idx = edge_particles(p, "left")
    assert idx.tolist() == [j * p.wales for j in range(1, p.courses - 1)]
    r = solve_static(p)
    assert r.success
    assert np.allclose(r.positions[0], r.network.natural[0])          # corner stays with bottom
    assert np.allclose(r.positions[idx, 0], r.network.natural[idx, 0] + 0.1)


BAD = [
    ({"boundary": "periodic"}, {"edge": "top", "displacement": [0, 1]}, "pull[1]", "edge",
     "boundary"),
    ({}, {"edge": "left", "displacement": [0, 1]}, "pull[1]", "edge", "not held"),
    ({}, {"edge": "middle", "displacement": [0, 1]}, "pull[1]", "edge", "one of"),
    ({}, {"edge": "top", "displacement": [1]}, "pull[1]", "displacement", "2 numbers"),
    ({}, {"edge": "top", "displacement": [0, "a"]}, "pull[1]", "displacement", "number"),
    ({}, {"edge": "top", "displacement": [0, 1], "force": 2}, "pull[1]", "force", "unknown"),
    ({}, {"displacement": [0, 1]}, "pull[1]", "edge", "missing"),
]


@pytest.mark.parametrize("fabric, pull, table, key, words", BAD)
def test_bad_pulls_are_one_line_errors(fabric, pull, table, key, words):
    doc = load_toml(STRETCH)
    doc["fabric"].update(fabric)
    if fabric.get("boundary") == "periodic":
        del doc["fabric"]["fixed_edges"]
    doc["pull"] = [pull]
    with pytest.raises(ProblemError) as err:
        parse_problem(doc, STRETCH)
    msg = str(err.value)
    assert "\n" not in msg and STRETCH.name in msg and f"[{table}] {key}:" in msg
    assert words in err.value.message


def test_an_edge_pulled_twice_is_an_error():
    doc = load_toml(STRETCH)
    doc["pull"] = doc["pull"] * 2
    with pytest.raises(ProblemError, match=r"pull\[2\].*pulled twice"):
        parse_problem(doc, STRETCH)


def test_json_and_summary_report_the_pull():
    """What ``knit-nlp solve`` writes and prints (the CLI run itself: test_jacquard_render's
    README letter K test)."""
    r = solve_static(load_problem(STRETCH))
    data = json.loads(json.dumps(r.to_json(), default=lambda a: a.tolist()))
    (pull,) = data["pulls"]
    assert pull["edge"] == "top" and pull["displacement"] == [0.0, 0.3]
    assert pull["reaction"] == pytest.approx(r.pulls()[0]["reaction"].tolist())
    assert "pull top by (0, 0.3) mm: reaction (0.1733, 3.581)" in solve_summary(r, [])
