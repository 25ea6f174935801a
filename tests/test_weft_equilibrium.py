"""Equilibrium physics of the full weft model: invariances, closed forms, convergence."""
import numpy as np
import pytest

from knit_nlp.weft.model.basis import phi
from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.transcription.factory import transcribe
from knit_nlp.weft.model.problem import load_problem
from knit_nlp.weft.api import solve as solve_problem
from knit_nlp.weft.solving.solve import WeftSolver

from conftest import PROBLEMS, elastica_force, solve_text

NATURAL_CLAMPS = """
[fabric]
courses = 3
wales = 4
[[clamp]]
loop = [1, 1]
point = "start"
displacement = [0.0, 0.0]
[[clamp]]
loop = [3, 4]
point = "H"
displacement = [0.0, 0.0]
[[clamp]]
loop = [2, 2]
point = "B"
displacement = [0.0, 0.0]
[[clamp]]
loop = [3, 1]
point = "start"
displacement = [0.0, 0.0]
fix = []
angle = 0.0
"""


def test_natural_state_is_the_minimum_with_zero_energy_and_reactions(write_problem):
    s = solve_text(write_problem(NATURAL_CLAMPS))
    assert s.success
    assert s.energy.total == pytest.approx(0.0, abs=1e-12)
    for c in s.clamps:
        assert np.allclose(c.reaction, 0.0, atol=1e-9)
    assert s.clamps[3].reaction_moment == pytest.approx(0.0, abs=1e-9)
    pr = s.nlp.problem
    np.testing.assert_allclose(s.coefficients,
                               np.broadcast_to(pr.natural.coeffs, (3, 4, 8)), atol=1e-8)


def _diagonal(write_problem, shift=(0.0, 0.0), nodes=16, courses=4, wales=4, name="p.toml"):
    sx, sy = shift
    return write_problem(f"""
        [fabric]
        courses = {courses}
        wales = {wales}
        [loop]
        quadrature_nodes = {nodes}
        [[clamp]]
        loop = [1, 1]
        point = "start"
        position = [{sx}, {sy}]
        [[clamp]]
        loop = [1, {wales}]
        point = "H"
        position = [{9.5 + sx}, {7.0 + sy}]
        """, name)


def test_translating_every_clamp_translates_the_solution(write_problem):
    base = solve_text(_diagonal(write_problem))
    moved = solve_text(_diagonal(write_problem, (3.25, -1.5), name="q.toml"))
    assert base.success and moved.success
    assert moved.energy.total == pytest.approx(base.energy.total, rel=1e-7)
    np.testing.assert_allclose(moved.centrelines(), base.centrelines() + [3.25, -1.5], atol=1e-6)
    for a, b in zip(base.clamps, moved.clamps):
        np.testing.assert_allclose(a.reaction, b.reaction, atol=1e-7)


def test_continuity_and_clamps_hold(write_problem):
    s = solve_text(_diagonal(write_problem))
    pr, coeffs = s.problem, s.coefficients
    lines = s.centrelines()
    for i in range(pr.courses):
        for j in range(pr.wales - 1):
            a, b = coeffs[i, j], coeffs[i, j + 1]
            assert phi(pr.L, pr.L, pr.t)[0] @ a == pytest.approx(phi(0.0, pr.L, pr.t)[0] @ b, abs=1e-8)
            np.testing.assert_allclose(lines[i, j, -1], lines[i, j + 1, 0], atol=1e-8)
    for c in s.clamps:
        np.testing.assert_allclose(c.position, c.target, atol=1e-8)
    assert s.violation < 1e-8
    # the two clamps are the only external forces: their reactions balance
    r = np.array([c.reaction for c in s.clamps])
    np.testing.assert_allclose(r.sum(axis=0), 0.0, atol=1e-8)
    assert np.linalg.norm(r[1]) > 1e-3


def test_reaction_sign_is_the_force_on_the_fabric(write_problem):
    """Pulling the right clamp away: the clamp pulls the fabric outward (along the pull)."""
    s = solve_text(_diagonal(write_problem))
    pull = np.array([9.5, 7.0]) - s.nlp.problem.natural_position((1, 4), s.nlp.problem.crossings.s["H"])
    assert np.dot(s.clamps[1].reaction, pull) > 0


def test_energy_converges_as_quadrature_nodes_grow(write_problem):
    energies = [solve_text(_diagonal(write_problem, nodes=k, name=f"n{k}.toml")).energy.total
                for k in (2, 3, 4, 8, 16)]
    errors = [abs(e - energies[-1]) for e in energies[:-1]]
    assert errors[0] > errors[1] > errors[2] > errors[3] >= 0
    assert errors[3] < 1e-10 * energies[-1]


def test_end_moment_closes_a_straight_yarn_into_a_circle():
    s = solve_problem(load_problem(PROBLEMS / "single_loop_moment.toml"))
    pr = s.nlp.problem
    assert s.success
    lines = s.centrelines(201)[0, 0]
    np.testing.assert_allclose(lines[-1], lines[0], atol=1e-9)          # the loop closes
    centre = np.array([0.0, pr.L / (2 * np.pi)])                        # radius R_f / M = L / 2π
    np.testing.assert_allclose(np.linalg.norm(lines - centre, axis=1), pr.L / (2 * np.pi), atol=1e-9)
    assert s.energy.bending == pytest.approx(2 * np.pi ** 2 * pr.R_f / pr.L, rel=1e-9)
    assert s.energy.load_work == pytest.approx(4 * np.pi ** 2 * pr.R_f / pr.L, rel=1e-9)


def _buckling(write_problem, t: int):
    return solve_text(write_problem(f"""
        [fabric]
        courses = 1
        wales = 1
        [loop]
        preset = "straight"
        length = 40.0
        harmonics = {t}
        [material]
        R_f = 2.0
        [[clamp]]
        loop = [1, 1]
        point = "start"
        position = [0.0, 0.0]
        [[clamp]]
        loop = [1, 1]
        point = "end"
        position = [36.0, 0.0]
        """, f"b{t}.toml"))


def test_compressed_straight_yarn_buckles_into_the_first_euler_mode(write_problem):
    exact = elastica_force(40.0, 36.0, 2.0)
    errors = []
    for t in (3, 6, 12):
        s = _buckling(write_problem, t)
        assert s.success, s.report.attempts
        fx = s.clamps[1].reaction[0]
        assert fx < 0                                        # the clamp pushes the yarn back
        errors.append(abs(-fx / exact - 1))
        y = s.centrelines(101)[0, 0, 1:-1, 1]
        assert np.all(y > 0) or np.all(y < 0)                # first mode: one arch, no crossing
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 1e-4


def test_solver_is_reused_across_parameters(write_problem):
    """The same nlpsol object, re-solved with moved targets, matches a fresh build."""
    pr = load_problem(_diagonal(write_problem))
    w = transcribe(pr, Full())
    solver = WeftSolver(w)
    p = w.p0.copy()
    t = w.p.get(p, "targets").copy()
    t[:, 1] += [0.5, -0.25]
    w.p.put(p, "targets", t)
    reused = solver.once(p, w.x0)
    fresh = solve_text(_diagonal_shifted(write_problem))
    assert reused.success and fresh.success
    assert reused.objective == pytest.approx(fresh.report.objective, rel=1e-8)


def _diagonal_shifted(write_problem):
    return write_problem("""
        [fabric]
        courses = 4
        wales = 4
        [[clamp]]
        loop = [1, 1]
        point = "start"
        position = [0.0, 0.0]
        [[clamp]]
        loop = [1, 4]
        point = "H"
        position = [10.0, 6.75]
        """, "shifted.toml")


def test_continuation_fallback_reaches_the_direct_solution(tmp_path):
    """A direct solve starved of iterations fails; continuation (with halving) gets there."""
    base = (PROBLEMS / "wada_fig7.toml").read_text()
    direct = solve_problem(load_problem(PROBLEMS / "wada_fig7.toml"))
    starved = tmp_path / "starved.toml"
    starved.write_text(base + "\n[solver]\nmax_iter = 4\n")
    s = solve_problem(load_problem(starved))
    assert s.success
    assert s.report.attempts[0].startswith("direct: Maximum_Iterations_Exceeded")
    assert s.report.continuation_steps > 4                       # a step had to be halved
    assert s.energy.total == pytest.approx(direct.energy.total, rel=1e-7)


def test_continuation_on_request_takes_the_asked_steps():
    direct = solve_problem(load_problem(PROBLEMS / "wada_fig7.toml"))
    stepped = solve_problem(load_problem(PROBLEMS / "wada_fig7.toml"), continuation=3)
    assert stepped.success and stepped.report.continuation_steps == 3
    assert stepped.energy.total == pytest.approx(direct.energy.total, rel=1e-7)
    np.testing.assert_allclose(stepped.centrelines(), direct.centrelines(), atol=1e-5)


NATURAL_PARAMETERS = """
[fabric]
courses = 3
wales = 3
[[clamp]]
loop = [1, 1]
point = "B"
displacement = [0.7, -0.2]
angle = 0.4
[[clamp]]
loop = [3, 3]
point = "E"
position = [6.0, 9.0]
fix = ["y"]
angle = -0.3
[[rigid_clamp]]
points = [{loop = [1, 3], point = "end"}, {loop = [2, 3], point = "end"}]
translation = [0.5, 0.1]
rotation = 0.1
[[load]]
loop = [2, 2]
point = "H"
force = [0.02, -0.01]
moment = 0.03
"""


def test_continuation_starts_from_parameters_that_hold_the_natural_state(write_problem):
    """Continuation steps every parameter from ``WeftParams.natural``: clamp targets at the
    natural positions, clamp angles at the natural angles (nonzero at B and E of a jersey loop),
    rigid clamps unmoved, loads zero. There the natural configuration satisfies every
    constraint and is the minimum: IPOPT stays at it with zero energy and zero reactions."""
    from knit_nlp.weft.model.params import WeftParams
    from knit_nlp.weft.output.results import WeftResult
    w = transcribe(load_problem(write_problem(NATURAL_PARAMETERS)), Full())
    pr, natural = w.problem, WeftParams.natural(w.problem)
    p_nat = natural.vector()
    natural_angles = [float(phi(c.s, pr.L, pr.t)[0] @ pr.natural.coeffs) for c in pr.clamps]
    assert min(abs(a) for a in natural_angles) > 0.5        # the angles matter
    solver = WeftSolver(w)
    assert solver.violation(w.x0, p_nat) < 1e-9             # (natural positions by quadrature)
    assert solver.violation(w.x0, w.p0) > 0.1                # while the problem's do not hold it
    rep = solver.once(p_nat, w.x0)
    assert rep.success and abs(rep.objective) < 1e-12
    np.testing.assert_allclose(rep.x, w.x0, atol=1e-9)
    res = WeftResult(w, rep, natural, 0.0, 0.0)
    for c, angle in zip(res.clamps, natural_angles):
        assert c.angle == pytest.approx(angle, abs=1e-12)
        assert np.allclose(c.reaction, 0.0, atol=1e-9) and abs(c.reaction_moment) < 1e-9
    # ... and continuation from there reaches the direct solution of the problem
    direct = solver.once(w.p0, w.x0)
    stepped = solver.continuation(w.p0, w.x0, 3)
    assert direct.success and stepped.success and stepped.continuation_steps == 3
    assert stepped.objective == pytest.approx(direct.objective, rel=1e-7)
