"""Smoke and physics tests of the study scripts (scripts/force_displacement.py,
scripts/stiffness_sweep.py, scripts/reproduce_wada_fig7.py): tiny runs through main(argv)."""
from __future__ import annotations

import csv
import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from imagecheck import check_line_plot

SCRIPTS = Path(__file__).resolve().parent.parent / "scripts"


def _script(name: str):
    spec = importlib.util.spec_from_file_location(f"_script_{name}", SCRIPTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_force_displacement_reaction_grows_and_does_the_work(tmp_path, saved_figures):
    """Every pull: the reaction along the pull is positive and grows with the displacement, and
    its work (trapezoid rule from the natural state) matches the stored energy."""
    fd = _script("force_displacement")
    tables = fd.main(["--size", "3", "--steps", "4", "--max-strain", "0.2", "--workers", "1",
                      "--out", str(tmp_path)])
    out = tmp_path / "force_displacement"
    assert json.loads((out / "summary.json").read_text())["complete"]
    colours = {"course": "#1f77b4", "wale": "#ff7f0e", "diagonal": "#2ca02c"}   # tab: colours
    reactions, energies = {}, {}
    for name in ("course", "wale", "diagonal"):
        rows = list(csv.DictReader((out / f"{name}.csv").open()))
        assert len(rows) == 4 and all(r["success"] == "True" for r in rows)
        d = np.array([0.0] + [float(r["displacement"]) for r in rows])
        f = np.array([0.0] + [float(r["reaction"]) for r in rows])
        u = np.array([0.0] + [float(r["energy_total"]) for r in rows])
        assert np.all(np.diff(f) > 0) and np.all(np.diff(u) > 0), name
        work = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(d))])
        np.testing.assert_allclose(work[1:], u[1:], rtol=0.1, err_msg=name)
        assert [r["reaction"] for r in tables[name]] == pytest.approx(f[1:].tolist())
        b = np.array([0.0] + [float(r["energy_bending"]) for r in rows])
        reactions[colours[name]] = [np.column_stack([d, f])]
        energies[colours[name]] = [np.column_stack([d, u]), np.column_stack([d, b])]
    # the picture plots the CSVs: reaction (left) and total and bending energy (right)
    check_line_plot(out / "force_displacement.png", saved_figures, 0, reactions)
    check_line_plot(out / "force_displacement.png", saved_figures, 1, energies)
    # a rerun with other steps in the same folder must not reuse the cached points of this one;
    # equilibrium does not depend on the path taken to it
    again = fd.main(["--size", "3", "--steps", "2", "--max-strain", "0.2", "--workers", "1",
                     "--out", str(tmp_path)])
    for name in ("course", "wale", "diagonal"):
        assert again[name][0]["strain"] == pytest.approx(tables[name][1]["strain"])
        assert again[name][0]["reaction"] == pytest.approx(tables[name][1]["reaction"], rel=1e-5)


def test_stiffness_sweep_stiffer_yarn_stores_more_energy(tmp_path):
    """At the same pull, raising k_b/k_a or R_f raises the energy and the pulling reaction."""
    sweep = _script("stiffness_sweep")
    rows = sweep.main(["--size", "3", "--kb", "0.01", "1", "--rf", "0.5", "2", "--workers", "1",
                       "--out", str(tmp_path)])
    out = tmp_path / "stiffness_sweep"
    assert (out / "stiffness_sweep.png").stat().st_size > 10_000
    assert len(list(csv.DictReader((out / "stiffness_sweep.csv").open()))) == 4
    assert all(r["success"] for r in rows)
    u = {(r["k_b_over_k_a"], r["R_f"]): r["energy_total"] for r in rows}
    f = {(r["k_b_over_k_a"], r["R_f"]): r["reaction_norm"] for r in rows}
    for rf in (0.5, 2.0):
        assert u[(1.0, rf)] > u[(0.01, rf)] and f[(1.0, rf)] > f[(0.01, rf)]
    for kb in (0.01, 1.0):
        assert u[(kb, 2.0)] > u[(kb, 0.5)] and f[(kb, 2.0)] > f[(kb, 0.5)]


def test_line_clamps_change_the_fig7_solution(tmp_path):
    """Line clamps add constraints to eq. 28, so they cannot lower the energy and they move the
    loops; one-point jaws are the point clamps again."""
    fig7 = _script("reproduce_wada_fig7")
    comp = fig7.main(["--grip", "2", "--out", str(tmp_path)])
    assert comp["point_clamps"]["success"] and comp["line_clamps"]["success"]
    assert comp["line_clamps"]["energy"]["total"] > comp["point_clamps"]["energy"]["total"] + 0.1
    assert comp["centreline_distance"]["max"] > 1.0
    assert (tmp_path / "wada_fig7" / "wada_fig7.png").stat().st_size > 10_000
    same = fig7.main(["--grip", "1", "--out", str(tmp_path)])
    assert same["centreline_distance"]["max"] < 1e-5
    assert same["line_clamps"]["energy"]["total"] == pytest.approx(
        same["point_clamps"]["energy"]["total"], rel=1e-7)


def test_papers_condensed_form_reaches_the_shipped_reduced_minimum():
    """bench_reduction_bound's condensed form (z and course starts only, loop starts chained,
    CasADi's AD) and the shipped reduced model (hand-assembled derivatives, shooting segments)
    are independent transcriptions of one model: same energy at the solution, and the paper's
    form has the paper's parameter count."""
    bound = _script("bench_reduction_bound")
    pr = bound.parse_problem(bound.diagonal_pull(4), "d.toml")
    run_shipped, _ = bound.shipped(pr, True)
    run_condensed, n_condensed = bound.condensed(pr, "exact")
    _, _, _, e_shipped, status_shipped = run_shipped()
    _, _, _, e_condensed, status_condensed = run_condensed()
    assert status_shipped == status_condensed == "Solve_Succeeded"
    assert abs(e_condensed - e_shipped) < 1e-7 * abs(e_shipped)
    assert n_condensed == bound.transcribe(pr, bound.Reduced()).n_parameters
