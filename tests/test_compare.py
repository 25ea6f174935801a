"""``knit-nlp compare``: a verdict with named limits, the reduced grid, a warm start on request."""
import dataclasses
import json

import pytest

import knit_nlp
import knit_nlp.weft.api as weft_api
from knit_nlp.api import MODELS
from knit_nlp.cli import main
from hypothesis import given, settings, strategies as st

from knit_nlp.weft.api import check_grids
from knit_nlp.weft.output.comparison import (ENERGY_REL_OK, RMS_LOOPS_OK, Comparison,
                                            GridRow, verdict)

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
    assert knit_nlp.compare("wada_fig7") == "cmp" and seen == {"warm": False, "grids": ()}
    knit_nlp.compare("wada_fig7", warm=True, grids=[2, 3])
    assert seen == {"warm": True, "grids": [2, 3]}
    with pytest.raises(ValueError, match="warm must be True or False"):
        knit_nlp.weft.compare(knit_nlp.load_problem("wada_fig7"), warm="yes")


# --- compare --grids: the accuracy-against-time frontier (issue 22, item 2) ---------------------

def test_the_frontier_ends_at_the_full_model_and_starts_at_the_corner_form(write_problem,
                                                                          tmp_path, capsys):
    """On a 4 x 5 pull: the grid with every course and wale (k = 5) is the full model (distance
    1e-6 L, energy ratio 1, within the limits), and k = 2 is the corner form that ``compare``
    solves as its reduced model, solved again: the same distance and energy ratio (red when the
    row compares another solve than its grid's with the full model)."""
    r = _compare(write_problem, tmp_path, 4, 5, "--grids", "5", "2", "2")
    grids = r["frontier"]["grids"]
    assert [g["k"] for g in grids] == [2, 5]                   # sorted, each once
    corner, every = grids
    assert every["courses"] == [1, 2, 3, 4] and every["wales"] == [1, 2, 3, 4, 5]
    assert every["distance_rms"] < 1e-6 * r["loop_length"]
    assert abs(every["energy_ratio"] - 1) < 1e-8 and every["ok"] is True
    assert corner["courses"] == [1, 4] and corner["wales"] == [1, 5]
    assert abs(corner["distance_rms"] - r["distance"]["rms"]) < 1e-6 * r["loop_length"]
    assert abs(corner["energy_ratio"] - r["energy_ratio"]) < 1e-8
    assert corner["ok"] is False
    assert r["frontier"]["fastest_ok"] == 5
    printed = capsys.readouterr().out
    assert "even grids against the full model" in printed
    assert "fastest grid within the limits: 5 x 5" in printed


def _row(k: int, speedup: float, ok: bool | None) -> GridRow:
    return GridRow(k, [], [], 10 * k, ok is not None, 1.0 / speedup, speedup, 0.0, 0.0, 1.0, ok)


def test_fastest_ok_is_the_fastest_row_within_the_limits():
    rows = [_row(2, 6.0, False), _row(4, 3.0, True), _row(6, 2.0, True), _row(8, 9.0, None)]
    assert Comparison(None, None, frontier=rows).fastest_ok.k == 4
    assert Comparison(None, None, frontier=rows[:1]).fastest_ok is None


def test_bad_grids_are_refused_in_one_line_before_anything_is_written(write_problem, tmp_path,
                                                                       capsys):
    path = write_problem(PULL.format(m=4, n=5), "g45.toml")
    for k, bad in enumerate((["--grids", "1"], ["--grids", "6"], ["--grids=-3"],
                             ["--grids", "2", "9"])):
        out = tmp_path / f"o{k}"
        assert main(["compare", str(path), "--out", str(out), *bad]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "--grids" in err and "from 2" in err
        assert not out.exists()


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(st.integers(-3, 9), st.floats(allow_nan=True), st.booleans(),
                          st.text(max_size=2)), max_size=4))
def test_check_grids_accepts_exactly_whole_numbers_from_2_to_the_larger_side(grids):
    problem = knit_nlp.load_problem("wada_fig7")                  # 5 x 5
    good = all(isinstance(k, int) and not isinstance(k, bool) and 2 <= k <= 5 for k in grids)
    if good:
        assert check_grids(grids, problem) == sorted(set(grids))
    else:
        with pytest.raises(ValueError, match="grid"):
            check_grids(grids, problem)


def test_compare_with_a_yarn_radius_is_refused_before_any_solve(write_problem, tmp_path,
                                                                  monkeypatch, capsys):
    """The reduced model has no contact: compare says so at once instead of after the full
    contact solve (red when the refusal comes from the reduced solve)."""
    solves = []
    real = weft_api.solve
    monkeypatch.setattr(weft_api, "solve", lambda *a, **k: solves.append(a) or real(*a, **k))
    path = write_problem(PULL.format(m=2, n=3) + "[yarn]\nradius = 0.1\n", "yarn.toml")
    out = tmp_path / "o"
    assert main(["compare", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "[yarn] radius" in err and "compare" in err
    assert solves == [] and not out.exists()
