"""knit-nlp calibrate's input: the test readers and the metric against hand computations, and
hostile specs and CSVs refused in one line with exit 2, nothing written (examples and
hypothesis properties). Parse only: no model is solved here."""
from __future__ import annotations

import copy
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calibration_files import SPEC_SBS, ramp_runs, sbs_row, write_columns, write_sbs, write_spec
from knit_nlp.cli import main
from knit_nlp.errors import ProblemError
from knit_nlp.weft.inverse.calibration import load_spec, parse_spec
from knit_nlp.weft.inverse.calibration.measured import read_columns, read_stitch_by_stitch
from knit_nlp.weft.inverse.calibration.metric import levels, metric

SETTINGS = settings(max_examples=60, deadline=5000, derandomize=False,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])

# three runs (frames given out of order in run 1), pins chosen for round strains
HAND_RUNS = {
    1: [(0, 0.0, 200.0, 100.0), (2, 3.0, 230.0, 95.0), (1, 1.0, 210.0, 98.0),
        (3, 2.5, 228.0, 95.5), (4, 6.0, 250.0, 90.0)],
    2: [(0, 0.0, 100.0, 50.0), (1, 2.0, 104.0, 49.5), (2, 4.0, 110.0, 48.0), (3, 5.5, 118.0, 47.0)],
    3: [(0, 0.0, 100.0, 40.0), (1, 2.5, 108.0, 39.6), (2, 5.0, 120.0, 38.8)],
}


def _hand_file(tmp_path: Path) -> Path:
    rows = [sbs_row(run, *frame) for run, frames in HAND_RUNS.items() for frame in frames]
    return write_sbs(tmp_path / "hand.csv", rows, clamp=100.0, fabric=150.0)


def test_stitch_by_stitch_reader_on_a_tiny_file(tmp_path):
    test = read_stitch_by_stitch(_hand_file(tmp_path), "hand.csv")
    assert [r.label for r in test.runs] == ["1", "2", "3"]
    run1 = test.runs[0]                                     # frames sorted: 0, 1, 2, 3, 4
    assert np.allclose(run1.force, [0.0, 1.0, 3.0, 2.5, 6.0])
    assert np.allclose(run1.axial, [0.0, 0.05, 0.15, 0.14, 0.25])
    assert np.allclose(run1.lateral, [0.0, -0.02, -0.05, -0.045, -0.10])
    assert test.aspect == pytest.approx(2.0)                # median of 2, 2, 2.5
    assert test.width_clamps == pytest.approx(1.5)          # 150 / 100
    assert test.max_force == 6.0 and test.common_force == 5.0
    assert test.description == "A test fabric"


def test_metric_against_a_hand_computation(tmp_path):
    """Medians over runs of the first frame reaching 2 N and 5 N: axial (0.08, 0.20), lateral
    (-0.01, -0.06); model (0.10, 0.17) and (-0.02, -0.05): RMS sqrt(6.5e-4) and 0.01."""
    test = read_stitch_by_stitch(_hand_file(tmp_path), "hand.csv")
    assert np.allclose(levels(test, (2.0, 5.0)), [[0.15, 0.25], [0.04, 0.18], [0.08, 0.20]])
    m = metric(test, (2.0, 5.0), np.array([0.10, 0.17]), np.array([-0.02, -0.05]))
    assert np.allclose(m.measured_axial, [0.08, 0.20])
    assert np.allclose(m.measured_lateral, [-0.01, -0.06])
    assert m.rms_axial == pytest.approx(math.sqrt(6.5e-4))
    assert m.rms_lateral == pytest.approx(0.01)
    assert metric(test, (2.0, 5.0), np.array([0.1, np.nan]), None).rms_axial is None


def test_columns_reader_groups_runs(tmp_path):
    path = write_columns(tmp_path / "c.csv", np.array([0, 1, 2, 0, 1.5]),
                         np.array([0, .1, .2, 0, .12]), np.array([0, -.01, -.02, 0, -.01]),
                         np.array(["a", "a", "a", "b", "b"]))
    test = read_columns(path, "c.csv")
    assert [r.label for r in test.runs] == ["a", "b"] and test.has_lateral
    assert test.aspect is None and test.width_clamps is None
    assert np.allclose(test.runs[1].axial, [0, .12])


def _run_cli(spec: Path, out: Path, capsys) -> tuple[int, str]:
    code = main(["calibrate", str(spec), "--out", str(out)])
    return code, capsys.readouterr().err


def _refused(spec: Path, tmp_path: Path, capsys, *needles: str) -> str:
    out = tmp_path / "out"
    code, err = _run_cli(spec, out, capsys)
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("knit-nlp: "), err
    for needle in needles:
        assert needle in err, err
    assert not out.exists()                                     # nothing written
    return err


def _bad_x(tmp_path: Path, text: str | bytes) -> Path:
    (tmp_path / "x.csv").write_bytes(text if isinstance(text, bytes) else text.encode())
    return write_spec(tmp_path, SPEC_SBS)


def _good_lines(tmp_path: Path) -> list[str]:
    return ramp_runs(tmp_path / "good.csv").read_text().splitlines()


def _with_cell(lines: list[str], k: int, column: int, value: str) -> list[str]:
    cells = lines[k].split(",")
    cells[column] = value
    return lines[:k] + [",".join(cells)] + lines[k + 1:]


@pytest.mark.parametrize("case, needles", [
    ("missing_column", ("x.csv", "missing column(s) top_pin_y")),
    ("not_a_number", ("x.csv", "line 5", "force_N", "expected a number")),
    ("never_reaches", ("x.csv", "run 1", "no frame reaches 25 N", "lower them")),
    ("never_rises", ("x.csv", "run 2", "never rises")),
    ("falls_from_second_frame", ("x.csv", "run 2", "force_N", "at frame 2 of 11", "must grow")),
    ("huge_cell", ("x.csv", "characters")),
    ("long_cell", ("x.csv", "line 5", "a cell of 100 characters")),
    ("empty", ("x.csv", "no header and no rows")),
    ("non_finite", ("x.csv", "must be finite")),
    ("not_utf8", ("x.csv", "not UTF-8")),
    ("header_only", ("x.csv", "no rows")),
    ("ragged_row", ("x.csv", "expected 13 cells")),
])
def test_bad_csvs_are_refused_in_one_line(tmp_path, capsys, case, needles):
    lines = _good_lines(tmp_path)                   # 2 comments, header (line 3), rows
    text: str | bytes
    if case == "missing_column":
        text = "\n".join(ln if ln.startswith("#") else ",".join(
            c for q, c in enumerate(ln.split(",")) if q != 10) for ln in lines)
    elif case == "not_a_number":
        text = "\n".join(_with_cell(lines, 4, 2, "abc"))
    elif case == "never_reaches":
        text = "\n".join(lines[:3] + [sbs_row(1, k, 20.0 * k / 10, 200, 100) for k in range(11)]
                         + [sbs_row(2, k, 30.0 * k / 10, 200, 100) for k in range(11)])
    elif case == "never_rises":
        text = "\n".join(lines[:3] + [sbs_row(1, k, 30.0 * k / 10, 200, 100) for k in range(11)]
                         + [sbs_row(2, k, 1.0 - k / 10, 200, 100) for k in range(11)])
    elif case == "falls_from_second_frame":       # issue 41: passed the old check (max > first)
        text = "\n".join(lines[:3] + [sbs_row(1, k, 30.0 * k / 10, 200, 100) for k in range(11)]
                         + [sbs_row(2, k, 0.0 if k == 0 else 30.0 - 3 * (k - 1), 200 + k, 100)
                            for k in range(11)])
    elif case == "huge_cell":
        text = "\n".join(_with_cell(lines, 4, 2, "9" * 100_000))
    elif case == "long_cell":
        text = "\n".join(_with_cell(lines, 4, 2, "9" * 100))
    elif case == "empty":
        text = ""
    elif case == "non_finite":
        text = "\n".join(_with_cell(lines, 4, 2, "inf"))
    elif case == "not_utf8":
        text = b"\xff\xfe" + "\n".join(lines).encode()
    elif case == "header_only":
        text = "\n".join(lines[:3])
    else:
        text = "\n".join(lines[:4] + ["1,2,3"])
    _refused(_bad_x(tmp_path, text), tmp_path, capsys, *needles)


@pytest.mark.parametrize("edit, needles", [
    (("calibrate", "fit", ["k_c"]), ("[calibrate] fit", "unknown entry 'k_c'")),
    (("calibrate", "speed", 3), ("[calibrate] speed", "unknown key")),
    (("calibrate", "forces", [5.0, 2.0]), ("[calibrate] forces", "increasing")),
    (("calibrate", "targets", {"fit_axial": -0.03}), ("[calibrate.targets] fit_axial", "positive")),
    (("calibrate", "targets", {"fit_shear": 0.03}), ("[calibrate.targets] fit_shear", "unknown")),
    (("calibrate", "length_scale", 25.4), ("[calibrate] length_scale", "the specimen's size",
                                          "clamp_width_mm = 35.5")),
    (("calibrate", "fit", ["k_b", "length_scale"]), ("[calibrate] fit", "the source gives",
                                                     "clamp_width_mm = 35.5")),
    (("calibrate", "clamp_width_mm", 0.0), ("[calibrate] clamp_width_mm", "positive")),
    (("units", "length", "cm"), ("[units] length", "mm")),
    (("test", "file", "../x.csv"), ("[test[1]] file", "outside the spec's folder")),
    (("test", "file", "/etc/passwd"), ("[test[1]] file", "relative path")),
    (("test", "direction", "bias"), ("[test[1]] direction", "must be one of")),
    (("test", "use", "predict"), ("(top level) test", "at least one test with use = \"fit\"")),
    (("units", "force", "kN"), ("[units] force", "newtons")),
    (("clamp", None, [{"edge": "left"}]), ("clamp", "rigid clamps")),
    (("load", None, [{"edge": "right", "force": [1.0, 0.0]}]), ("load", "pulled by its clamp")),
    (("reduction", None, {"adaptive": True}), ("reduction", "full model")),
    (("calibrate", "fit", ["R_f"]), ()),                    # valid: parsed, not solved here
])
def test_bad_specs_are_refused_in_one_line(tmp_path, capsys, edit, needles):
    import tomllib
    ramp_runs(tmp_path / "x.csv")
    doc = tomllib.loads(SPEC_SBS.replace("\n    ", "\n").strip())
    table, key, value = edit
    if key is None:
        doc[table] = value
    elif table == "test":
        doc["test"][0][key] = value
    elif value is None:
        doc[table].pop(key)
    else:
        doc.setdefault(table, {})[key] = value
    if not needles:
        assert parse_spec(doc, tmp_path / "spec.toml").fit == ("R_f",)
        return
    with pytest.raises(ProblemError) as err:
        parse_spec(doc, tmp_path / "spec.toml")
    for needle in needles:
        assert needle in str(err.value), str(err.value)


def test_a_shipped_spec_is_found_by_its_name_under_the_named_problems():
    from knit_nlp.problems import problems_dir
    from knit_nlp.weft.inverse.calibration.spec import spec_path
    shipped = problems_dir() / "real_fabric" / "acrylic_fit_x.toml"
    assert spec_path("real_fabric/acrylic_fit_x") == shipped
    assert spec_path("real_fabric/acrylic_fit_x.toml") == shipped
    assert spec_path("no/such\0spec") == Path("no/such\0spec")


def test_the_shipped_spec_reads_its_data():
    spec = load_spec(Path(__file__).resolve().parent.parent / "problems" / "real_fabric"
                     / "acrylic_fit_x.toml")
    x, y = spec.tests
    assert (x.direction, x.use, y.direction, y.use) == ("courses", "fit", "wales", "predict")
    assert [len(t.measured.runs) for t in spec.tests] == [5, 5]
    assert x.measured.width_clamps == pytest.approx(306.4001 / 163.4307)
    assert y.measured.width_clamps == pytest.approx(567.3047 / 210.0798)
    assert 1.8 < x.aspect < 1.95 and 0.5 < y.aspect < 0.55       # gauge over width, pins


# --- hypothesis: hostile cells and spec values --------------------------------------------

CELLS = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                  st.integers(-10 ** 30, 10 ** 30).map(str),
                  st.text(max_size=12), st.just(""), st.just("1e999"), st.just("9" * 80),
                  st.just('"a,b"'))


@SETTINGS
@given(rows=st.lists(st.lists(CELLS, min_size=1, max_size=15), max_size=8),
       header=st.sampled_from(["full", "shuffled", "short"]))
def test_hostile_tracking_files_are_read_or_refused_in_one_line(tmp_path, rows, header):
    names = ["run", "frame", "force_N", "right_pin_x", "right_pin_y", "left_pin_x", "left_pin_y",
             "bottom_pin_x", "bottom_pin_y", "top_pin_x", "top_pin_y"]
    if header == "shuffled":
        names = names[::-1]
    elif header == "short":
        names = names[:7]
    text = ",".join(names) + "\n" + "\n".join(",".join(r) for r in rows)
    path = tmp_path / "h.csv"
    path.write_bytes(text.encode("utf-8", "surrogatepass"))
    try:
        test = read_stitch_by_stitch(path, "h.csv")
    except ProblemError as err:
        assert "\n" not in str(err) and str(err).startswith(str(path))
        return
    assert all(np.all(np.isfinite(r.axial)) and r.force.max() > r.force[0] for r in test.runs)


VALUES = st.one_of(st.none(), st.booleans(), st.integers(-10 ** 12, 10 ** 12),
                   st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=10),
                   st.lists(st.one_of(st.text(max_size=8), st.floats(), st.integers()), max_size=4),
                   st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
                   st.sampled_from(["k_a", "k_b", "R_f", "length_scale", "courses", "wales",
                                    "fit", "predict", "columns", "stitch_by_stitch", "x.csv",
                                    "implicit", "finite_differences", "periodic", "clamped",
                                    "natural", "straight"]))
KEYS = st.sampled_from([("calibrate", k) for k in ("fit", "clamp_width_mm", "forces", "strains",
                                                    "min_loops", "sensitivities", "specimen",
                                                    "scan", "cell_samples", "bending_reference",
                                                    "extra")]
                       + [("test", k) for k in ("file", "format", "direction", "use", "width",
                                                "aspect", "extra")]
                       + [("fabric", k) for k in ("courses", "wales")])


@SETTINGS
@given(edits=st.lists(st.tuples(KEYS, VALUES), min_size=1, max_size=4))
def test_hostile_spec_tables_are_parsed_or_refused_in_one_line(tmp_path, capsys, edits):
    import tomllib
    ramp_runs(tmp_path / "x.csv")
    doc = tomllib.loads(SPEC_SBS.replace("\n    ", "\n").strip())
    for (table, key), value in edits:
        target = doc["test"][0] if table == "test" else doc.setdefault(table, {})
        if value is None:
            target.pop(key, None)
        else:
            target[key] = copy.deepcopy(value)
    try:
        parse_spec(doc, tmp_path / "spec.toml")
    except ProblemError as err:
        message = str(err)
        assert "\n" not in message and message.isprintable()
        return
    except RecursionError:                                      # pragma: no cover
        pytest.fail("recursion on a spec")


def test_a_refused_spec_file_exits_2_through_the_cli(tmp_path, capsys):
    """The one-line contract end to end, for the spec itself (not only its CSV)."""
    ramp_runs(tmp_path / "x.csv")
    spec = write_spec(tmp_path, SPEC_SBS.replace('fit = ["k_b"]', 'fit = ["k_b", "k_b"]'))
    _refused(spec, tmp_path, capsys, "[calibrate] fit", "twice")


def test_the_shipped_data_are_the_published_bytes_with_their_licence():
    """The copies match the hashes recorded in problems/real_fabric/SOURCE.md (taken from the
    shared data folder) and the MIT licence travels with them."""
    import hashlib
    import re
    folder = Path(__file__).resolve().parent.parent / "problems" / "real_fabric"
    recorded = dict(re.findall(r"\| `([^`]+)` \| `([0-9a-f]{64})` \|",
                               (folder / "SOURCE.md").read_text()))
    assert set(recorded) == {"acrylic_stockinette_x.csv", "acrylic_stockinette_y.csv", "LICENSE"}
    for name, digest in recorded.items():
        assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest, name
    assert "MIT License" in (folder / "LICENSE").read_text()


def test_the_width_conversion_is_the_sources_formula_on_one_frame_by_hand():
    """stitch-by-stitch template.nb: stress = force / (fabricSize · 35.5 / clampSize). The x
    file's comment line gives clampSize 163.4307 px and fabricSize 306.4001 px, so the specimen
    is 306.4001 × 35.5 / 163.4307 = 66.555 mm wide; its run 1 first reaches 10 N at frame 2129,
    10.700 N: stress 10.700 / 66.555 = 0.16077 N/mm. The calibration compares that frame with
    the model force 10.700 / scale on the model's pitch width: the same stress."""
    from knit_nlp.weft.inverse.calibration.calibrate import Calibration
    folder = Path(__file__).resolve().parent.parent / "problems" / "real_fabric"
    x = Calibration(load_spec(folder / "acrylic_fit_x.toml")).models[0]
    run = x.measured.runs[0]
    k = int(np.argmax(run.force >= 10.0))
    assert run.label == "1" and run.force[k] == 10.700
    assert x.width() == pytest.approx(66.555, abs=5e-4)
    model_force = run.force[k] / x.scale()
    assert model_force / x.specimen.pitch_width == pytest.approx(0.16077, abs=5e-6)
