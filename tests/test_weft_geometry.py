"""Geometry: basis, quadrature, natural loop and crossings against the spec's check values."""
import numpy as np
import pytest
from scipy.special import j0

from knit_nlp.weft.model.basis import bending_diagonal, continuity_rows, dphi, phi
from knit_nlp.weft.model.crossing_points import CrossingError, find_crossings
from knit_nlp.weft.model.energy import bending_energy, bending_energy_quadrature
from knit_nlp.weft.model.natural_loop import natural_loop, preset_coeffs
from knit_nlp.weft.model.quadrature import panel_rule


@pytest.fixture(scope="module")
def jersey():
    return natural_loop(preset_coeffs("jersey", 3), 10.0, 3)


def test_jersey_spacings_match_spec(jersey):
    assert jersey.wale_spacing == pytest.approx(10.0 * j0(2.0), abs=1e-12)
    assert round(jersey.wale_spacing, 6) == 2.238908
    assert round(jersey.height, 6) == 3.954294
    assert round(jersey.course_spacing, 6) == 1.977147


def test_crossing_check_values(jersey):
    s = find_crossings(jersey).s
    expected = dict(A=0.521500, C=2.320496, D=2.679504, F=4.478500, Q=7.679504, S=9.478500,
                    G=5.521500, P=7.320496, B=1.420998, E=3.579002, R=8.579002, H=6.420998)
    for label, value in expected.items():
        assert s[label] == pytest.approx(value, abs=5e-6), label


def test_crossings_are_the_same_material_points(jersey):
    """A on the upper loop and D on the lower loop are one point in the natural fabric."""
    c = find_crossings(jersey)
    up = lambda k: jersey.xy([c.s[k]])[0] + [0.0, jersey.course_spacing]  # noqa: E731
    low = lambda k: jersey.xy([c.s[k]])[0]  # noqa: E731
    for u, l in (("A", "D"), ("C", "F"), ("Q", "G"), ("S", "P")):
        np.testing.assert_allclose(up(u), low(l), atol=1e-10)
    assert np.dot(c.frame_left[0], c.frame_left[1]) == pytest.approx(0.0, abs=1e-14)


def test_geometry_without_crossings_is_rejected():
    with pytest.raises(CrossingError):
        find_crossings(natural_loop(preset_coeffs("jersey", 3), 10.0, 3, course_spacing=20.0))


@pytest.mark.parametrize("t", [1, 3, 5])
def test_bending_closed_form_equals_quadrature(t):
    rng = np.random.default_rng(t)
    a, a0 = rng.normal(size=2 * t + 2), rng.normal(size=2 * t + 2)
    exact = float(bending_energy(7.5, t)(a, a0, 1.7))
    assert exact == pytest.approx(bending_energy_quadrature(a, a0, 7.5, t, 1.7, 24), rel=1e-12)
    assert np.all(bending_diagonal(7.5, t)[:-1] > 0) and bending_diagonal(7.5, t)[-1] == 0


def test_continuity_rows_are_angle_and_curvature():
    L, t = 10.0, 3
    end, start = continuity_rows(L, t)
    a = np.random.default_rng(0).normal(size=8)
    assert end[0] @ a == pytest.approx(phi(L, L, t)[0] @ a)
    assert start[1] @ a == pytest.approx(dphi(0.0, L, t)[0] @ a)


def test_panel_rule_integrates_to_every_point_exactly():
    rule = panel_rule([1.3, 4.0, 7.7], 10.0, 6)
    f = rule.nodes ** 7 - 3 * rule.nodes ** 2
    exact = np.array([s ** 8 / 8 - s ** 3 for s in (1.3, 4.0, 7.7)])
    np.testing.assert_allclose(rule.cumulative @ f, exact, rtol=1e-12)


def test_user_natural_shape_with_other_harmonics(write_problem):
    """Own coefficients (t = 2, a flatter loop with a second harmonic) and spacing: four
    crossings found, and the natural state solves at zero energy."""
    from conftest import solve_text
    path = write_problem("""
        [fabric]
        courses = 3
        wales = 3
        [loop]
        harmonics = 2
        length = 8.0
        natural_coefficients = [1.8, 0.15, 0.0, 0.0, 0.0, 0.0]
        course_spacing = 1.4
        [[clamp]]
        loop = [1, 1]
        point = "R"
        displacement = [0.0, 0.0]
        [[clamp]]
        loop = [3, 3]
        point = "E"
        displacement = [0.0, 0.0]
        """)
    s = solve_text(path)
    c = s.nlp.problem.crossings
    assert 0 < c.s["A"] < c.s["C"] < 4.0 < c.s["Q"] < c.s["S"] < 8.0
    assert s.success and s.energy.total == pytest.approx(0.0, abs=1e-12)
