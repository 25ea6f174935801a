"""knit-nlp sweep: grids over problem-file keys agree with one solve per point; bad axes are one
line and exit code 2."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import knit_nlp
from knit_nlp.api import parse_problem
from knit_nlp.cli import main
from knit_nlp.jacquard.study import set_key
from knit_nlp.studies.sweep import parse_axis
from knit_nlp.weft.keys import changes
from knit_nlp.tomlio import load_toml

from conftest import PROBLEMS


def _sweep(tmp_path, *args):
    return main(["sweep", *args, "--workers", "2", "--out", str(tmp_path)])


def _rows(tmp_path, name):
    return json.loads((tmp_path / name / "summary.json").read_text())["points"]


def test_weft_sweep_matches_one_solve_per_point(tmp_path, capsys):
    """A k_b grid x a loading path of the pulled clamp's x target: every point equals a cold
    solve of the problem file with those two values written into it (energy, reactions)."""
    assert _sweep(tmp_path, "wada_fig7", "--vary", "material.k_b=0.01:0.1:2",
                  "--path", "clamp[2].position.x=14.2:16.2:2") == 0
    rows = _rows(tmp_path, "sweep_wada_fig7")
    assert [r["path"] for r in rows] == ["p0000", "p0000", "p0001", "p0001"]
    doc = load_toml(PROBLEMS / "wada_fig7.toml")
    for r in rows:
        kb, x = r["label"]["material.k_b"], r["label"]["clamp[2].position.x"]
        one = set_key(doc, "material.k_b", kb)
        one["clamp"][1]["position"][0] = x
        alone = knit_nlp.solve(parse_problem(one, PROBLEMS / "wada_fig7.toml"))
        assert r["success"] and alone.success
        assert r["energy"]["total"] == pytest.approx(alone.energy.total, rel=1e-7)
        for got, want in zip(r["clamps"], alone.clamps):
            np.testing.assert_allclose(got["reaction"], want.reaction, atol=1e-7)
    table = list(csv.DictReader((tmp_path / "sweep_wada_fig7" / "sweep.csv").open()))
    assert [float(t["energy_total"]) for t in table] == [r["energy"]["total"] for r in rows]
    assert (tmp_path / "sweep_wada_fig7" / "sweep.png").stat().st_size > 10_000
    assert "4 of 4 points converged" in capsys.readouterr().out


def test_sweep_on_a_local_dask_cluster_equals_the_local_pool(tmp_path):
    pytest.importorskip("distributed")
    args = ["wada_fig7", "--vary", "material.R_f=0.5:2:2", "--path", "material.k_b=0.01:0.05:2"]
    assert main(["sweep", *args, "--out", str(tmp_path / "pool")]) == 0
    assert main(["sweep", *args, "--scheduler", "local:2", "--out", str(tmp_path / "dask")]) == 0
    assert _rows(tmp_path / "pool", "sweep_wada_fig7") == _rows(tmp_path / "dask", "sweep_wada_fig7")


def test_jacquard_sweep_matches_one_solve_per_point(tmp_path):
    """Thick fall-plate stiffness x thin inlay pretension on the diamond (designs in sibling
    files, shipped inline): each point equals a solve of the edited document."""
    assert _sweep(tmp_path, "jacquard_diamond", "--vary", "fall_plate.stiffness.thick=0.5:2:2",
                  "--vary", "inlay.pretension.thin=0.8:0.95:2", "--name", "jd") == 0
    rows = _rows(tmp_path, "jd")
    assert len(rows) == 4
    doc = load_toml(PROBLEMS / "jacquard_diamond.toml")
    energies = []
    for r in rows:
        one = doc
        for key, value in r["label"].items():
            one = set_key(one, key, value)
        alone = knit_nlp.solve(parse_problem(one, PROBLEMS / "jacquard_diamond.toml"))
        assert r["success"] and alone.success
        assert r["energy"]["total"] == pytest.approx(alone.energy.total, rel=1e-7, abs=1e-12)
        energies.append(r["energy"]["total"])
    assert len(set(np.round(energies, 9))) == 4        # each key changes the equilibrium


def test_displacement_keys_are_from_the_natural_position():
    """clamp[2].displacement.x = d sets the same target as clamp[2].position.x = natural x + d;
    a whole-vector axis runs along the segment between its ends."""
    pr = knit_nlp.load_problem("wada_fig7")
    c = pr.clamps[1]
    x0, y0 = pr.natural_position(c.loop, c.s)
    by_d = changes(pr, [("clamp[2].displacement.x", (1.0,), 1.0)])
    by_p = changes(pr, [("clamp[2].position.x", (x0 + 1,), x0 + 1)])
    assert by_d == by_p == {"targets": {"2": [x0 + 1, 13.9]}}
    axis = parse_axis("--path", "clamp[2].displacement=0,0:2,1:3")
    assert axis.values == ([0.0, 0.0], [1.0, 0.5], [2.0, 1.0])
    assert changes(pr, [(axis.key, axis.values, axis.values[1])])["targets"]["2"] == [x0 + 1.0,
                                                                                     y0 + 0.5]


@pytest.mark.parametrize("args, where", [
    (["wada_fig7", "--vary", "material.k_x=0:1:2"], "--vary material.k_x=0:1:2: unknown key"),
    (["wada_fig7", "--vary", "material.k_b=-1:1:3"], "k_b must be >= 0"),
    (["wada_fig7", "--vary", "material.k_b=0:1"], "use KEY=START:STOP:COUNT"),
    (["wada_fig7", "--vary", "material.k_b=0:1:0"], "COUNT must be from 1"),
    (["wada_fig7", "--vary", "clamp[3].position.x=0:1:2"], "clamp[3] does not exist"),
    (["wada_fig7", "--vary", "clamp[2].angle=0:1:2"], "holds no angle"),
    (["wada_fig7", "--vary", "clamp[2].displacement=0:1:2"], "is a vector"),
    (["wada_fig7", "--vary", "material.k_b=nan:1:2"], "is not a number"),
    (["wada_fig7", "--path", "material.k_b=0:1:2", "--path", "material.R_f=1:2:3"], "same COUNT"),
    (["jacquard_stripe", "--path", "ground.stiffness=1:2:2"], "independent"),
    (["jacquard_stripe", "--vary", "ground.pretension=0.5:1.5:3"], "pretension ratio"),
    (["jacquard_stripe", "--vary", "fabric.dz=1:2:2"], "unknown key"),
    (["wada_fig7", "--vary", "material.k_b=0:1:2", "--name", "../up"], "--name ../up"),
    (["wada_fig7", "--vary", "material.k_b=0:1:2", "--scheduler", "nowhere"], "--scheduler"),
    (["wada_fig7", "--vary", "material.k_b=0:1:2", "--timeout", "-1"], "--timeout"),
])
def test_bad_axes_are_one_line_and_exit_2(tmp_path, capsys, args, where):
    try:                 # argparse exits itself (--scheduler, --timeout); the others return 2
        code = main(["sweep", *args, "--out", str(tmp_path)])
    except SystemExit as exit_:
        code = exit_.code
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("knit-nlp: ") and err.count("\n") == 1 and where in err, err
    assert not list(tmp_path.iterdir())                  # nothing solved, nothing written


ADAPTIVE = """
name = "adaptive_pull"
[fabric]
courses = 3
wales = 3
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [1, 3]
point = "H"
displacement = [4.0, 3.0]
[reduction]
adaptive = true
tolerance = 0.01
"""


def test_sweep_of_an_adaptive_problem_solves_the_adaptive_model(tmp_path):
    """Issue 18: the sweep built the full NLP for [reduction] adaptive = true and called it
    reduced. Each point must be what solve() gives: the adaptive model's parameter count and
    energy, not the full model's."""
    path = tmp_path / "adaptive_pull.toml"
    path.write_text(ADAPTIVE)
    assert _sweep(tmp_path, str(path), "--vary", "material.k_b=0.01:0.02:2", "--name", "a") == 0
    points = sorted((tmp_path / "a" / "points").glob("*.json"))
    assert len(points) == 2
    for js, row in zip(points, _rows(tmp_path, "a")):
        point = json.loads(js.read_text())
        pr = knit_nlp.load_problem(path)
        params = knit_nlp.weft.WeftParams.of(pr).with_(material={"k_b": row["label"]["material.k_b"]})
        alone = knit_nlp.solve(pr, params=params)
        full = knit_nlp.solve(pr, reduced=False, params=params)
        assert alone.success and full.success and point["success"]
        assert point["model"] == "reduced" and "adaptive" in point
        assert point["n_parameters"] == alone.nlp.n_parameters < full.nlp.n_parameters
        assert point["representatives"] == alone.representatives()
        assert row["energy"]["total"] == pytest.approx(alone.energy.total, rel=1e-7)
        assert abs(row["energy"]["total"] - full.energy.total) > 1e-4 * full.energy.total


def test_an_old_jacquard_result_with_a_number_for_energy_is_still_read(tmp_path, capsys):
    """The jacquard JSON's energy became the Energy object; a study cached before (energy a
    number, no message) replays into the same rows, CSV and picture, and overlay refuses it in
    one line (it is not a weft result) instead of failing on it."""
    args = ["jacquard_all_net", "--vary", "ground.stiffness=1:2:2", "--name", "old"]
    assert _sweep(tmp_path, *args) == 0
    new = _rows(tmp_path, "old")
    for js in (tmp_path / "old" / "points").glob("*.json"):
        doc = json.loads(js.read_text())
        assert set(doc["energy"]) == {"total", "spring", "bending", "load_work"}
        doc["energy"] = doc["energy"]["total"]
        del doc["message"]
        js.write_text(json.dumps(doc))
    (tmp_path / "old" / "summary.json").unlink()
    assert _sweep(tmp_path, *args) == 0
    assert all(isinstance(json.loads(js.read_text())["energy"], float)     # replayed, not
               for js in (tmp_path / "old" / "points").glob("*.json"))     # solved again
    old = _rows(tmp_path, "old")
    assert [r["energy"] for r in old] == [r["energy"] for r in new]
    assert all(r["energy"]["spring"] == r["energy"]["total"] > 0 for r in old)
    table = list(csv.DictReader((tmp_path / "old" / "sweep.csv").open()))
    assert [float(t["energy_total"]) for t in table] == [r["energy"]["total"] for r in new]
    js = next((tmp_path / "old" / "points").glob("*.json"))
    capsys.readouterr()
    assert main(["overlay", str(js), str(js), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "NPZ" in err


def _grips():
    """hold_top_pull_corner: clamp[1] is the top edge (8 points), clamp[2] the corner."""
    return knit_nlp.load_problem(PROBLEMS / "hold_top_pull_corner.toml")


def test_a_sweep_key_addresses_the_files_table_not_a_point_of_a_shorthand():
    """clamp[2] is the file's second [[clamp]] table (the pulled corner, the 9th point after the
    top edge expands to 8), not the second point of the held edge."""
    pr = _grips()
    got = changes(pr, [("clamp[2].displacement.x", (1.0,), 1.0)])
    assert list(got["targets"]) == ["9"]
    corner = pr.clamps[8]
    assert corner.loop == (1, 8) and not corner.expanded
    assert got["targets"]["9"][0] == pytest.approx(pr.natural_position(corner.loop, corner.s)[0]
                                                   + 1.0)
    assert got["targets"]["9"][1] == pytest.approx(corner.target[1])


def test_a_sweep_key_into_a_shorthand_table_moves_every_point_it_made():
    pr = _grips()
    got = changes(pr, [("clamp[1].displacement.y", (2.0,), 2.0)])
    assert sorted(got["targets"], key=int) == [str(q) for q in range(1, 9)]
    for q in range(8):
        c = pr.clamps[q]
        want = pr.natural_position(c.loop, c.s) + [0.0, 2.0]
        np.testing.assert_allclose(got["targets"][str(q + 1)], want)


def test_sweep_tables_are_counted_as_the_file_counts_them():
    pr = _grips()
    with pytest.raises(ValueError, match=r"clamp\[3\] does not exist: the problem file has 2 "):
        changes(pr, [("clamp[3].displacement.x", (1.0,), 1.0)])
    with pytest.raises(ValueError, match=r"grips 8 points.*displacement instead"):
        changes(pr, [("clamp[1].position.x", (1.0,), 1.0)])


def test_a_sweep_of_the_pulled_corner_solves_the_file_with_that_pull(tmp_path):
    """End to end: the sweep point with the corner's x displacement d equals a solve of the file
    with the corner table's direction/distance replaced by displacement [d, dy]."""
    pr = _grips()
    corner = pr.clamps[8]
    dy = float(corner.target[1] - pr.natural_position(corner.loop, corner.s)[1])
    text = (PROBLEMS / "hold_top_pull_corner.toml").read_text()
    text = text.replace("courses = 8", "courses = 4").replace("wales = 8", "wales = 4")
    text = text[:text.index("loop = [1, 8]")] + (
        f'loop = [1, 4]\npoint = "end"\ndisplacement = [1.0, {dy!r}]\n')
    small = tmp_path / "hold_top_pull_corner.toml"
    small.write_text(text)
    doc = load_toml(small)
    assert main(["sweep", str(small), "--path", "clamp[2].displacement.x=0:1:2",
                 "--workers", "1", "--out", str(tmp_path / "out")]) == 0
    rows = _rows(tmp_path / "out", "sweep_hold_top_pull_corner")
    alone = knit_nlp.solve(parse_problem(doc, small))
    assert rows[-1]["success"] and alone.success
    assert rows[-1]["energy"]["total"] == pytest.approx(alone.energy.total, rel=1e-6)
    np.testing.assert_allclose(rows[-1]["clamps"][-1]["reaction"], alone.clamps[-1].reaction,
                               atol=1e-7)
