"""Overlay: the similarity recovered from matches on the synthetic photograph, and the model-unit
misfit against observations."""
import json

import matplotlib.image as mpimg
import matplotlib.pyplot as plt
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

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


# -- matches that fix no similarity are refused in one line (issue 41 item 8) ----------------------
@pytest.fixture(scope="module")
def tiny_result(tmp_path_factory):
    """A solved 2 x 3 result, loaded, and the point reader of its problem."""
    from test_command_contract import tiny
    from knit_nlp.weft.inverse.overlay import load_result, point_reader
    folder = tmp_path_factory.mktemp("tiny")
    problem = tiny(folder)
    assert main(["solve", str(problem), "--out", str(folder)]) == 0
    return load_result(folder / "obs.full.json"), point_reader(problem)[0], problem, folder


POINTS = ["1,1,start", "2,3,H", "1,2,E", "2,1,3.5"]
PIXEL = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6),
                  st.sampled_from([120.0, 120.3, 1e308, -1e308]))
NEAR = st.sampled_from([(120.0, 560.0), (120.3, 560.2), (80.0, 300.0)])   # pixels often close


@given(st.lists(st.tuples(st.sampled_from(POINTS), st.one_of(st.tuples(PIXEL, PIXEL), NEAR)),
                min_size=2, max_size=5))
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_any_matches_give_a_finite_scale_or_one_line_refusal(tiny_result, matches):
    """Whatever the match strings, overlay either refuses them in one line naming --match or
    returns a finite similarity that maps the matched material points at least a pixel apart
    (scale x their spread >= 1 px) with finite residuals. Red before: NaN and infinite pixels
    gave "scale nan px/unit"; two matches on one pixel a scale of 1e-15 px/unit."""
    from knit_nlp.errors import ProblemError
    from knit_nlp.weft.inverse.overlay import overlay, parse_match
    shape, reader, _, _ = tiny_result
    try:
        parsed = [parse_match(f"{p}={x!r},{y!r}", reader) for p, (x, y) in matches]
        ans = overlay(shape, parsed)
    except ProblemError as err:
        assert str(err).startswith("--match") and "\n" not in str(err), str(err)
        return
    t = ans.transform
    assert np.isfinite([t.a, t.b]).all() and np.isfinite(ans.residuals_px).all()
    spread = max(np.linalg.norm(p - q) for p in ans.model_points for q in ans.model_points)
    assert t.scale * spread >= 1.0


@pytest.mark.parametrize("second, needle", [("2,3,H=nan,560", "finite"), ("2,3,H=inf,3", "finite"),
                                            ("2,3,H=120,560", "1 px")])
def test_overlay_refuses_pixels_that_fix_no_scale(tiny_result, tmp_path, capsys, second, needle):
    """The command: exit 2, one line naming the match, nothing written."""
    _, _, problem, folder = tiny_result
    plt.imsave(tmp_path / "img.png", np.zeros((20, 30, 3)))
    out = tmp_path / "out"
    assert main(["overlay", str(folder / "obs.full.json"), str(tmp_path / "img.png"), "--problem",
                 str(problem), "--match", "1,1,start=120,560", "--match", second,
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("knit-nlp: --match") and err.count("\n") == 1 and needle in err, err
    assert not out.exists()


def test_an_overlay_answer_takes_the_contract_and_saves_the_commands_files(tiny_result, tmp_path,
                                                                          capsys):
    """``knit-nlp overlay``'s files are ``OverlayAnswer.save``'s: the same JSON and PNG bytes
    under the same names; ``to_json()`` is the JSON; ``success``/``status``/``message`` say the
    similarity was fitted (refused matches raise before an answer exists). Without the
    photograph, ``save`` refuses in one line naming the argument."""
    from knit_nlp.weft.inverse.overlay import FITTED, overlay, parse_match
    from knit_nlp.weft.inverse.run import read_image
    shape, reader, problem, folder = tiny_result
    result, image = folder / "obs.full.json", tmp_path / "img.png"
    plt.imsave(image, np.zeros((20, 30, 3)))
    texts = ["1,1,start=2,3", "2,3,H=25,12", "1,2,E=14,6"]
    ans = overlay(shape, [parse_match(m, reader) for m in texts], result_path=result,
                  image=image, picture=read_image(image))
    assert ans.success and ans.status == FITTED
    assert ans.message.startswith("similarity fitted to 3 matches: scale ")
    assert f"largest match residual {max(ans.residuals_px):.3g} px" in ans.message
    mine = ans.save(tmp_path / "api")
    assert [p.name for p in mine] == ["obs.full.img.overlay.json", "obs.full.img.overlay.png"]
    written = json.loads(mine[0].read_text())
    assert written == json.loads(json.dumps(ans.to_json()))
    assert [m["residual_px"] for m in written["matches"]] == ans.residuals_px.tolist()
    assert written["transform"]["scale_px_per_unit"] == ans.transform.scale
    assert (written["result"], written["image"]) == (str(result), str(image))
    argv = ["overlay", str(result), str(image), "--problem", str(problem), "--out",
            str(tmp_path / "cmd")]
    assert main(argv + [a for m in texts for a in ("--match", m)]) == 0
    assert str(mine[0].relative_to(tmp_path / "api")) in capsys.readouterr().out
    for path in mine:
        assert (tmp_path / "cmd" / path.name).read_bytes() == path.read_bytes()
    bare = overlay(shape, [parse_match(m, reader) for m in texts])
    with pytest.raises(ValueError, match="^result_path, image: "):
        bare.save(tmp_path / "bare")
    assert bare.to_json()["result"] is None and not (tmp_path / "bare").exists()
