"""Calibration with the 3-D weft model (issue 40 items 1, 3, 4 with issue 39's model): a spec whose
``[yarn]`` has geometry = "3d" is read with its measured values held, its contact rigidity enters
as an exact energy scale, a fitted measured value is reported beside its measurement, the metric
in the JSON is the one the curves CSV and the test CSV give, and the planar model's figures
stand beside the 3-D model's. Small fabrics (2 x 2 loops): seconds of CPU each."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest
from scipy.interpolate import PchipInterpolator

from calibration_files import noisy_columns
from knit_nlp.cli import main
from knit_nlp.errors import ProblemError
from knit_nlp.tomlio import load_toml, toml_text
from knit_nlp.weft.inverse.calibration.calibrate import TestModel as SpecimenTest
from knit_nlp.weft.inverse.calibration.curve import SpecimenModel, strains_at
from knit_nlp.weft.inverse.calibration.spec import load_spec, parse_spec
from knit_nlp.weft.inverse.calibration.specimen import build_specimen

TRUTH_R_F = 0.045
YARN = {"radius": 0.74, "geometry": "3d"}
DOC = {"units": {"length": "mm", "force": "N"}, "loop": {"length": 11.28},
       "material": {"R_f": TRUTH_R_F}, "yarn": YARN}
FORCES = (2.0, 5.0, 8.0)


def synthetic_3d(path, top: float = 10.0, runs: int = 3, rows: int = 400,
                 noise: float = 0.001) -> float:
    """The 3-D model's own 2 x 2 course pull (R_f = 0.045, the acrylic's default law) to 20 %
    strain, written as a ``columns`` test with noise; returns the width (mm) at which the
    model's force at 20 % is ``top`` N."""
    sp = build_specimen(DOC, "<synthetic3d>", "courses", 2, 2, "synthetic3d")
    c = SpecimenModel(sp).pull_to(DOC["material"], np.linspace(0.02, 0.2, 10))
    return noisy_columns(path, c, sp, top, noise, runs, rows, seed=3)


PLANAR = {"k_a": 0.0354, "k_b": 0.000354}       # the paper's crossing springs


def spec_file(folder, width: float, fit: tuple[str, ...] = (), R_f: float = TRUTH_R_F,
              planar: bool = False, **calibrate: str):
    """The calibration spec of the 2 x 2 course pull in ``synthetic3d.csv`` (``width`` mm),
    written to ``folder``: the 3-D model's, ``synthetic3d.toml`` (the yarn of ``DOC``), or with
    ``planar`` the paper's, ``planar.toml`` (crossing springs, no yarn); ``fit``, ``R_f`` and
    further ``[calibrate]`` keys (``beside``) as given."""
    name = "planar" if planar else "synthetic3d"
    model = ({"material": {**PLANAR, "R_f": R_f}} if planar
             else {"material": {"R_f": R_f}, "yarn": YARN})
    doc = {"name": name, "fabric": {"courses": 2, "wales": 2}, "loop": DOC["loop"],
           "units": DOC["units"], **model,
           "calibrate": {"fit": list(fit), "forces": list(FORCES), **calibrate},
           "test": [{"file": "synthetic3d.csv", "format": "columns", "direction": "courses",
                     "use": "fit", "width": width}]}
    path = folder / f"{name}.toml"
    path.write_text(toml_text(doc))
    return path


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cal3d")
    return folder, synthetic_3d(folder / "synthetic3d.csv")


@pytest.fixture(scope="module")
def fitted(data):
    """``knit-nlp calibrate`` of the 3-D spec, R_f fitted from 0.06 on the 3-D model's own
    curve (truth 0.045), with the planar spec on the same test beside it; and the planar spec
    alone."""
    folder, width = data
    spec_file(folder, width, planar=True)
    out = folder / "out"
    spec = spec_file(folder, width, ("R_f",), 0.06, beside="planar.toml")
    code = main(["calibrate", str(spec), "--out", str(out)])
    main(["calibrate", str(folder / "planar.toml"), "--out", str(folder / "planar_out")])
    doc = json.loads((out / "synthetic3d.calibration.json").read_text())
    planar = json.loads((folder / "planar_out" / "planar.calibration.json").read_text())
    return folder, code, doc, planar


def test_a_3d_spec_holds_its_measured_values_and_refuses_what_it_cannot_fit(data):
    """Read: the 3-D spec's yarn values are its values (radius measured); only R_f and the
    contact rigidity may be fitted (k_a, k_b are off in 3-D without crossing springs, the radius
    shapes the natural loop), its sensitivities are curve differences (no KKT ones in 3-D)."""
    folder, width = data
    spec = load_spec(spec_file(folder, width))
    assert spec.spatial and spec.sensitivities == "curve_differences" and spec.fit == ()
    assert spec.values["radius"] == 0.74 and spec.values["R_f"] == TRUTH_R_F
    assert spec.values["contact_rigidity"] == pytest.approx(0.0012)
    doc = load_toml(spec_file(folder, width))
    for key, value, words in (("fit", ["radius"], "contact_rigidity"),
                              ("fit", ["k_a"], "R_f"),
                              ("sensitivities", "implicit", "curve_differences"),
                              ("beside", "nowhere.toml", "no calibration spec")):
        bad = {**doc, "calibrate": {**doc["calibrate"], key: value}}
        with pytest.raises(ProblemError) as err:
            parse_spec(bad, folder / "synthetic3d.toml")
        assert key in str(err.value) and words in str(err.value)


def test_the_contact_rigidity_is_an_exact_energy_scale(data):
    """U = R_f B + k C: the NLP built at k0, re-solved with the material divided by
    λ = k / k0 and its forces times λ, is the NLP built at k (``TestModel.energy_scale``):
    the same forces at the same clamp strains, to the solver's tolerance."""
    folder, width = data
    spec = load_spec(spec_file(folder, width))
    tm = SpecimenTest(spec, 0)
    values = {**spec.values, "contact_rigidity": 4 * spec.values["contact_rigidity"]}
    strains = [0.05, 0.1]
    scaled = tm.model.pull_to(tm.material(values), strains).force * tm.energy_scale(values)
    doc = {**DOC, "yarn": {**YARN, "contact_rigidity": values["contact_rigidity"]}}
    direct = SpecimenModel(build_specimen(doc, "<k>", "courses", 2, 2, "k")).pull_to(
        DOC["material"], strains).force
    base = tm.model.pull_to(DOC["material"], strains).force
    assert tm.energy_scale(values) == pytest.approx(4.0)
    assert scaled[1:] == pytest.approx(direct[1:], rel=1e-5)
    # the contacts carry load: k moves the force well beyond that tolerance
    assert abs(direct[2] / base[2] - 1) > 1e-3


def test_a_fitted_measured_value_is_reported_beside_its_measurement_in_3d(fitted, capsys):
    """R_f fitted in 3-D from the spec's 0.06 lands on the truth and is reported as fitted
    beside its measurement; the radius is held and reported as measured; the contact law's
    other values as held, without a measurement."""
    folder, code, doc, _ = fitted
    row = doc["parameters"]["R_f"]
    assert row["fitted"] and row["measured"] == 0.06
    assert row["value"] == pytest.approx(TRUTH_R_F, rel=0.05)
    assert doc["parameters"]["radius"] == {"value": 0.74, "fitted": False, "initial": 0.74,
                                           "measured": 0.74}
    assert "measured" not in doc["parameters"]["contact_rigidity"]
    assert "k_a" not in doc["parameters"] and doc["given"]["geometry"] == "3d"
    assert doc["sensitivities"] == "curve_differences"
    assert doc["tests"][0]["check"]["model"] == "3d"


def test_the_3d_metric_is_that_of_its_curves_csv(fitted):
    """From the files alone: the model's strains at the metric forces by monotone cubic
    interpolation of the curves CSV's nodes, the measured ones the median over runs of each
    run's first row reaching the force; their RMS is the JSON's."""
    folder, _, doc, _ = fitted
    with open(folder / "out" / "synthetic3d.curves.csv", newline="") as fh:
        nodes = [r for r in csv.DictReader(fh) if r["test"] == "synthetic3d.csv"]
    force = np.array([float(r["force_N"]) for r in nodes])
    model = {k: PchipInterpolator(force, [float(r[f"{k}_strain"]) for r in nodes])(FORCES)
             for k in ("axial", "lateral")}
    with open(folder / "synthetic3d.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    for kind in ("axial", "lateral"):
        medians = []
        for f in FORCES:
            firsts = []
            for run in ("1", "2", "3"):
                mine = [r for r in rows if r["run"] == run]
                firsts.append(next(float(r[f"{kind}_strain"]) for r in mine
                                   if float(r["force_N"]) >= f))
            medians.append(np.median(firsts))
        rms = float(np.sqrt(np.mean((model[kind] - np.array(medians)) ** 2)))
        assert doc["tests"][0]["rms_strain_error"][kind] == pytest.approx(rms, rel=1e-5, abs=1e-7)
    assert doc["tests"][0]["rms_strain_error"]["axial"] < 0.01     # (the truth was recovered)


def test_the_planar_models_figures_stand_beside_the_3d_models(fitted, capsys):
    """``beside``: the JSON's checks carry the planar spec's figures, the same as its own run's
    JSON; the 3-D figures are this run's."""
    _, code, doc, planar = fitted
    beside = doc["checks"]["beside"]
    assert beside["geometry"] == "planar" and beside["name"] == "planar"
    mine, theirs = beside["tests"][0], planar["tests"][0]
    assert mine["rms_strain_error"] == theirs["rms_strain_error"]
    assert mine["checks"] == theirs["checks"]
    assert doc["tests"][0]["rms_strain_error"] != theirs["rms_strain_error"]
    key = "wale_over_course_stiffness_per_width_at_0.1"
    assert key in beside and code in (0, 1)
