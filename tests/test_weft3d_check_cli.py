"""``knit-nlp check`` on a 3-D result (docs/weft3d.md, "Check"): the independent check over all
pairs of yarn pieces, rebuilt from the result JSON; exit 0 clean, 1 not clean (as the planar
check), and the same numbers as the result's own ``check`` block."""
from __future__ import annotations

import json

import numpy as np
import pytest

import knit_nlp
from knit_nlp.cli import main
from knit_nlp.tomlio import toml_text
from knit_nlp.weft.model.problem import parse_problem
from problem_texts import pull3d

DOC = pull3d("thin3d", L=10.0, R_f=1.0, radius=0.15, lift=0.3)


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    out = tmp_path_factory.mktemp("check3d")
    source = out / "thin3d.toml"
    source.write_text(toml_text(DOC))
    result = knit_nlp.solve(parse_problem(DOC, source))
    path = out / "thin3d.full3d.json"
    path.write_text(json.dumps(result.to_json()))
    return result, source, path


def test_check_of_a_3d_result_is_clean_and_agrees_with_its_own(solved, tmp_path, capsys) -> None:
    result, source, path = solved
    assert result.success
    assert main(["check", str(path), "--problem", str(source), "--out", str(tmp_path)]) == 0
    line = capsys.readouterr().out
    assert line.startswith("thin3d: clean: all pairs of yarn pieces in 3-D")
    told = json.loads(next(tmp_path.rglob("thin3d.full3d.check.json")).read_text())
    own = result.to_json()["check"]
    assert own["ok"] is True and told["ok"] is True
    # the JSON chains loops by their computed ends, the solve's own check reads its loop starts,
    # which meet those ends to the solve's constraint tolerance
    slack = 10 * result.to_json()["max_constraint_violation"] + 1e-12
    assert told["smallest_distance"] == pytest.approx(own["smallest_distance"], abs=slack)
    assert told["flipped"] == own["flipped"] == 0


def test_check_of_a_mirrored_3d_result_exits_1(solved, tmp_path, capsys) -> None:
    """The result's elevations and course heights negated (the fabric's face and back swapped:
    every designed crossing in the reverse order): exit 1, the flipped crossings counted."""
    _, source, path = solved
    doc = json.loads(path.read_text())
    loops = doc["loops"]
    loops["elevations"] = (-np.array(loops["elevations"])).tolist()
    loops["course_starts_z"] = (-np.array(loops["course_starts_z"])).tolist()
    bad = tmp_path / "mirrored.json"
    bad.write_text(json.dumps(doc))
    assert main(["check", str(bad), "--problem", str(source), "--out", str(tmp_path)]) == 1
    line = capsys.readouterr().out
    assert "NOT CLEAN" in line and "8 of 8 designed crossings flipped" in line
