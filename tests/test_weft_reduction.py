"""The interpolation reduction (eqs. 22-27): one model, two parametrisations."""
import numpy as np
import pytest

from knit_nlp.weft.model.basis import continuity_rows
from knit_nlp.weft.model.parametrisation import Full, Reduced
from knit_nlp.weft.model.problem import load_problem
from knit_nlp.weft.transcription.rows import n_parameters

from conftest import PROBLEMS, solve_text
from reference import dense_reduction_map

PULL = """
[fabric]
courses = {m}
wales = {n}
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [1, {n}]
point = "H"
displacement = [2.0, 3.0]
{reduction}
"""


def _pull(write_problem, m=4, n=5, courses=None, wales=None, name="p.toml"):
    red = ""
    if courses is not None:
        red = f"[reduction]\nrepresentative_courses = {courses}\nrepresentative_wales = {wales}\n"
    return write_problem(PULL.format(m=m, n=n, reduction=red), name)


def test_parameter_counts_as_the_paper_counts():
    pr = load_problem(PROBLEMS / "diagonal_pull.toml")
    assert n_parameters(pr, Full()) == 820
    assert n_parameters(pr, Reduced()) == 48


def test_map_is_linear_exact_and_continuous_by_construction(write_problem):
    pr = load_problem(_pull(write_problem, courses=[1, 3, 4], wales=[1, 2, 5]))
    T = dense_reduction_map(pr, pr.reduction or Reduced())
    assert T.shape == (4 * 5 * 8, 3 * 3 * 6 + 2 * 3)
    rng = np.random.default_rng(3)
    z1, z2 = rng.normal(size=T.shape[1]), rng.normal(size=T.shape[1])
    np.testing.assert_allclose(T @ (2.0 * z1 - 0.5 * z2), 2.0 * (T @ z1) - 0.5 * (T @ z2), atol=1e-12)
    a = (T @ z1).reshape(4, 5, 8)
    end, start = continuity_rows(pr.L, pr.t)
    for i in range(4):
        for j in range(4):
            np.testing.assert_allclose(end @ a[i, j], start @ a[i, j + 1], atol=1e-11)
    # representative loops carry their own parameters: the sub-loop part is z itself
    np.testing.assert_allclose(a[2, 1, :6], z1[(1 * 3 + 1) * 6:(1 * 3 + 2) * 6], atol=1e-14)


def test_corner_form_is_the_papers_bilinear_interpolation(write_problem):
    """Eq. (22): â_ij = (1−λ)(1−μ)â11 + (1−λ)μ â1n + λ(1−μ)âm1 + λμ âmn; eq. (23) for a_i1."""
    pr = load_problem(_pull(write_problem))
    T = dense_reduction_map(pr, pr.reduction or Reduced())
    z = np.random.default_rng(5).normal(size=T.shape[1])
    a = (T @ z).reshape(4, 5, 8)
    h = z[:24].reshape(2, 2, 6)
    for i in range(4):
        lam = i / 3
        np.testing.assert_allclose(a[i, 0, 6:], (1 - lam) * z[24:26] + lam * z[26:28], atol=1e-12)
        for j in range(5):
            mu = j / 4
            expect = ((1 - lam) * (1 - mu) * h[0, 0] + (1 - lam) * mu * h[0, 1]
                      + lam * (1 - mu) * h[1, 0] + lam * mu * h[1, 1])
            np.testing.assert_allclose(a[i, j, :6], expect, atol=1e-12)


def test_every_loop_representative_reproduces_the_full_model(write_problem):
    full = solve_text(_pull(write_problem))
    red = solve_text(_pull(write_problem, courses=[1, 2, 3, 4], wales=[1, 2, 3, 4, 5], name="r.toml"),
                     reduced=True)
    assert full.success and red.success
    assert red.nlp.n_parameters == full.nlp.n_parameters - 2 * 4 * (5 - 1)
    np.testing.assert_allclose(red.coefficients,
                               full.coefficients, atol=1e-6)
    assert red.energy.total == pytest.approx(full.energy.total, rel=1e-8)


@pytest.mark.parametrize("grid", [None, ([1, 4], [1, 3, 5]), ([1, 2, 4], [1, 5])])
def test_reduced_energy_is_never_below_full(write_problem, grid):
    full = solve_text(_pull(write_problem))
    courses, wales = grid or (None, None)
    red = solve_text(_pull(write_problem, courses=courses, wales=wales, name="r.toml"), reduced=True)
    assert full.success and red.success
    assert red.energy.total >= full.energy.total - 1e-9


def test_compare_writes_counts_energies_distances_and_warm_start(write_problem, tmp_path, capsys,
                                                                saved_figures):
    import json
    from knit_nlp.cli import main
    from imagecheck import check_overlay_picture
    path = _pull(write_problem, name="cmp.toml")
    assert main(["compare", str(path), "--out", str(tmp_path), "--warm"]) == 0
    r = json.loads((tmp_path / "cmp.compare.json").read_text())
    full, red, warm = (r["models"][k] for k in ("full", "reduced", "full_warm_from_reduced"))
    assert full["n_parameters"] == 4 * 5 * 8 + 8 and red["n_parameters"] == 4 * 6 + 4 + 8
    assert red["energy"]["total"] >= full["energy"]["total"] - 1e-9
    assert r["distance"]["max"] >= r["distance"]["rms"] > 0
    assert warm["success"] and warm["iterations"] >= 0
    assert "centreline distance" in capsys.readouterr().out
    for flag in ("--full", "--reduced"):      # the same two solutions, as result files
        assert main(["solve", str(path), flag, "--out", str(tmp_path / "solve")]) == 0
    check_overlay_picture(tmp_path / "cmp.compare.png",
                          json.loads((tmp_path / "solve" / "cmp.full.json").read_text()),
                          json.loads((tmp_path / "solve" / "cmp.reduced.json").read_text()),
                          10.0, saved_figures)


def test_solve_reduced_by_default_when_the_file_has_a_reduction(write_problem, tmp_path):
    import json
    from knit_nlp.cli import main
    path = _pull(write_problem, courses=[1, 4], wales=[1, 5], name="red.toml")
    assert main(["solve", str(path), "--out", str(tmp_path)]) == 0
    assert json.loads((tmp_path / "red.reduced.json").read_text())["model"] == "reduced"
    assert main(["solve", str(path), "--full", "--out", str(tmp_path)]) == 0
    assert json.loads((tmp_path / "red.full.json").read_text())["n_parameters"] == 168
    assert main(["solve", str(path), "--full", "--warm-from-reduced", "--out", str(tmp_path)]) == 0
    assert "warm_start" in json.loads((tmp_path / "red.full.json").read_text())


def test_warm_from_reduced_reaches_the_cold_start_minimum():
    """``warm_from_reduced`` (``--warm-from-reduced``) on diagonal_pull: the full model started
    from the lifted reduced solution ends at the cold-start minimum (same energy, same loops).
    The start is really the reduced solution (lifting is exact: feasible, and the full energy
    there equals the reduced one), which is far from the minimum (the reduced energy is 1.8 ×
    higher), and it is closer than the natural state (fewer iterations)."""
    from knit_nlp.weft.api import solve
    from knit_nlp.weft.model.parametrisation import Full, Reduced
    from knit_nlp.weft.solving.solve import WeftSolver
    pr = load_problem(PROBLEMS / "diagonal_pull.toml")
    cold = solve(pr, Full())
    warm = solve(pr, Full(), warm_from_reduced=True)
    red = solve(pr, pr.reduction or Reduced())          # the reduced solve warm_from_reduced ran
    assert cold.success and red.success and warm.success
    assert warm.warm_start.reduced_iterations == red.iterations
    x0 = warm.nlp.lift(red.coefficients, red.starts)
    lifted = sum(float(v) for v in warm.nlp.energy(x0, warm.nlp.p0)[:2])
    assert lifted == pytest.approx(red.energy.total, rel=1e-9)
    assert WeftSolver(warm.nlp).violation(x0, warm.nlp.p0) < 1e-8     # and feasible
    assert red.energy.total > 1.5 * cold.energy.total
    assert warm.energy.total == pytest.approx(cold.energy.total, rel=1e-8)
    np.testing.assert_allclose(warm.centrelines(), cold.centrelines(), atol=1e-5)
    assert warm.to_json()["warm_start"]["from"] == "reduced"
    assert warm.iterations < cold.iterations
