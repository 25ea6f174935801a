"""``knit-nlp compare``: a verdict with named limits, the reduced grid, a warm start on request."""
import dataclasses
import json

import pytest

import knit_nlp
import knit_nlp.weft.api as weft_api
from knit_nlp.api import MODELS
from knit_nlp.cli import main
from knit_nlp.weft.output.comparison import ENERGY_REL_OK, RMS_LOOPS_OK, verdict

PULL = """
[fabric]
courses = {m}
wales = {n}
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [1, {n}]
point = "H"
displacement = [2.0, 3.0]
"""


@pytest.mark.parametrize("loops, ratio, ok", [
    (0.99 * RMS_LOOPS_OK, 1 + 0.99 * ENERGY_REL_OK, True),
    (0.99 * RMS_LOOPS_OK, 1 - 0.99 * ENERGY_REL_OK, True),
    (1.01 * RMS_LOOPS_OK, 1.0, False),
    (0.0, 1 + 1.01 * ENERGY_REL_OK, False),
    (0.0, 1 - 1.01 * ENERGY_REL_OK, False),
    (2.9, 1.8, False),
])
def test_verdict_flips_at_each_limit(loops, ratio, ok):
    good, line = verdict(loops * 8.0, 8.0, ratio, "mm")
    assert good is ok
    assert line.startswith("verdict: ")
    assert ("use the full model" in line) is (not ok)
    if not ok:
        assert f"{loops * 8.0:.3g} mm RMS" in line


def _compare(write_problem, tmp_path, m, n, *flags):
    path = write_problem(PULL.format(m=m, n=n), f"c{m}{n}.toml")
    out = tmp_path / f"out{m}{n}{len(flags)}"
    assert main(["compare", str(path), "--out", str(out), *flags]) == 0
    return json.loads((out / f"c{m}{n}.compare.json").read_text())


def test_reduced_grid_of_every_loop_is_fine(write_problem, tmp_path, capsys):
    """2 x 2 loops: the corners are every loop, so the reduced model is the full one."""
    r = _compare(write_problem, tmp_path, 2, 2)
    printed = capsys.readouterr().out
    assert r["verdict"]["reduced_ok"] is True
    assert "verdict: the reduced model is within" in printed
    assert r["verdict"]["text"] in printed
    assert r["representatives"] == {"courses": [1, 2], "wales": [1, 2]}
    assert "reduced grid: courses [1, 2], wales [1, 2] of 2 courses x 2 wales" in printed


def test_corner_grid_of_a_pulled_fabric_says_use_the_full_model(write_problem, tmp_path, capsys):
    """4 x 5 loops from their corners: 1.76x the full model's energy."""
    r = _compare(write_problem, tmp_path, 4, 5)
    printed = capsys.readouterr().out
    assert r["verdict"]["reduced_ok"] is False
    assert r["energy_ratio"] > 1 + ENERGY_REL_OK
    assert "verdict: use the full model" in printed
    assert r["representatives"] == {"courses": [1, 4], "wales": [1, 5]}
    assert r["verdict"]["limits"] == {"rms_loop_lengths": RMS_LOOPS_OK,
                                      "energy_relative": ENERGY_REL_OK}


def test_warm_start_is_solved_only_with_the_flag(write_problem, tmp_path, monkeypatch):
    """Two solves by default ("warm": null), three with --warm (the last started from the
    reduced answer)."""
    solves = []
    real = weft_api.solve
    monkeypatch.setattr(weft_api, "solve", lambda *a, **k: solves.append(k) or real(*a, **k))
    r = _compare(write_problem, tmp_path, 2, 3)
    assert len(solves) == 2 and r["warm"] is None
    assert set(r["models"]) == {"full", "reduced"}
    solves.clear()
    r = _compare(write_problem, tmp_path, 2, 3, "--warm")
    assert len(solves) == 3 and solves[-1].get("start") is not None
    assert set(r["models"]) == {"full", "reduced", "full_warm_from_reduced"}
    assert abs(r["warm"]["energy_minus_full"]) < 1e-6


def test_python_compare_takes_warm(monkeypatch):
    """knit_nlp.compare passes warm (default False) to the model's compare; a non-bool is
    refused."""
    seen = {}
    monkeypatch.setitem(MODELS, "weft", dataclasses.replace(
        MODELS["weft"], compare=lambda problem, **options: seen.update(options) or "cmp"))
    assert knit_nlp.compare("wada_fig7") == "cmp" and seen == {"warm": False}
    knit_nlp.compare("wada_fig7", warm=True)
    assert seen == {"warm": True}
    with pytest.raises(ValueError, match="warm must be True or False"):
        knit_nlp.weft.compare(knit_nlp.load_problem("wada_fig7"), warm="yes")
