"""Studies: one build, many solves; resumable, cached runs."""
import json

import numpy as np
import pytest

from knit_nlp.studies import LoadPath, run_study
from knit_nlp.weft.model.cases import course_pull
from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.study import WeftStudy
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.api import solve as solve_problem

from conftest import elastica_force


def _doc(dx=0.0, k_b=0.01):
    return {"fabric": {"courses": 3, "wales": 4}, "material": {"k_b": k_b},
            "clamp": [{"loop": [1, 1], "point": "start", "position": [0.0, 0.0]},
                      {"loop": [1, 4], "point": "H", "displacement": [dx, 0.5 * dx]}]}


def test_one_build_many_solves_matches_fresh_solves():
    study = WeftStudy(parse_problem(_doc(), "<s>"))
    built, x = study.nlp, None
    for dx, k_b in ((0.5, 0.01), (1.0, 0.01), (1.5, 0.05)):
        p = study.params.with_(displacements={2: [dx, 0.5 * dx]}, material={"k_b": k_b})
        rep = study.solve(p, x0=x)
        x = rep.x
        fresh = solve_problem(parse_problem(_doc(dx, k_b), "<f>"))
        assert rep.success and fresh.success
        res = study.result(rep, p)
        assert res.energy.total == pytest.approx(fresh.energy.total, rel=1e-8)
        np.testing.assert_allclose(res.clamps[1].reaction, fresh.clamps[1].reaction,
                                   atol=1e-8)
        np.testing.assert_allclose(res.clamps[1].position, fresh.clamps[1].target,
                                   atol=1e-8)
    assert study.nlp is built                  # one build for every solve


def _paths():
    return [LoadPath("soft", _doc(), [{"displacements": {"2": [d, 0.5 * d]}} for d in (0.4, 0.8, 1.2)]),
            LoadPath("stiff", _doc(k_b=0.1),
                     [{"displacements": {"2": [d, 0.5 * d]}} for d in (0.4, 0.8, 1.2)])]


def test_resumed_study_gives_the_same_summary(tmp_path, capsys):
    whole = run_study("s", _paths(), tmp_path / "a", workers=1)
    assert whole["complete"] and len(whole["points"]) == 6
    partial = run_study("s", _paths(), tmp_path / "b", workers=1, limit=1)
    assert not partial["complete"] and not (tmp_path / "b" / "s" / "summary.json").exists()
    resumed = run_study("s", _paths(), tmp_path / "b", workers=2)
    assert resumed["complete"]
    a = json.loads((tmp_path / "a" / "s" / "summary.json").read_text())
    b = json.loads((tmp_path / "b" / "s" / "summary.json").read_text())
    assert a == b
    # monotone loading: reaction grows with displacement along each path
    for name in ("soft", "stiff"):
        f = [np.linalg.norm(r["clamps"][1]["reaction"]) for r in a["points"] if r["path"] == name]
        assert f[0] < f[1] < f[2]
    assert "6/6 points" in capsys.readouterr().err


def test_changed_settings_are_not_served_from_the_cache(tmp_path):
    first = run_study("s", _paths(), tmp_path, workers=1)
    moved = [LoadPath("soft", _doc(), [{"displacements": {"2": [d, 0.5 * d]}} for d in (0.5, 0.9, 1.3)])]
    second = run_study("s", moved, tmp_path, workers=1)
    e1 = [r["energy"]["total"] for r in first["points"] if r["path"] == "soft"]
    e2 = [r["energy"]["total"] for r in second["points"]]
    assert all(b > a for a, b in zip(e1, e2))


def test_study_of_a_straight_yarn_buckles_from_a_natural_problem():
    """The problem file holds the rod at its natural length; the study compresses it. The
    degenerate straight start must be detected from the parameters solved, not the file's."""
    doc = {"fabric": {"courses": 1, "wales": 1}, "loop": {"preset": "straight", "length": 40.0,
                                                          "harmonics": 6},
           "clamp": [{"loop": [1, 1], "point": "start", "position": [0.0, 0.0]},
                     {"loop": [1, 1], "point": "end", "position": [40.0, 0.0]}]}
    study = WeftStudy(parse_problem(doc, "<rod>"))
    p = study.params.with_(targets={2: [36.0, 0.0]})
    rep = study.solve(p)
    assert rep.success and any(a.startswith("perturbed") for a in rep.attempts)
    force = study.result(rep, p).clamps[1].reaction[0]
    assert -force == pytest.approx(elastica_force(40.0, 36.0, 1.0), rel=2e-3)



def test_a_study_of_a_reduced_problem_solves_what_solve_solves(tmp_path):
    """Issue 18: studies built the old lifted reduced model (no clamp-rank extension, no
    representatives) while solve() used the condensed one. A study point (run_study, through
    the worker's WeftStudy) and solve() of the same reduced problem: same energy, same
    representatives (here extended: the course pull's clamps are dependent over the corners),
    same parameter count, on both points of a warm-started path."""
    doc = course_pull(6)
    doc["reduction"] = {"representative_courses": [1, 6], "representative_wales": [1, 6]}
    path = LoadPath("red", doc, [{"material": {"k_b": kb}} for kb in (0.01, 0.05)])
    summary = run_study("r", [path], tmp_path, workers=1)
    cached = sorted((tmp_path / "r" / "points").glob("*.json"))
    problem = parse_problem(doc, "<r>")
    for kb, row, js in zip((0.01, 0.05), summary["points"], cached):
        alone = solve_problem(problem, params=WeftParams.of(problem).with_(material={"k_b": kb}))
        point = json.loads(js.read_text())
        assert alone.success and row["success"] and alone.model == point["model"] == "reduced"
        assert row["energy"]["total"] == pytest.approx(alone.energy.total, rel=1e-8)
        assert point["representatives"] == alone.representatives()
        assert "asked" in point["representatives"]
        assert point["n_parameters"] == alone.nlp.n_parameters
    assert WeftStudy(problem).nlp.representatives() == alone.representatives()
