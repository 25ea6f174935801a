"""The condensed reduced model: its hand-assembled derivatives, and agreement with the lifted
reduced model (a reference copy, tests/reference.py) and (every loop representative) the full
model."""
import casadi as ca
import numpy as np
import pytest

from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.transcription.condensed.nlp import build_condensed
from knit_nlp.weft.model.kinematics import LoopIntegrals, loop_displacements
from knit_nlp.weft.model.parametrisation import Full, Reduced
from knit_nlp.weft.transcription.factory import transcribe
from knit_nlp.weft.model.problem import load_problem, parse_problem
from knit_nlp.weft.solving.solve import WeftSolver, solve_nlp

from reference import lifted_reduced_solve

# every kind of term: point clamps (one fixing x only), an angle clamp, a rigid clamp, a load
# with force and moment
MIXED = """
[fabric]
courses = 4
wales = 5
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
angle = 0.1
[[clamp]]
loop = [1, 5]
point = "H"
displacement = [2.0, 3.0]
[[clamp]]
loop = [3, 5]
point = "end"
displacement = [1.0, 0.0]
fix = ["x"]
[[rigid_clamp]]
points = [{loop = [4, 1], point = "start"}, {loop = [4, 2], point = "start"}]
translation = [0.5, -0.3]
rotation = 0.05
[[load]]
loop = [2, 3]
point = "E"
force = [0.2, -0.1]
moment = 0.05
[reduction]
representative_courses = [1, 3, 4]
representative_wales = [1, 2, 5]
"""


@pytest.fixture(params=[1, 2, None], ids=["segment1", "segment2", "single-shooting"])
def mixed(write_problem, request):
    """The mixed problem in shooting segments of 1 and 2 loops (5 and 3 per course, chained
    by constraints) and in one segment per course (the default's form on 5 wales)."""
    pr = load_problem(write_problem(MIXED))
    return build_condensed(pr, pr.reduction, segment=request.param)


def _point(c, seed=0, scale=0.05):
    w = c.w(c.x0)
    return w + scale * np.random.default_rng(seed).normal(size=w.size)


def test_loop_integrals_closed_forms_equal_casadi_ad():
    pts = np.array([10.0, 1.420998, 8.579002, 3.579002, 6.420998, 5.0])
    li = LoopIntegrals(10.0, 3, pts, 8)
    f = loop_displacements(10.0, 3, pts, 8)
    a, mu = ca.MX.sym("a", 8), ca.MX.sym("mu", 2, pts.size)
    D = f(a)
    ad = ca.Function("ad", [a, mu], [D, ca.jacobian(ca.vec(D), a), ca.hessian(ca.dot(mu, D), a)[0]])
    rng = np.random.default_rng(1)
    A, M = rng.normal(scale=0.7, size=(3, 8)), rng.normal(size=(3, pts.size, 2))
    theta, Dn = li.values(A)
    J, H = li.jacobians(theta), li.weighted_hessians(theta, M)
    for k in range(3):
        d, j, h = (np.asarray(v) for v in ad(A[k], M[k].T))
        np.testing.assert_allclose(Dn[k], d.T, atol=1e-13)
        np.testing.assert_allclose(J[k], j.reshape(pts.size, 2, 8), atol=1e-13)
        np.testing.assert_allclose(H[k], h, atol=1e-11)


def test_gradient_equals_central_differences(mixed):
    c = mixed
    w, lam = _point(c), np.random.default_rng(2).normal(size=c.g.size)

    def lagrangian(v):
        return 0.7 * c.objective(v, c.p0) + lam @ c.constraints(v, c.p0)

    g = c.gradient(w, c.p0, 0.7, lam)
    h = 1e-6
    fd = np.array([(lagrangian(w + h * e) - lagrangian(w - h * e)) / (2 * h) for e in np.eye(w.size)])
    np.testing.assert_allclose(g, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_jacobian_and_hessian_equal_central_differences(mixed):
    c = mixed
    w, lam = _point(c, 3), np.random.default_rng(4).normal(size=c.g.size)
    h = 1e-6
    E = np.eye(w.size)
    fd_jac = np.array([(c.constraints(w + h * e, c.p0) - c.constraints(w - h * e, c.p0)) / (2 * h)
                       for e in E]).T
    np.testing.assert_allclose(c.jacobian(w, c.p0), fd_jac, atol=1e-6 * np.abs(fd_jac).max())
    assert not np.any(c.jacobian(w, c.p0)[~c.jac_mask])
    fd_hess = np.array([(c.gradient(w + h * e, c.p0, 0.7, lam) - c.gradient(w - h * e, c.p0, 0.7, lam))
                        / (2 * h) for e in E])
    H = c.hessian(w, c.p0, 0.7, lam)
    np.testing.assert_allclose(H, fd_hess, atol=1e-5 * np.abs(fd_hess).max())
    np.testing.assert_allclose(H, H.T, atol=1e-9 * np.abs(H).max())
    assert not np.any(np.triu(H)[~c.hess_mask])            # the structural pattern holds


def test_condensed_and_lifted_reduced_models_reach_the_same_minimum(write_problem):
    pr = load_problem(write_problem(MIXED))
    cond = transcribe(pr, pr.reduction)
    # the same start for both (the condensed default would solve the corner form first)
    rc = solve_nlp(cond, WeftSolver(cond), start="natural")
    rl = lifted_reduced_solve(pr, pr.reduction)
    assert rc.success and rl.success
    assert rc.objective == pytest.approx(rl.objective, rel=1e-9)
    np.testing.assert_allclose(cond.coefficients(rc.x), rl.coefficients, atol=1e-6)
    np.testing.assert_allclose(cond.starts(rc.x), rl.starts, atol=1e-6)
    # same multipliers: the clamps' reactions agree (the rows share their names and order)
    assert list(cond.g.blocks) == [k for k in rl.full.g.blocks if k.startswith(("clamp", "rigid"))]
    for name in cond.g.blocks:
        np.testing.assert_allclose(rc.lam_g[cond.g.slice(name)], rl.lam_g[rl.full.g.slice(name)],
                                   rtol=1e-5, atol=1e-7)


def test_every_loop_representative_condensed_equals_the_full_model(write_problem):
    pr = load_problem(write_problem(MIXED))
    every = Reduced(tuple(range(1, 5)), tuple(range(1, 6)))
    cond, full = transcribe(pr, every), transcribe(pr, Full())
    rc, rf = solve_nlp(cond, WeftSolver(cond)), solve_nlp(full, WeftSolver(full))
    assert rc.success and rf.success
    assert rc.objective == pytest.approx(rf.objective, rel=1e-9)
    np.testing.assert_allclose(cond.coefficients(rc.x), full.coefficients(rf.x), atol=1e-6)
    np.testing.assert_allclose(cond.special_positions(rc.x), full.special_positions(rf.x), atol=1e-6)


def test_shooting_segments_reach_the_single_shooting_minimum_in_fewer_iterations():
    # measured on the 20 x 20 diagonal pull (corner form): 8 iterations in segments of 12
    # loops, 22 with each course one segment; 50 x 50: 9 against 47 (docs/measurements.md)
    pr = parse_problem(diagonal_pull(20), "<diagonal pull 20 x 20>")
    seg, one = build_condensed(pr, segment=12), build_condensed(pr, segment=20)
    assert (seg.n_seg, one.n_seg) == (2, 1)
    assert seg.g.size == one.g.size + 2 * 20            # one chaining row pair per course
    rs = solve_nlp(seg, WeftSolver(seg, max_iter=100))
    r1 = solve_nlp(one, WeftSolver(one, max_iter=100))
    assert rs.success and r1.success
    assert rs.objective == pytest.approx(r1.objective, rel=1e-9)
    np.testing.assert_allclose(seg.coefficients(rs.x), one.coefficients(r1.x), atol=1e-6)
    np.testing.assert_allclose(seg.starts(rs.x), one.starts(r1.x), atol=1e-6)
    assert rs.iterations <= 12 < r1.iterations


def test_a_finer_reduced_grid_starts_from_the_corner_form():
    # measured on the 16 x 16 diagonal pull over an even 8 x 8 grid: corner 9 + grid 13
    # iterations against 45 from the natural state, to the same minimum (docs/measurements.md)
    pr = parse_problem(diagonal_pull(16), "<diagonal pull 16 x 16>")
    grid = build_condensed(pr, Reduced((1, 3, 5, 7, 10, 12, 14, 16), (1, 3, 5, 7, 10, 12, 14, 16)))
    warm = solve_nlp(grid, WeftSolver(grid, max_iter=200))
    cold = solve_nlp(grid, WeftSolver(grid, max_iter=200), start="natural")
    assert warm.success and cold.success
    first = warm.attempts[0]
    assert first.startswith("corner start: Solve_Succeeded")
    corner_its = int(first.split("(")[1].split(" it")[0])
    assert corner_its + warm.iterations < cold.iterations
    assert warm.objective == pytest.approx(cold.objective, rel=1e-9)
    np.testing.assert_allclose(grid.coefficients(warm.x), grid.coefficients(cold.x), atol=1e-6)
    corner = build_condensed(pr)
    attempts = solve_nlp(corner, WeftSolver(corner)).attempts
    assert not any(a.startswith("corner start") for a in attempts)
