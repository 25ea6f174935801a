"""Deformation control: round trips, least squares against bounds, the outer gradient against
finite differences of forward solves, and the second-order (stability) check."""
import json

import numpy as np
import pytest

from knit_nlp.cli import main
from knit_nlp.weft.inverse.control import Controller, control
from knit_nlp.weft.solving.sensitivity import Stability
from knit_nlp.weft.solving.solve import Equilibrium
from knit_nlp.weft.inverse.spec import load_control
from knit_nlp.weft.model.problem import load_problem
from knit_nlp.weft.solving.starts import perturbed_starts

FABRIC = """
[fabric]
courses = 4
wales = 4
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [4, 4]
point = "H"
displacement = [0.0, 0.0]
actuated = true
{bounds}
[[goal]]
loop = [3, 2]
point = "B"
position = [{gx}, {gy}]
"""


def _forward_point(write_problem, target):
    """Solve the fabric forward with the actuated target fixed at ``target``; the achieved B of
    loop (3, 2)."""
    ctl = Controller(load_control(write_problem(FABRIC.format(bounds="", gx=0, gy=0), "fw.toml")))
    rep = ctl.equilibrium(np.asarray(target))
    assert rep.success
    return ctl.goal_positions(rep.x)[:, 0], ctl


def test_round_trip_recovers_the_known_targets(write_problem):
    known = np.array([17.0, 15.5])                 # H of (4, 4) pulled up and right from (10.9, 12.9)
    goal, _ = _forward_point(write_problem, known)
    cp = load_control(write_problem(FABRIC.format(bounds="", gx=goal[0], gy=goal[1]), "rt.toml"))
    ans = control(cp)                              # starts from the natural target, elsewhere
    assert ans.success and ans.status == "Converged"
    assert np.abs(ans.start.u - known).max() > 3.0
    misfit = np.linalg.norm(ans.ctl.goal_positions(ans.state.x)[:, 0] - goal)
    assert misfit < 1e-6
    assert np.allclose(ans.state.u, known, atol=1e-5)
    assert ans.stability.stable and ans.forward_success and ans.forward_distance < 1e-6


def test_unreachable_goal_gives_the_bounded_least_squares_best(write_problem):
    # B of (3, 2) is naturally near (3.6, 7.0); a goal 100 units to the right is beyond the
    # yarn. The box stops the gripper at x = 16: the answer sits on that bound.
    box = "bounds = [[0.0, 16.0], [0.0, 30.0]]"
    cp = load_control(write_problem(FABRIC.format(bounds=box, gx=100.0, gy=7.0), "far.toml"))
    ans = control(cp)
    assert ans.success, ans.status
    assert ans.state.u[0] == pytest.approx(16.0, abs=1e-9)          # the blocking bound is active
    reached = ans.ctl.goal_positions(ans.state.x)[:, 0]
    misfit = np.linalg.norm(reached - [100.0, 7.0])
    assert misfit > 80.0 and float(ans.state.r @ ans.state.r) == pytest.approx(misfit ** 2)
    # least squares best: no feasible neighbour (y free, x inside the box) does better
    ctl = ans.ctl
    for du in ([0.0, 0.3], [0.0, -0.3], [-0.3, 0.0]):
        rep = ctl.equilibrium(ans.state.u + du, x0=ans.state.x)
        assert rep.success
        other = np.linalg.norm(ctl.goal_positions(rep.x)[:, 0] - [100.0, 7.0])
        assert other >= misfit - 1e-9


@pytest.mark.parametrize("kind", ["clamp", "rigid"])
def test_outer_gradient_equals_finite_differences_of_forward_solves(write_problem, kind):
    text = FABRIC.format(bounds="", gx=5.0, gy=8.0)
    if kind == "rigid":
        text = text.replace("actuated = true\n", "") + """
[[rigid_clamp]]
points = [{loop = [4, 1], point = "start"}, {loop = [4, 1], point = "B"}]
translation = [0.5, 0.3]
rotation = 0.1
actuated = true
"""
    text += "[control]\ntravel_weight = 0.5\n"            # its rows √w·(u − u₀) too
    ctl = Controller(load_control(write_problem(text, f"g_{kind}.toml")))
    u = ctl.u0 + (np.array([1.5, 0.8]) if kind == "clamp" else np.array([0.2, -0.1, 0.05]))
    rep = ctl.equilibrium(u)
    assert rep.success
    s = ctl._state(u, rep)
    _, Jr, _ = ctl.jacobians(s)
    h = 1e-5
    for k in range(len(u)):
        e = np.zeros(len(u))
        e[k] = h
        plus, minus = (ctl.equilibrium(u + sgn * e, x0=rep.x) for sgn in (1, -1))
        fd = (ctl._residual(u + e, plus.x) - ctl._residual(u - e, minus.x)) / (2 * h)
        assert np.linalg.norm(Jr[:, k] - fd) <= 1e-5 * np.linalg.norm(fd)


def _goal_jacobian(ctl: Controller, u: np.ndarray, x: np.ndarray, h: float = 1e-4) -> np.ndarray:
    """dP/du of the goal point by central differences of forward solves (not the code's
    sensitivities)."""
    cols = []
    for e in h * np.eye(len(u)):
        plus, minus = (ctl.equilibrium(u + sgn * e, x0=x) for sgn in (1, -1))
        assert plus.success and minus.success
        cols.append((ctl.goal_positions(plus.x)[:, 0] - ctl.goal_positions(minus.x)[:, 0]) / (2 * h))
    return np.column_stack(cols)


@pytest.mark.parametrize("w", [1.0, 100.0])
def test_travel_weight_gives_the_stationary_compromise(write_problem, w):
    """Objective |P(u) − goal|² + w·|u − u₀|², goal reached at u = (13, 14) with w = 0. Its
    optimum satisfies, in closed form, w·(u − u₀) = −Jᵀ(P(u) − goal) (J = dP/du there, by
    finite differences of forward solves): the travel is the goal's pull over the weight, a
    compromise strictly short of (13, 14). For large w the pull is linear near u₀ and the
    answer is u₀ + (AᵀA + w·I)⁻¹Aᵀ(goal − P(u₀)), A = dP/du at u₀. A travel Jacobian of the
    wrong sign stops elsewhere (first Gauss–Newton step or beyond), off the first relation."""
    known = np.array([13.0, 14.0])
    goal, _ = _forward_point(write_problem, known)
    path = write_problem(FABRIC.format(bounds="", gx=goal[0], gy=goal[1])
                         + f"[control]\ntravel_weight = {w}\n", "travel.toml")
    ans = control(load_control(path))
    assert ans.success and ans.status == "Converged", ans.status
    ctl, u, x = ans.ctl, ans.state.u, ans.state.x
    travel = u - ctl.u0
    assert 0.0 < np.linalg.norm(travel) < np.linalg.norm(known - ctl.u0)
    pull = -_goal_jacobian(ctl, u, x).T @ (ctl.goal_positions(x)[:, 0] - goal)
    assert np.linalg.norm(w * travel - pull) <= 1e-6 * np.linalg.norm(w * travel)
    if w >= 100.0:
        start = ctl.equilibrium(ctl.u0)
        A = _goal_jacobian(ctl, ctl.u0, start.x)
        linear = np.linalg.solve(A.T @ A + w * np.eye(2),
                                 A.T @ (goal - ctl.goal_positions(start.x)[:, 0]))
        assert np.linalg.norm(travel - linear) <= 0.01 * np.linalg.norm(travel)


def test_stability_tells_the_first_euler_mode_from_the_second(tmp_path):
    """Pinned compressed rod (problems/euler_buckling.toml): mode 1 is a minimum, the S-shaped
    mode 2 a saddle; dense null-space and shift-invert Lanczos agree."""
    from tests.conftest import PROBLEMS
    eq = Equilibrium(load_problem(PROBLEMS / "euler_buckling.toml"))
    modes = {}
    for name, x0 in perturbed_starts(eq.wnlp):
        rep = eq.solver.once(eq.wnlp.p0, x0)
        assert rep.success
        modes[name] = (rep.objective, rep)
    low = min(modes.values(), key=lambda v: v[0])[1]
    high = max(modes.values(), key=lambda v: v[0])[1]
    assert high.objective > low.objective + 1e-3
    for rep, stable in ((low, True), (high, False)):
        dense = eq.stability(rep.x, rep.lam_g, eq.wnlp.p0, method="dense")
        lanczos = eq.stability(rep.x, rep.lam_g, eq.wnlp.p0, method="sparse")
        assert dense.stable is stable and lanczos.stable is stable
        if stable:
            assert lanczos.min_eigenvalue == pytest.approx(dense.min_eigenvalue, rel=1e-6)


def test_a_saddle_is_exit_1_never_success(write_problem, tmp_path, monkeypatch):
    known = np.array([13.0, 14.0])
    goal, _ = _forward_point(write_problem, known)
    path = write_problem(FABRIC.format(bounds="", gx=goal[0], gy=goal[1]), "sad.toml")
    monkeypatch.setattr(Equilibrium, "stability", lambda self, x, lam, p, method='sparse': Stability(-1.0, "forced"))
    assert main(["control", str(path), "--out", str(tmp_path)]) == 1
    r = json.loads((tmp_path / "sad.control.json").read_text())
    assert r["success"] is False and r["stable"] is False and "Saddle" in r["status"]


def test_control_cli_writes_the_contract_and_holds_an_active_opening(write_problem, tmp_path):
    known = np.array([13.0, 14.0])
    goal, ctl = _forward_point(write_problem, known)
    # B-R of loop (2, 2) at the goal state, asked 5 % wider: the opening must bind
    opening = "[[opening]]\npoints = [{loop = [2, 2], point = \"B\"}, {loop = [2, 2], point = \"R\"}]\n"
    probe = load_control(write_problem(FABRIC.format(bounds="", gx=0, gy=0) + opening
                                       + "at_least = 0.1\n", "probe.toml"))
    pctl = Controller(probe)
    wide = 1.05 * pctl.opening_distances(pctl.equilibrium(known).x)[0]
    path = write_problem(FABRIC.format(bounds="", gx=goal[0], gy=goal[1]) + opening
                         + f"at_least = {wide}\n", "cli.toml")
    assert main(["control", str(path), "--out", str(tmp_path)]) == 0
    r = json.loads((tmp_path / "cli.control.json").read_text())
    for key in ("problem", "success", "status", "objective", "iterations", "timings", "actuated",
                "goals", "openings", "stable", "min_reduced_hessian_eigenvalue", "forward_check",
                "equilibrium"):
        assert key in r
    assert r["actuated"][0]["clamp"] == 2
    assert r["openings"][0]["achieved"] == pytest.approx(wide, abs=1e-6)      # active
    assert r["goals"][0]["misfit"] > 1e-3                                     # so the goal yields
    assert r["objective"] == pytest.approx(r["goals"][0]["misfit"] ** 2)
    assert r["equilibrium"]["success"] is True and r["forward_check"]["success"] is True
    assert (tmp_path / "cli.control.png").stat().st_size > 10_000


def test_control_says_it_solves_the_full_model_when_given_a_reduction(write_problem, tmp_path,
                                                                      capsys):
    """The inverse problems' equilibrium is the full model's (equilibrium.py): a [reduction]
    table is named as ignored on stderr (once control ignored it without a word), and the
    answer is the one without it, to the solver's tolerance."""
    text = FABRIC.format(bounds="", gx=4.5, gy=5.1)
    reduction = "[reduction]\nrepresentative_courses = [1, 4]\nrepresentative_wales = [1, 4]\n"
    targets = []
    for name, extra in (("plain", ""), ("reduced", reduction)):
        path = write_problem(text + extra, f"{name}.toml")
        assert main(["control", str(path), "--out", str(tmp_path)]) == 0
        err = capsys.readouterr().err
        assert ("[reduction] ignored" in err and str(path) in err) == bool(extra), err
        targets.append(json.loads((tmp_path / f"{name}.control.json").read_text())
                       ["actuated"][0]["target"])
    np.testing.assert_allclose(targets[0], targets[1], atol=1e-7)


def test_a_control_answer_that_tears_the_fabric_says_so(write_problem, tmp_path, capsys):
    """A goal 40 units off on a 4 x 4 fabric: the gripper drags the fabric apart, and the
    summary names the springs stretched beyond a loop length (output/plausibility.py)."""
    path = write_problem(FABRIC.format(bounds="", gx=40.0, gy=40.0), "far.toml")
    main(["control", str(path), "--out", str(tmp_path)])
    line = next(ln for ln in capsys.readouterr().out.splitlines() if "IMPLAUSIBLE" in ln)
    assert "crossing springs stretched beyond a loop length" in line


def test_the_bound_named_is_the_one_each_unknown_stopped_on(write_problem):
    """A goal above the fabric (B of (3, 2) at y = 20) with the gripper's y capped at 16:
    the answer names exactly ``target y = 16 (upper bound)`` (red when each unknown's bounds
    are compared with the first unknown's value, a survivor of scripts/mutate.py: the x
    bound alone was tested)."""
    from knit_nlp.weft.inverse.control import at_bounds
    box = "bounds = [[-100.0, 100.0], [0.0, 16.0]]"
    ans = control(load_control(write_problem(FABRIC.format(bounds=box, gx=4.0, gy=20.0),
                                             "up.toml")))
    assert ans.state.u[1] == pytest.approx(16.0, abs=1e-9)
    assert -100.0 < ans.state.u[0] < 100.0
    assert at_bounds(ans) == ["clamp[2] target y = 16 (upper bound)"]
