"""A 3-D problem through the front door: knit_nlp.solve, the result JSON's spatial block, the
3-D NPZ arrays, and the reduced model and compare refused."""
from __future__ import annotations

import json

import numpy as np
import pytest

import knit_nlp
from knit_nlp.weft.api import compare
from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.model.parametrisation import Reduced
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.transcription.factory import transcribe
from knit_nlp.weft.transcription.full import FullNLP
from knit_nlp.weft.transcription.spatial import PlanarOnly
from problem_texts import pull3d

DOC = pull3d("small3d", L=11.28, R_f=0.045, radius=0.74, lift=0.8)


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    pr = parse_problem(DOC, "small3d.toml")
    result = knit_nlp.solve(pr)
    out = tmp_path_factory.mktemp("out3d")
    result.save(out)
    return pr, result, out


def test_solve_reports_crossings_and_writes_3d_arrays(solved) -> None:
    pr, result, out = solved
    assert result.success and result.model == "full3d"
    doc = json.loads((out / "small3d.full3d.json").read_text())
    sp = doc["spatial"]
    assert len(sp["crossings"]) == 4 and sp["flipped"] == 0
    h = np.array([c["separation"] for c in sp["crossings"]])
    assert sp["smallest_separation"] == pytest.approx(h.min())
    assert 2 * pr.yarn.core_radius < h.min() < 2 * pr.yarn.radius        # pressed, not through
    pressed = [c for c in sp["crossings"] if c["compression"] < 0]
    assert pressed and all(c["force"] > 0 for c in pressed)
    assert sum(c["force"] == 0.0 for c in sp["crossings"]) == len(sp["crossings"]) - len(pressed)
    arrays = np.load(out / "small3d.full3d.npz")
    assert arrays["natural"].shape[-1] == 3 and arrays["deformed"].shape == arrays["natural"].shape
    assert np.ptp(arrays["deformed"][..., 2]) > pr.yarn.radius             # out of the plane
    # x, y forces balance: contacts are internal, z rows carry no x, y force
    total = sum(np.array(c["reaction"]) for c in doc["clamps"])
    np.testing.assert_allclose(total, 0.0, atol=1e-9)


def test_the_reduced_model_and_compare_are_refused() -> None:
    pr = parse_problem(DOC, "small3d.toml")
    with pytest.raises(PlanarOnly, match="reduced model is planar"):
        knit_nlp.weft.solve(pr, Reduced())
    with pytest.raises(PlanarOnly, match="reduced model is planar"):
        compare(pr)


def test_planar_yarn_is_todays_model() -> None:
    """[yarn] radius without geometry: the paper's full NLP (its contact solver on top)."""
    doc = diagonal_pull(3)
    doc["yarn"] = {"radius": 0.15}
    assert isinstance(transcribe(parse_problem(doc, "planar.toml")), FullNLP)


def test_the_check_and_the_3d_files_speak_of_the_3d_answer(solved) -> None:
    """The result's check is the independent 3-D one over all pairs of yarn pieces (the planar
    projection's crossings do not apply), the marked contact points lie where the
    two yarns touch (r from each centreline at a touching crossing: red with a tangent taken
    for a point), and the .3d.png, .yarn.vtu and .tube.ply are written."""
    import meshio

    pr, result, out = solved
    doc = json.loads((out / "small3d.full3d.json").read_text())
    assert doc["check"]["model"] == "3d" and doc["check"]["flipped"] == 0
    assert doc["check"]["smallest_distance"] is not None      # tests/test_weft3d_check.py
    nlp, x = result.nlp, result.x
    touch = nlp.contact_points(x)
    lines = nlp.centrelines3d(x, 4001)                        # dense: nearest point to ~1e-3 r
    h = np.array([c["separation"] for c in doc["spatial"]["crossings"]])
    for k, c in enumerate(doc["spatial"]["crossings"]):
        (iu, ju), (il, jl) = c["upper"], c["lower"]
        for i, j in ((iu, ju), (il, jl)):
            d = np.linalg.norm(lines[i - 1, j - 1] - touch[k], axis=1).min()
            assert d == pytest.approx(h[k] / 2, rel=2e-3, abs=2e-3 * pr.yarn.radius)
    for suffix in (".3d.png", ".yarn.vtu", ".tube.ply"):
        assert (out / f"small3d.full3d{suffix}").stat().st_size > 0
    mesh = meshio.read(out / "small3d.full3d.yarn.vtu")
    np.testing.assert_allclose(mesh.point_data["radius"], pr.yarn.radius)


