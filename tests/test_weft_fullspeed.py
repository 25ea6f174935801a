"""Issue 14 (full model on large fabrics): closed-form derivatives and the rigid-fit start."""
import casadi as ca
import numpy as np
import pytest

from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.model.problem import load_problem, parse_problem
from knit_nlp.weft.solving import solve as solving, starts as start
from knit_nlp.weft.solving.solve import WeftSolver, solve_nlp
from knit_nlp.weft.solving.starts import rigid_start
from knit_nlp.weft.transcription.derivatives import closed_form_derivatives
from knit_nlp.weft.transcription.factory import transcribe

from knit_nlp.weft.model.cases import course_pull, diagonal_pull

from conftest import ROOT

# every kind of constraint and energy term: point clamps (one at a crossing point, one partial),
# an angle clamp, a rigid clamp, a point load with a moment
ALL_TERMS = """
[fabric]
courses = 3
wales = 4
[[clamp]]
loop = [1, 1]
point = "start"
displacement = [0.0, 0.0]
[[clamp]]
loop = [2, 3]
point = "B"
displacement = [1.0, -0.5]
[[clamp]]
loop = [3, 4]
point = "H"
displacement = [2.0, 0.0]
fix = ["x"]
angle = 0.3
[[rigid_clamp]]
points = [{loop = [1, 4], point = "end"}, {loop = [2, 4], point = "end"}]
translation = [1.5, 0.5]
rotation = 0.2
[[load]]
loop = [3, 2]
point = 4.0
force = [0.1, 0.2]
moment = 0.05
"""


@pytest.fixture(scope="module")
def all_terms(tmp_path_factory):
    path = tmp_path_factory.mktemp("p") / "all.toml"
    path.write_text(ALL_TERMS)
    return transcribe(load_problem(path))


def _random_point(wnlp, seed=0):
    rng = np.random.default_rng(seed)
    x = wnlp.x0 + 0.3 * rng.standard_normal(wnlp.n_variables)
    lam = rng.standard_normal(wnlp.n_constraints)
    return x, lam


def test_closed_form_derivatives_equal_casadi_ad(all_terms):
    wnlp = all_terms
    ad = WeftSolver(transcribe(wnlp.problem, Full(), derivatives="casadi")).solver
    ours = closed_form_derivatives(wnlp)
    x, lam = _random_point(wnlp)
    g_ad, J_ad = ad.get_function("nlp_jac_g")(x, wnlp.p0)
    g, J = ours["jac_g"](x, wnlp.p0)
    assert float(ca.norm_inf(g - g_ad)) < 1e-13
    assert float(ca.norm_inf(J - J_ad)) < 1e-12 * max(1.0, float(ca.norm_inf(J_ad)))
    H_ad = ad.get_function("nlp_hess_l")(x, wnlp.p0, 0.7, lam)
    H = ours["hess_lag"](x, wnlp.p0, 0.7, lam)
    assert H.sparsity().is_triu()
    assert float(ca.norm_inf(H - H_ad)) < 1e-12 * float(ca.norm_inf(H_ad))


def test_closed_form_derivatives_match_finite_differences(all_terms):
    """Independent of CasADi's AD: J against central differences of g, and the Hessian of the
    Lagrangian against central differences of the closed-form gradient ∇f + Jᵀλ."""
    wnlp = all_terms
    ours = closed_form_derivatives(wnlp)
    grad_f = ca.Function("gf", [wnlp.nlp["x"], wnlp.nlp["p"]],
                         [ca.gradient(wnlp.nlp["f"], wnlp.nlp["x"])])
    x, lam = _random_point(wnlp, 1)
    p, sigma, eps = wnlp.p0, 0.7, 1e-6
    J = ours["jac_g"](x, p)[1]
    H = ours["hess_lag"](x, p, sigma, lam)
    H = np.asarray(ca.DM(H + ca.triu(H, False).T))                 # symmetric from the triangle

    def grad_lag(xx):
        return sigma * np.asarray(grad_f(xx, p)).ravel() + np.asarray(
            ca.mtimes(ours["jac_g"](xx, p)[1].T, lam)).ravel()

    rng = np.random.default_rng(2)
    for _ in range(3):
        d = rng.standard_normal(x.size)
        dg = (np.asarray(ours["jac_g"](x + eps * d, p)[0]) - np.asarray(ours["jac_g"](x - eps * d, p)[0])).ravel() / (2 * eps)
        assert np.max(np.abs(dg - np.asarray(ca.mtimes(J, d)).ravel())) < 1e-6
        dl = (grad_lag(x + eps * d) - grad_lag(x - eps * d)) / (2 * eps)
        assert np.max(np.abs(dl - H @ d)) < 1e-5 * max(1.0, np.max(np.abs(H @ d)))


def test_closed_form_and_ad_solves_take_the_same_path():
    pr = load_problem(ROOT / "problems" / "diagonal_pull.toml")
    wnlp = transcribe(pr, Full(), derivatives="casadi")
    assert "hess_lag" not in wnlp.nlpsol_options          # CasADi's AD, the reference
    a = WeftSolver(wnlp).once(wnlp.p0, wnlp.x0)
    b = WeftSolver(transcribe(pr, Full())).once(wnlp.p0, wnlp.x0)
    assert a.success and b.success and a.iterations == b.iterations
    assert abs(a.objective - b.objective) < 1e-10 * a.objective
    assert np.max(np.abs(a.x - b.x)) < 1e-8


def test_rigid_start_is_consistent_and_exact_for_a_rigid_motion(all_terms):
    """Chaining, continuity and every lifted constraint hold exactly at the start; when the
    clamp targets are a rigid motion of the natural positions the clamps hold too."""
    wnlp = all_terms
    pr, gl = wnlp.problem, wnlp.g
    g = ca.Function("g", [wnlp.nlp["x"], wnlp.nlp["p"]], [wnlp.nlp["g"]])
    x0 = rigid_start(wnlp, wnlp.p0)
    res = np.asarray(g(x0, wnlp.p0)).ravel()
    for name in gl.blocks:          # to the NLP quadrature's error, as at the natural start
        if not name.startswith(("clamp", "rigid")):
            assert np.max(np.abs(res[gl.slice(name)])) < 1e-8, name
    # targets of the two fully clamped points and the rigid clamp, all by one rigid motion
    phi, b = 0.4, np.array([3.0, -2.0])
    R = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
    rc = pr.rigid_clamps[0]
    p = wnlp.params.with_(
        targets={q + 1: R @ pr.natural_position(c.loop, c.s) + b for q, c in enumerate(pr.clamps)},
        rigid={1: [*(R @ rc.centre + b - rc.centre), phi]}).vector()
    res = np.asarray(g(rigid_start(wnlp, p), p)).ravel()
    for q, c in enumerate(pr.clamps):
        assert np.max(np.abs(res[gl.slice(f"clamp{q}_pos")])) < 1e-8
    assert np.max(np.abs(res[gl.slice("rigid0")])) < 1e-8
    # it halves (at least) the clamp violation of the natural start on the diagonal pull
    diag = transcribe(parse_problem(diagonal_pull(10), "d"))
    gd = ca.Function("g", [diag.nlp["x"], diag.nlp["p"]], [diag.nlp["g"]])
    v_nat = np.max(np.abs(np.asarray(gd(diag.x0, diag.p0))))
    v_rig = np.max(np.abs(np.asarray(gd(rigid_start(diag, diag.p0), diag.p0))))
    assert v_rig < 0.5 * v_nat


@pytest.mark.parametrize("n", [10, 20])
@pytest.mark.parametrize("doc", [diagonal_pull, course_pull], ids=["diagonal", "course"])
def test_rigid_and_natural_starts_reach_the_same_minimum(n, doc):
    wnlp = transcribe(parse_problem(doc(n), "p"))
    solver = WeftSolver(wnlp)
    nat = solve_nlp(wnlp, solver, start="natural")
    rig = solve_nlp(wnlp, solver, start="rigid")
    assert nat.success and rig.success
    assert abs(nat.objective - rig.objective) < 1e-9 * nat.objective
    assert np.max(np.abs(wnlp.coefficients(nat.x) - wnlp.coefficients(rig.x))) < 1e-6
    assert np.max(np.abs(wnlp.starts(nat.x) - wnlp.starts(rig.x))) < 1e-6


@pytest.mark.parametrize("n", [10, 20])
@pytest.mark.parametrize("doc", [diagonal_pull, course_pull], ids=["diagonal", "course"])
def test_multilevel_and_natural_starts_reach_the_same_minimum(n, doc, monkeypatch):
    """Two levels at each size (10 -> 5, 20 -> 10 -> 5), prolonged whatever the probe says;
    the start violates the constraints at most a fifth as much as the natural one."""
    monkeypatch.setattr(start, "COARSEST", 5)
    monkeypatch.setattr(solving, "EASY_ITERATIONS", 0)
    wnlp = transcribe(parse_problem(doc(n), "p"))
    solver = WeftSolver(wnlp)
    nat = solve_nlp(wnlp, solver, start="natural")
    ml = solve_nlp(wnlp, solver, start="multilevel")
    assert nat.success and ml.success
    assert [a.split(":")[0] for a in ml.attempts[:-1]] == (
        ["multilevel 5x5"] if n == 10 else ["multilevel 5x5", "multilevel 10x10"])
    assert abs(nat.objective - ml.objective) < 1e-9 * nat.objective
    assert np.max(np.abs(wnlp.coefficients(nat.x) - wnlp.coefficients(ml.x))) < 1e-6
    assert np.max(np.abs(wnlp.starts(nat.x) - wnlp.starts(ml.x))) < 1e-6
    x0 = solving.start_point(wnlp, wnlp.p0, "multilevel")
    assert solver.violation(x0, wnlp.p0) < 0.2 * solver.violation(wnlp.x0, wnlp.p0)


def test_probe_keeps_the_natural_start_for_the_course_pull_only():
    """20 x 20: the 10 x 10 probe takes 5 iterations on the course pull (natural start kept, no
    more coarse solves) and more than EASY_ITERATIONS on the diagonal pull (prolonged)."""
    for doc, prolonged in ((course_pull, False), (diagonal_pull, True)):
        wnlp = transcribe(parse_problem(doc(20), "p"))
        log = []
        x0 = solving.start_point(wnlp, wnlp.p0, "multilevel", log)
        assert len(log) == 1 and log[0].startswith("multilevel 10x10: Solve_Succeeded")
        assert (x0 is not wnlp.x0) == prolonged


def test_prolonged_coarse_natural_state_is_the_fine_natural_state():
    """Unpulled (targets at their natural positions) the coarse problem's solution is the
    natural state, and its prolongation is the fine natural state with every constraint held."""
    wnlp = transcribe(parse_problem(diagonal_pull(9), "p"))
    p = WeftParams.natural(wnlp.problem)
    cp = start.coarse_problem(wnlp.problem, p, 5, 5)
    assert [c.loop for c in cp.clamps] == [(1, 1), (1, 5)]
    for c in cp.clamps:            # at their natural positions on the coarse fabric
        assert np.allclose(c.target, cp.natural_position(c.loop, c.s), atol=1e-12)
    coarse = transcribe(cp)
    x = start.prolong(coarse, coarse.x0, wnlp)
    assert np.allclose(wnlp.starts(x), wnlp.problem.natural_starts(), atol=1e-8)
    assert WeftSolver(wnlp).violation(x, p.vector()) < 1e-8


def test_coarse_problem_scales_the_pull_and_merges_points():
    """The course pull: 20 left and 20 right edge clamps become 10 + 10 with the displacement
    halved in proportion (r = 9/19), and the corner keeps both coordinates."""
    pr = parse_problem(course_pull(20), "p")
    cp = start.coarse_problem(pr, WeftParams.of(pr), 10, 10)
    assert len(cp.clamps) == 20 and cp.clamps[0].fix == (True, True)
    right = [c for c in cp.clamps if c.loop[1] == 10]
    d = [c.target[0] - cp.natural_position(c.loop, c.s)[0] for c in right]
    assert np.allclose(d, 0.25 * 20 * pr.natural.wale_spacing * 9 / 19)


def test_prolonged_rigid_turn_is_the_same_rigid_turn():
    """Displacements scale with the fabric: the coarse natural fabric turned about the origin
    prolongs to exactly the fine natural fabric turned by the same angle."""
    def turned(wnlp, phi):
        pr = wnlp.problem
        R = np.array([[np.cos(phi), -np.sin(phi)], [np.sin(phi), np.cos(phi)]])
        coeffs = np.broadcast_to(pr.natural.coeffs, (pr.courses, pr.wales, 8)).copy()
        coeffs[..., -1] += phi
        return wnlp.lift(coeffs, pr.natural_starts() @ R.T)

    fine = transcribe(parse_problem(diagonal_pull(9), "p"))
    coarse = transcribe(parse_problem(diagonal_pull(5), "p"))
    x = start.prolong(coarse, turned(coarse, 0.4), fine)
    want = turned(fine, 0.4)
    assert np.max(np.abs(fine.coefficients(x) - fine.coefficients(want))) < 1e-12
    assert np.max(np.abs(fine.starts(x) - fine.starts(want))) < 1e-9


def test_prolonged_start_is_near_the_fine_solution_in_energy():
    """The 24 x 24 diagonal pull prolonged from its 12 x 12 solution starts at 1.38 times the
    fine solution's energy (measured); with the loop starts chained along each course through
    the interpolated shapes the per-loop errors added up to 3.8 times (and 200 times at 200 x
    200, where IPOPT then crawled)."""
    fine = transcribe(parse_problem(diagonal_pull(24), "p"))
    cp = start.coarse_chain(fine.problem, WeftParams.of(fine.problem))[0]
    coarse = transcribe(cp)
    xc = solve_nlp(coarse, WeftSolver(coarse)).x
    xf = solve_nlp(fine, WeftSolver(fine)).x
    energy = ca.Function("E", [fine.nlp["x"], fine.nlp["p"]], [fine.nlp["f"]])
    ratio = float(energy(start.prolong(coarse, xc, fine), fine.p0) / energy(xf, fine.p0))
    assert 1.0 < ratio < 2.0


def test_prolonged_multipliers_approximate_the_fine_ones_and_save_iterations():
    """A 16 x 24 diagonal pull from its 8 x 12 coarse problem: the prolonged multipliers lie
    within 40 % (yarn and spring forces; measured 25-38 %), 70 % (continuity moments; 62 %)
    and 15 % (clamp reactions, scaled by 1/r: forces over a cross-section grow with a 2-D
    fabric; 8 %) of the fine solution's, where zeros are 100 % off;
    started from them the fine solve reaches the same minimum in fewer iterations than from
    IPOPT's least-squares estimate. (Unscaled clamp rows are 49 % off, loop rows reshaped
    along the wrong axis 94 %.)"""
    fine = transcribe(parse_problem(diagonal_pull(24, 16), "p"))
    coarse = transcribe(start.coarse_problem(fine.problem, fine.params, 8, 12))
    rc = solve_nlp(coarse, WeftSolver(coarse), start="natural")
    x0 = start.prolong(coarse, rc.x, fine)
    cold = WeftSolver(fine).once(fine.p0, x0)
    lam = start.prolong_multipliers(coarse, rc.lam_g, fine)
    assert rc.success and cold.success
    for name in fine.g.blocks:
        rows = fine.g.slice(name)
        rel = np.linalg.norm(lam[rows] - cold.lam_g[rows]) / np.linalg.norm(cold.lam_g[rows])
        bound = (0.15 if name.startswith(("clamp", "lift_special")) else
                 0.7 if name == "continuity" else 0.4)
        assert rel < bound, name
    warm = WeftSolver(fine, ipopt=solving.WARM).once(fine.p0, x0, lam_g0=lam)
    assert warm.success and warm.iterations < cold.iterations
    assert abs(warm.objective - cold.objective) < 1e-9 * cold.objective
    assert np.max(np.abs(fine.coefficients(warm.x) - fine.coefficients(cold.x))) < 1e-6


def test_ipopt_options_of_the_full_model_do_not_change_its_path():
    """``first_hessian_perturbation = 1`` (``solve.MODEL_IPOPT``) reaches the regularisation
    IPOPT's default trials reach (1e-4, 1e-2, 1) directly: the same iterates, fewer
    factorisations (the 20 x 20 diagonal pull from its multilevel start)."""
    wnlp = transcribe(parse_problem(diagonal_pull(20), "p"))
    x0 = solving.start_point(wnlp, wnlp.p0, "multilevel")
    assert solving.MODEL_IPOPT["full"] == {"first_hessian_perturbation": 1.0}
    default = WeftSolver(wnlp, ipopt={"first_hessian_perturbation": 1e-4}).once(wnlp.p0, x0)
    ours = WeftSolver(wnlp).once(wnlp.p0, x0)
    assert default.success and ours.success and default.iterations == ours.iterations
    assert abs(default.objective - ours.objective) < 1e-12 * default.objective
    assert np.max(np.abs(default.x - ours.x)) < 1e-9
