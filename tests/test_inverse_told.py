"""fit, control and calibrate carry the answer's own check too (issue 41, item 1): the JSON's
``check`` block, a ``check`` line in the summary and the picture's title say what ``knit-nlp
check`` says of their equilibria (``WeftResult.checked``); a converged control still exits 0,
calibrate's exit follows its targets."""
from __future__ import annotations

import importlib
import json

import numpy as np
import pytest

from calibration_files import SYNTH_TRUTH, synthetic_columns, synthetic_spec
from knit_nlp.cli import main
from knit_nlp.weft.inverse.fit import Fitter
from knit_nlp.weft.inverse.observations import Observation
from knit_nlp.weft.model.problem import load_problem
from knit_nlp.weft.model.centrelines import centrelines, natural_centrelines
from knit_nlp.weft.output.check import own_check
from knit_nlp.weft.inverse.spec import load_control
from knit_nlp.weft.output.check import check
from problem_texts import bend
from test_inverse_control import FABRIC

# the module (the package exports its function of the same name)
curve_module = importlib.import_module("knit_nlp.weft.inverse.calibration.curve")   # the check's caller

BEND = bend()


def test_a_converged_control_whose_fabric_crosses_itself_says_so_and_exits_0(
        write_problem, tmp_path, capsys, titles):
    """The 4 x 4 fabric's corner dragged until B of loop (3, 2) sits at (18, 2): the control
    converges, stable, and the paper's model lets yarns pass through each other. The JSON's
    ``check`` block, the summary and the title say what ``check`` finds in the written file."""
    path = write_problem(FABRIC.format(bounds="", gx=18.0, gy=2.0), "drag.toml")
    assert main(["control", str(path), "--out", str(tmp_path)]) == 0
    r = json.loads((tmp_path / "drag.control.json").read_text())
    again = check(r, load_control(path).problem)      # the equilibrium's loops, checked anew
    block = r["check"]
    assert again.n_new > 0 and block["ok"] is False
    assert block["new_crossings"] == again.n_new and block == r["equilibrium"]["check"]
    assert block["verdict"].startswith(f"{again.n_new} new crossings between "
                                       f"{len(again.new_crossings)} pairs of loops")
    assert f"\n  check: {block['verdict']}\n" in capsys.readouterr().out
    title, colour = titles[-1]
    assert title.startswith("drag: Converged") and colour == "tab:red"
    assert " ".join(title.split("\n")[1:]) == f"check: {block['verdict']}"


def test_a_fit_checks_each_case_at_the_fitted_values_as_a_solve_there_does(
        write_problem, tmp_path, capsys, titles):
    """One course bent by an end moment, R_f fitted to noise-free points of R_f = 1: the fit's
    ``check`` of the case is the ``check`` block of a forward solve of the case at the fitted
    R_f, and the summary and the case's panel say it."""
    path = write_problem(BEND.format(R_f=0.6), "bend.toml")
    where = [(j, s) for j in (1, 2, 3) for s in (2.5, 5.0, 7.5)]
    fitter = Fitter([load_problem(path)], [Observation("bend", (1, j), s, s, np.zeros(2))
                                           for j, s in where], ["R_f"])
    assert fitter.solve_cases(np.array([1.0]))
    rows = [f"bend,1,{j},{s},{x:.12f},{y:.12f}\n"
            for (j, s), (x, y) in zip(where, fitter.positions(fitter.cases[0]))]
    csv = tmp_path / "obs.csv"
    csv.write_text("case,course,wale,point,x,y\n" + "".join(rows))
    assert main(["fit", str(path), "--observations", str(csv), "--params", "R_f",
                 "--out", str(tmp_path / "fit")]) == 0
    r = json.loads((tmp_path / "fit" / "bend.fit.json").read_text())
    block = r["check"]["bend"]
    assert block["ok"] is False and block["new_crossings"] > 0      # the course crosses itself
    assert f"\n  check of bend: {block['verdict']}\n" in capsys.readouterr().out
    fitted = r["parameters"]["R_f"]["value"]
    assert fitted == pytest.approx(1.0, rel=1e-6)
    again = write_problem(BEND.format(R_f=repr(fitted)), "again.toml")
    assert main(["solve", str(again), "--out", str(tmp_path / "again")]) == 0
    assert block == json.loads((tmp_path / "again" / "bend.full.json").read_text())["check"]
    panel = next(t for t, _ in titles if t.startswith("load case bend"))
    assert " ".join(panel.split("\n")[1:]) == f"check: {block['verdict']}"


def _stretch(problem, coeffs, starts) -> float:
    """How much longer along x the fabric's centrelines (eq. 1) are than its natural ones."""
    span = np.ptp(centrelines(coeffs, starts, problem.L, problem.t, 41)[0][..., 0])
    return float(span - np.ptp(natural_centrelines(problem, 41)[..., 0]))


def test_calibrate_checks_each_test_at_its_largest_load(tmp_path, capsys, titles, monkeypatch):
    """The synthetic 2 x 3 course pull at its true values (nothing fitted): each test's answer
    at the model curve's last node (the largest force in ``curves.csv``) is checked; the JSON,
    the summary and the test's panel say it, and the exit still follows the target. The loops
    checked are stretched along x by that node's travel (axial strain x gauge) over the
    natural fabric's extent."""
    seen = []

    def spy(problem, coeffs, starts):
        seen.append(_stretch(problem, coeffs, starts))
        return own_check(problem, coeffs, starts)
    monkeypatch.setattr(curve_module, "own_check", spy)
    width = synthetic_columns(tmp_path / "synthetic.csv", rows=400)
    spec = synthetic_spec(tmp_path, width, "[]", SYNTH_TRUTH, tables="",
                          extra="[calibrate.targets]\nfit_axial = 0.003\n")
    assert main(["calibrate", str(spec), "--out", str(tmp_path / "out")]) == 0
    doc = json.loads((tmp_path / "out" / "synthetic.calibration.json").read_text())
    block = doc["tests"][0]["check"]
    assert block["ok"] in (True, False) and block["verdict"]
    last = (tmp_path / "out" / "synthetic.curves.csv").read_text().splitlines()[-1].split(",")
    assert block["at"]["force_N"] == pytest.approx(float(last[2]), rel=1e-8)
    assert block["at"]["axial_strain"] == pytest.approx(float(last[3]), rel=1e-8)
    line = (f"check at {float(last[2]):.4g} N (axial strain {float(last[3]):.3g}, the curve's "
            f"largest load): {block['verdict']}")
    assert f"\n    {line}\n" in capsys.readouterr().out
    assert any(t.endswith("\n" + line) for t, _ in titles)
    travel = block["at"]["axial_strain"] * doc["tests"][0]["specimen"]["gauge"]
    assert seen == [pytest.approx(travel, rel=1e-6)], (seen, travel)


def test_calibrate_finds_the_first_node_the_check_calls_not_clean(tmp_path, capsys, titles,
                                                                  monkeypatch):
    """Where the answer at the curve's largest load is not clean, the nodes are checked from the
    unloaded one on and the first that is not clean is named (JSON ``first_not_clean``, the
    summary's and the panel's check line): here a check that calls a node clean while its
    loops are stretched by less than half the last node's travel, so the first node not clean
    is the first whose stretch (recomputed from its loops) passes that."""
    seen = []

    def judge(problem, coeffs, starts):
        stretch = _stretch(problem, coeffs, starts)
        seen.append(stretch)
        block = own_check(problem, coeffs, starts)[1]
        ok = stretch < limit[0] and not (only_last[0] and len(seen) == 1)
        return None, {**block, "ok": ok, "verdict": f"{'clean' if ok else 'NOT CLEAN'} (test)"}
    limit, only_last = [np.inf], [False]
    monkeypatch.setattr(curve_module, "own_check", judge)
    width = synthetic_columns(tmp_path / "synthetic.csv", rows=400)
    spec = synthetic_spec(tmp_path, width, "[]", SYNTH_TRUTH, tables="")
    assert main(["calibrate", str(spec), "--out", str(tmp_path / "first")]) in (0, 1)
    doc = json.loads((tmp_path / "first" / "synthetic.calibration.json").read_text())
    gauge = doc["tests"][0]["specimen"]["gauge"]
    last_travel = doc["tests"][0]["check"]["at"]["axial_strain"] * gauge
    assert doc["tests"][0]["check"]["ok"] and "first_not_clean" not in doc["tests"][0]["check"]
    assert len(seen) == 1                       # a clean last node: only it is checked
    capsys.readouterr()
    seen.clear()
    limit[0] = 0.5 * last_travel
    assert main(["calibrate", str(spec), "--out", str(tmp_path / "again")]) in (0, 1)
    doc = json.loads((tmp_path / "again" / "synthetic.calibration.json").read_text())
    first = doc["tests"][0]["check"]["first_not_clean"]
    stretches = seen[1:]                        # seen[0]: the last node, checked first
    k = next(i for i, s in enumerate(stretches) if s >= limit[0])
    assert first["node"] == k and len(stretches) == k + 1
    assert all(s < limit[0] for s in stretches[:k])
    assert first["axial_strain"] * gauge == pytest.approx(stretches[k], rel=1e-6)
    assert first["verdict"] == "NOT CLEAN (test)"
    words = (f"the first node not clean: {first['force_N']:.4g} N (axial strain "
             f"{first['axial_strain']:.3g}), the nodes before it clean")
    assert words in capsys.readouterr().out
    assert any(words in " ".join(t.split("\n")) for t, _ in titles)
    # only the last node not clean: it is the first not clean, every node before it checked
    seen.clear()
    limit[0], only_last[0] = np.inf, True
    assert main(["calibrate", str(spec), "--out", str(tmp_path / "last")]) in (0, 1)
    first = json.loads((tmp_path / "last" / "synthetic.calibration.json").read_text()
                       )["tests"][0]["check"]["first_not_clean"]
    assert first["node"] == len(seen) - 1 and first["verdict"] == "NOT CLEAN (test)"
    assert first["axial_strain"] * gauge == pytest.approx(last_travel, rel=1e-6)
