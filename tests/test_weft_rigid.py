"""Rigid (line) clamps: the held points move as one rigid body."""
import numpy as np
import pytest

from conftest import solve_text

RIGID = """
[fabric]
courses = 4
wales = 4
[[rigid_clamp]]
points = [{loop = [1, 1], point = "start"}, {loop = [2, 1], point = "start"},
          {loop = [3, 1], point = "start"}, {loop = [4, 1], point = "start"}]
[[rigid_clamp]]
points = [{loop = [1, 4], point = "end"}, {loop = [2, 4], point = "end"},
          {loop = [3, 4], point = "end"}, {loop = [4, 4], point = "end"}]
translation = [2.5, 1.0]
rotation = 0.3
centre = [9.0, 3.0]
"""


def test_rigid_clamp_points_keep_their_mutual_distances(write_problem):
    s = solve_text(write_problem(RIGID))
    assert s.success
    pr = s.nlp.problem
    for rc, res in zip(pr.rigid_clamps, s.rigid_clamps):
        p0 = np.array([pr.natural_position(lp, sv) for lp, _, sv in rc.points])
        p1 = res.positions
        d0 = np.linalg.norm(p0[:, None] - p0[None], axis=-1)
        d1 = np.linalg.norm(p1[:, None] - p1[None], axis=-1)
        np.testing.assert_allclose(d1, d0, atol=1e-8)
    # the moved clamp is turned by exactly the rotation
    p0 = np.array([pr.natural_position(lp, sv) for lp, _, sv in pr.rigid_clamps[1].points])
    p1 = s.rigid_clamps[1].positions
    v0, v1 = p0[-1] - p0[0], p1[-1] - p1[0]
    assert np.arctan2(v1[1], v1[0]) - np.arctan2(v0[1], v0[0]) == pytest.approx(0.3, abs=1e-8)


def test_rigid_clamp_forces_balance_but_moments_need_not(write_problem):
    """The energy is translation invariant, so the clamps' forces balance. The paper fixes the
    spring frames and rest vectors in space, so the energy is not rotation invariant and the
    clamps' moments about the origin do not balance once the fabric turns."""
    s = solve_text(write_problem(RIGID))
    force, moment = np.zeros(2), 0.0
    for rc in s.rigid_clamps:
        for f, x in zip(rc.reactions, rc.positions):
            force += f
            moment += x[0] * f[1] - x[1] * f[0]
    assert np.linalg.norm(s.rigid_clamps[1].force) > 1e-3
    np.testing.assert_allclose(force, 0.0, atol=1e-8)
    assert abs(moment) > 1e-3


def test_turning_the_whole_fabric_rigidly_costs_energy(write_problem):
    """Four corners turned together by 0.2 rad: a rotation-invariant model would follow at zero
    energy; with springs fixed in space (the paper's eqs. 6-7) the turn costs energy."""
    s = solve_text(write_problem("""
        [fabric]
        courses = 4
        wales = 4
        [[rigid_clamp]]
        points = [{loop = [1, 1], point = "start"}, {loop = [4, 1], point = "start"},
                  {loop = [1, 4], point = "end"}, {loop = [4, 4], point = "end"}]
        rotation = 0.2
        """))
    assert s.success
    assert s.energy.total > 1e-3


def test_a_point_in_a_clamp_and_a_rigid_clamp_is_over_constrained(write_problem, tmp_path, capsys):
    from knit_nlp.cli import main
    path = write_problem(RIGID + '[[clamp]]\nloop = [3, 1]\npoint = "start"\nposition = [0.0, 4.0]\n'
                         'fix = ["y"]\n', "over.toml")
    assert main(["solve", str(path), "--out", str(tmp_path)]) == 2
    assert "[rigid_clamp[1]] points[3]" in capsys.readouterr().err
