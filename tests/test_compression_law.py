"""The yarn's compression law (knit_nlp/weft/model/compression.py) against independent
computations: its force is minus the derivative of its energy, its inverse inverts it, the
crossing energy (C1) is the double integral it claims, and (C2) its derivative."""
import casadi as ca
import numpy as np
import pytest
from scipy import integrate

from knit_nlp.weft.model.compression import ACRYLIC, SoftShell

LAWS = [ACRYLIC, SoftShell(1.0, 0.4, 0.3, 2.0), SoftShell(1.0, 0.5, 2.0, 3.0),
        SoftShell(0.5, 0.1, 1.0, 1.5)]


@pytest.mark.parametrize("law", LAWS)
def test_force_is_minus_the_derivative_of_the_energy(law):
    d = np.linspace(2 * law.core_radius + 0.05 * law.shell, 2 * law.radius * 1.1, 40)
    h = 1e-6 * law.shell
    numeric = -(law.energy(d + h) - law.energy(d - h)) / (2 * h)
    assert np.allclose(law.force(d), numeric, rtol=1e-5, atol=1e-9 * law.force(d).max())
    assert law.energy(2 * law.radius) == 0 and law.force(2 * law.radius) == 0
    assert np.isinf(law.energy(2 * law.core_radius))


@pytest.mark.parametrize("law", LAWS)
def test_distance_at_inverts_the_force(law):
    d = np.linspace(2 * law.core_radius + 0.02 * law.shell, 2 * law.radius, 30)
    assert np.allclose(law.distance_at(law.force(d)), d, rtol=1e-10)


@pytest.mark.parametrize("law, alpha", [(ACRYLIC, np.pi / 2), (LAWS[3], 0.7)])
def test_crossing_energy_is_the_double_integral_of_the_density(law, alpha):
    """(C1) against scipy's dblquad over the two yarns' arc lengths (straight yarns crossing at
    alpha, their centrelines h apart along the common normal)."""
    t1 = np.array([1.0, 0.0, 0.0])
    t2 = np.array([np.cos(alpha), np.sin(alpha), 0.0])
    for h in 2 * law.core_radius + law.shell * np.array([0.3, 0.9]):
        reach = 2 * law.radius / np.sin(alpha) * 1.05

        def density(s2, s1):
            gap = s1 * t1 - s2 * t2 + np.array([0.0, 0.0, h])
            return float(law.energy(np.linalg.norm(gap)))
        value, _ = integrate.dblquad(density, -reach, reach, -reach, reach, epsabs=1e-12,
                                     epsrel=1e-7)
        assert law.crossing_energy(h, np.sin(alpha)) == pytest.approx(value, rel=1e-4)


@pytest.mark.parametrize("law", LAWS)
def test_crossing_force_is_minus_the_derivative_and_casadi_agrees(law):
    h = np.linspace(2 * law.core_radius + 0.1 * law.shell, 2 * law.radius * 1.05, 25)
    eps = 1e-6 * law.shell
    numeric = -(law.crossing_energy(h + eps) - law.crossing_energy(h - eps)) / (2 * eps)
    assert np.allclose(law.crossing_force(h), numeric, rtol=1e-5,
                       atol=1e-9 * law.crossing_force(h).max())
    x = ca.SX.sym("h")
    f = ca.Function("E", [x], [law.casadi_crossing_energy(x, 0.8)])
    g = ca.Function("v", [x], [law.casadi_energy(x)])
    assert np.allclose(np.asarray(f(h)).ravel(), law.crossing_energy(h, 0.8), rtol=1e-12)
    assert np.allclose(np.asarray(g(h)).ravel(), law.energy(h), rtol=1e-12, atol=1e-300)


def test_bad_parameters_are_refused():
    for args in [(1.0, 1.2, 1.0, 2.0), (1.0, 0.5, -1.0, 2.0), (1.0, 0.5, 1.0, 1.0)]:
        with pytest.raises(ValueError):
            SoftShell(*args)
