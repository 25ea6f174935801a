"""What a researcher checks first (issue 40 item 4): the force at 10 % and 30 % strain, the
stiffening from 5 % to 45 %, the wale / course stiffness per width at 10 %, recomputed here
from the files the command writes (the curves CSV, the test CSV) and compared with its JSON."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from calibration_files import SYNTH_TRUTH, predicted_wale_test, synthetic_columns, synthetic_spec
from knit_nlp.cli import main
from knit_nlp.weft.inverse.calibration.checks import force_at


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """``knit-nlp calibrate`` at the true values (nothing fitted) on the model's own 2 x 3 curve
    to strain 0.6, as a course pull (fit) and as a wale pull (predict)."""
    folder = tmp_path_factory.mktemp("checks")
    width = synthetic_columns(folder / "synthetic.csv", rows=600, strain=0.6)
    spec = synthetic_spec(folder, width, "[]", SYNTH_TRUTH, extra=predicted_wale_test(2 * width))
    out = folder / "out"
    main(["calibrate", str(spec), "--out", str(out)])
    doc = json.loads((out / "synthetic.calibration.json").read_text())
    with open(out / "synthetic.curves.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    return folder, doc, rows


def _model_curve(rows: list[dict], use: str) -> tuple[np.ndarray, np.ndarray]:
    pick = [r for r in rows if r["use"] == use]
    axial = np.array([float(r["axial_strain"]) for r in pick])
    force = np.array([float(r["force_N"]) for r in pick])
    assert np.all(np.diff(axial) > 0) and np.all(np.diff(force) > 0)
    return axial, force


def _tangent(axial: np.ndarray, force: np.ndarray, strain: float) -> float:
    return (np.interp(strain + 0.025, axial, force) - np.interp(strain - 0.025, axial, force)) / 0.05


def test_the_models_checks_are_those_of_its_curves_csv(written):
    """From the curves CSV alone (np.interp on the monotone nodes) and the JSON's widths."""
    _, doc, rows = written
    stiff = {}
    for t in doc["tests"]:
        axial, force = _model_curve(rows, t["use"])
        got = t["checks"]["model"]
        for e in (0.1, 0.3):
            assert got["force_N"][f"{e:g}"] == pytest.approx(np.interp(e, axial, force), rel=1e-6)
        assert got["stiffening"] == pytest.approx(
            _tangent(axial, force, 0.45) / _tangent(axial, force, 0.05), rel=1e-6)
        stiff[t["direction"]] = _tangent(axial, force, 0.1) / t["specimen"]["width"]
        assert got["stiffness_per_width"] == pytest.approx(stiff[t["direction"]], rel=1e-6)
    ratio = doc["checks"]["wale_over_course_stiffness_per_width_at_0.1"]
    assert ratio["model"] == pytest.approx(stiff["wales"] / stiff["courses"], rel=1e-6)
    assert 0.1 < ratio["model"] < 10 and ratio["measured"] == pytest.approx(0.5, rel=0.02)


def test_the_measured_checks_are_the_median_runs_first_crossing(written):
    """From the test CSV: per run, the force where its axial strain first reaches 10 % and 30 %
    (linear between the two frames around it), median over the three runs."""
    folder, doc, _ = written
    with open(folder / "synthetic.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for e in (0.1, 0.3):
        per_run = []
        for run in ("1", "2", "3"):
            a = np.array([float(r["axial_strain"]) for r in rows if r["run"] == run])
            f = np.array([float(r["force_N"]) for r in rows if r["run"] == run])
            k = int(np.argmax(a >= e))
            per_run.append(f[k - 1] + (f[k] - f[k - 1]) * (e - a[k - 1]) / (a[k] - a[k - 1]))
        got = doc["tests"][0]["checks"]["measured"]["force_N"][f"{e:g}"]
        assert got == pytest.approx(float(np.median(per_run)), rel=1e-9)
        # the model at the true values, noise 0.002 in strain: within a few percent
        assert doc["tests"][0]["checks"]["model"]["force_N"][f"{e:g}"] == pytest.approx(got, rel=0.05)


def test_a_strain_never_reached_has_no_force():
    assert force_at(np.array([0.0, 0.05, 0.2]), np.array([0.0, 1.0, 3.0]), 0.3) is None
    assert force_at(np.array([0.0, 0.05, 0.2]), np.array([0.0, 1.0, 3.0]), 0.1) == pytest.approx(
        1.0 + 2.0 * 0.05 / 0.15)


@pytest.mark.parametrize("strain, force", [(-0.1, 0.5), (0.0, 0.5), (0.05, 0.875), (0.1, 1.25),
                                           (0.3, 4.0), (0.5, None)])
def test_force_at_interpolates_between_the_points_that_bracket_the_strain(strain, force):
    """F(ε) on a broken line through (0, 0.5), (0.2, 2), (0.4, 6): linear between its
    points, the first point's force where ε is reached at once, None beyond the last (red
    with the first point's case taken at the second point, a survivor of scripts/mutate.py:
    no read fell between the first two points)."""
    axial, forces = np.array([0.0, 0.2, 0.4]), np.array([0.5, 2.0, 6.0])
    assert force_at(axial, forces, strain) == (None if force is None else pytest.approx(force))


def test_a_curve_without_a_solved_node_has_no_final_check() -> None:
    """``calibrate --breaks`` on acrylic_3d_source crashed after 38 minutes (IndexError) where
    the loop length ×2 left a test's model curve without a solved node."""
    from knit_nlp.weft.inverse.calibration.calibrate import final_check
    from knit_nlp.weft.inverse.calibration.curve import Curve

    empty = Curve(np.zeros(0), np.zeros(0), np.zeros(0), complete=False, reason="no start")
    assert final_check(None, empty, None) == {}
