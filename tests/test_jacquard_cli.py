"""The jacquard problem form through ``knit-nlp solve``: outputs, exit codes, validation."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from knit_nlp.cli import main

from imagecheck import check_jacquard_picture

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"

GOOD = """\
name = "tiny"
model = "jacquard"
[fabric]
wales = 4
courses = 4
dz = 10.0
dh = 8.0
[fall_plate]
design = \"\"\"
##++
##++
++##
++##
\"\"\"
[inlay]
design_file = "tiny_inlay.txt"
"""
INLAY = "+#.+\n#+.#\n+#.+\n#+.#\n"


def _write(tmp_path: Path, text: str, inlay: str = INLAY) -> Path:
    (tmp_path / "tiny_inlay.txt").write_text(inlay)
    path = tmp_path / "tiny.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("solver", ["static", "explicit"])
def test_solve_writes_json_and_png(tmp_path, capsys, solver, saved_figures):
    path = _write(tmp_path, GOOD)
    out = tmp_path / "out"
    assert main(["solve", str(path), "--out", str(out), "--solver", solver, "--svg"]) == 0
    data = json.loads((out / "tiny.jacquard.json").read_text())
    assert data["success"] is True and data["solver"] == solver
    for key in ("residual_force", "steps", "timings", "particles", "skew", "zero_modes"):
        assert key in data
    nat, fin = np.array(data["particles"]["natural"]), np.array(data["particles"]["final"])
    assert nat.shape == fin.shape == (16, 2)
    assert np.allclose(nat[2 * 4 + 3], [3 * 1.25, 2 * 1.0])        # index j*M + i
    assert np.max(np.abs(fin - nat)) > 1e-3                          # it deformed
    assert len(data["skew"]["mean_angle_deg"]) == 4
    assert (data["steps"] is None) == (solver == "static")
    assert data["residual_force"] < 1e-5
    check_jacquard_picture(out / "tiny.jacquard.png", data, saved_figures)
    assert (out / "tiny.jacquard.svg").exists()
    assert "tiny" in capsys.readouterr().out


def test_step_limit_exits_1_and_marks_failure(tmp_path):
    path = _write(tmp_path, GOOD + "[solver]\nmethod = \"explicit\"\nmax_steps = 5\n")
    out = tmp_path / "out"
    assert main(["solve", str(path), "--out", str(out)]) == 1
    data = json.loads((out / "tiny.jacquard.json").read_text())
    assert data["success"] is False and data["steps"] == 5


@pytest.mark.parametrize("edit, inlay, words", [
    (("##++\n##++\n++##\n++##", "##++\n##++\n++##"), INLAY, "3 courses"),          # wrong size
    (("##++\n##++\n++##\n++##", "##++\n##+++\n++##\n++##"), INLAY, "line 2"),      # ragged
    (("##++\n##++\n++##\n++##", "##++\n#x++\n++##\n++##"), INLAY, "'x'"),          # symbol
    (None, "+#.+\n#+.#\n+#.+\n", "3 courses"),                                     # file size
    (("dz = 10.0", "dz = 0.0"), INLAY, "dz"),
    (("dh = 8.0", "dh = -8.0"), INLAY, "dh"),
    (("[inlay]", "[ground]\npretension = 1.5\n[inlay]"), INLAY, "pretension"),
    (("[inlay]", "[ground]\npretension = 0.0\n[inlay]"), INLAY, "(0, 1]"),
    (("[inlay]", "[fall_plate.pretension]\nthick = 0\n[inlay]"), INLAY, "(0, 1]"),
    (("dh = 8.0", "dh = 8.0\ncolour = 3"), INLAY, "unknown key"),
    (("dh = 8.0", "dh = 8.0\nboundary = \"fixed\"\nfixed_edges = [\"left\"]"), INLAY, "top"),
    (("courses = 4", "courses = 5"), INLAY, "even"),
    (("dh = 8.0", "dh = 8.0\nlambda_max = 0.9"), INLAY, "lambda_max"),
])
def test_bad_problem_exits_2_with_one_line(tmp_path, capsys, edit, inlay, words):
    text = GOOD if edit is None else GOOD.replace(*edit, 1)
    assert text != GOOD or edit is None
    path = _write(tmp_path, text, inlay)
    assert main(["solve", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "tiny.toml" in err and words in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", sorted(p.stem for p in PROBLEMS.glob("jacquard_*.toml")
                                        if "bench" not in p.stem))
def test_shipped_problems_solve(tmp_path, name):
    assert main(["solve", name, "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / f"{name}.jacquard.json").read_text())
    assert data["max_stretch"] <= data["lambda_max"] * (1 + 1e-7)
    assert data["min_order_gap"] >= -1e-8
