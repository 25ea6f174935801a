"""Overlay: the similarity recovered from matches on the synthetic photograph, and the model-unit
misfit against observations."""
import json

import matplotlib.image as mpimg
import numpy as np
import pytest

from knit_nlp.cli import main
from knit_nlp.weft.inverse.overlay import fit_similarity
from tests.conftest import PROBLEMS

EXAMPLE = PROBLEMS / "fit_example"


def test_least_squares_similarity_is_exact_on_exact_matches():
    rng = np.random.default_rng(1)
    model = rng.normal(size=(6, 2)) * 10
    a = 7.0 * np.exp(1j * 0.3)
    w = a * (model[:, 0] + 1j * model[:, 1]) + complex(40, -90)
    sim = fit_similarity(model, np.stack([w.real, -w.imag], axis=1))
    assert sim.scale == pytest.approx(7.0) and sim.rotation == pytest.approx(0.3)
    assert np.allclose(sim.to_pixels(model), np.stack([w.real, -w.imag], axis=1))


def test_transform_from_the_synthetic_photograph_is_exact(tmp_path, capsys):
    case = tmp_path / "fit_course_pull.toml"
    text = (EXAMPLE / "fit_course_pull.toml").read_text()
    case.write_text(text.replace("k_a = 1.5", "k_a = 1.0").replace("k_b = 0.02", "k_b = 0.01")
                    .replace("R_f = 0.7", "R_f = 1.0"))               # the photo's material
    assert main(["solve", str(case), "--out", str(tmp_path)]) == 0
    matches = [ln.split()[1] for ln in (EXAMPLE / "photo_matches.txt").read_text().splitlines()
               if ln.startswith("--match")]
    args = ["overlay", str(tmp_path / "fit_course_pull.full.json"), str(EXAMPLE / "photo.png"),
            "--problem", str(case), "--observations", str(EXAMPLE / "observations.csv"),
            "--out", str(tmp_path)]
    for m in matches:
        args += ["--match", m]
    assert main(args) == 0
    info = json.loads((tmp_path / "fit_course_pull.full.photo.overlay.json").read_text())
    t = info["transform"]
    assert t["scale_px_per_unit"] == pytest.approx(18.0, abs=1e-4)
    assert np.degrees(t["rotation_rad"]) == pytest.approx(8.0, abs=1e-4)
    assert np.allclose(t["shift_px"], [120.0, 560.0], atol=0.01)
    assert max(m["residual_px"] for m in info["matches"]) < 0.1
    # observations made with noise 0.02 per coordinate: RMS distance about 0.02·√2
    assert 0.01 < info["observed_rms_model_units"] < 0.05
    photo = mpimg.imread(EXAMPLE / "photo.png")
    drawn = mpimg.imread(tmp_path / "fit_course_pull.full.photo.overlay.png")
    # the photograph at its own resolution in the top rows (its corner, where nothing is
    # drawn, pixel for pixel), the key in a strip under it
    h, w = photo.shape[:2]
    assert drawn.shape[1] == w and drawn.shape[0] > h
    np.testing.assert_allclose(drawn[:40, :40, :3], photo[:40, :40, :3], atol=1 / 255)
    assert "residual" in capsys.readouterr().out
