"""The 3-D weft model's geometry (docs/weft3d.md): space curves, bending, the natural 3-D loop,
and the [yarn] keys that switch it on."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from knit_nlp.errors import ProblemError
from knit_nlp.weft.model.basis import bending_diagonal, n_coeffs, phi
from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.model.quadrature import positions
from knit_nlp.weft.model.spatial.curve3d import (bending3d, bending3d_numpy, loop_displacements3d,
                                                  positions3d, segment, symbolic_phi)
from knit_nlp.weft.model.spatial.natural3d import PAIRS
from knit_nlp.weft.model.spatial.natural_fit import gap

L, T, Q = 10.0, 3, 3


def _helix(kappa: float, lift: float) -> tuple[np.ndarray, np.ndarray]:
    """θ = κ s (the basis's linear term), φ = lift (its constant term): a uniform helix."""
    a, b = np.zeros(n_coeffs(T)), np.zeros(n_coeffs(Q))
    a[-2], b[-1] = kappa, lift
    return a, b


def test_helix_positions_and_bending_have_their_closed_forms() -> None:
    """A helix of in-plane turning rate κ and constant elevation φ: x = cos φ sin(κs)/κ,
    y = cos φ (1 − cos κs)/κ, z = s sin φ (S2), and bending ½ B L (cos φ κ)² against a straight
    natural rod (S4) — in numpy, in CasADi's panel rule and in the Gauss segment (S3)."""
    kappa, lift, B = 0.7, 0.4, 2.5
    a, b = _helix(kappa, lift)
    s = np.array([0.0, 1.3, 4.0, 7.7, L])
    exact = np.stack([np.cos(lift) * np.sin(kappa * s) / kappa,
                      np.cos(lift) * (1 - np.cos(kappa * s)) / kappa, s * np.sin(lift)], 1)
    np.testing.assert_allclose(positions3d(a, b, s, L, T, Q), exact, atol=1e-12)
    D = np.asarray(loop_displacements3d(L, T, Q, s, 8)(a, b)).T
    np.testing.assert_allclose(D, exact, atol=1e-12)
    delta, tang = segment(L, T, Q, 8)(a, b, 4.0, 4.9)
    np.testing.assert_allclose(np.asarray(delta).ravel(),
                               positions3d(a, b, [4.9], L, T, Q)[0] - exact[2], atol=1e-12)
    np.testing.assert_allclose(np.asarray(tang).ravel(), [np.cos(lift) * np.cos(kappa * 4.9),
                                                          np.cos(lift) * np.sin(kappa * 4.9),
                                                          np.sin(lift)], atol=1e-14)
    zero_a, zero_b = np.zeros_like(a), np.zeros_like(b)
    closed = 0.5 * B * L * (np.cos(lift) * kappa) ** 2
    assert float(bending3d(L, T, Q, 8)(a, b, zero_a, zero_b, B)) == pytest.approx(closed, rel=1e-12)
    assert bending3d_numpy(a, b, zero_a, zero_b, L, T, Q, B) == pytest.approx(closed, rel=1e-12)


def test_an_elevation_wave_bends_by_its_closed_form() -> None:
    """θ constant, φ = β sin(2πs/L): U_bend = ½ B ∫ φ′² ds = ½ B β² (2π/L)² L/2 (S4)."""
    a, b = np.zeros(n_coeffs(T)), np.zeros(n_coeffs(Q))
    a[-1], b[0] = 0.3, 0.5
    closed = 0.5 * 1.3 * 0.5 ** 2 * (2 * np.pi / L) ** 2 * L / 2
    assert float(bending3d(L, T, Q, 8)(a, b, a, np.zeros_like(b), 1.3)) == pytest.approx(closed, rel=1e-12)


def test_flat_loops_are_the_papers_loops() -> None:
    """φ = 0: positions are eq. (1)'s and bending is eq. (11)'s exact diagonal form."""
    rng = np.random.default_rng(3)
    a, a0 = rng.normal(size=(2, n_coeffs(T)))
    s = np.linspace(0, L, 7)
    np.testing.assert_allclose(positions3d(a, np.zeros(n_coeffs(Q)), s, L, T, Q)[:, :2],
                               positions(a, s, L, T), atol=1e-13)
    exact = 0.5 * 1.7 * bending_diagonal(L, T) @ (a - a0) ** 2
    value = float(bending3d(L, T, Q, 8)(a, np.zeros(n_coeffs(Q)), a0, np.zeros(n_coeffs(Q)), 1.7))
    assert value == pytest.approx(exact, rel=1e-11)


def test_symbolic_basis_is_the_basis() -> None:
    s = ca.SX.sym("s")
    f = ca.Function("f", [s], [symbolic_phi(s, L, T)])
    for v in (0.0, 2.7, L):
        np.testing.assert_allclose(np.asarray(f(v)).ravel(), phi(v, L, T)[0], atol=1e-15)


@pytest.fixture(scope="module")
def problem3d():
    doc = diagonal_pull(3)
    doc["yarn"] = {"radius": 0.15, "geometry": "3d", "elevation_modes": 3}
    return parse_problem(doc, "pull3d.toml")


def test_natural_3d_loop_interlocks_in_the_plain_knit_order(problem3d) -> None:
    """The natural 3-D loop (``natural_fit``, N1-N5): the projections cross at the four designed
    crossings with the upper course's yarn in front (+z) at C/F and Q/G (its legs over the
    head below) and behind at A/D and S/P (its sinker loop under the legs below); each wrap's
    points are closest points (N4) at least g apart; the loop closes on its lattice; for a thin
    yarn the projection stays near the paper's loop."""
    sh = problem3d.yarn.natural3d
    shift = [0.0, sh.course_spacing, 0.0]
    up, low = sh.xyz(sh.cross_upper) + shift, sh.xyz(sh.cross_lower)
    np.testing.assert_allclose(up[:, :2], low[:, :2], atol=1e-7)
    assert [int(np.sign(v)) for v in up[:, 2] - low[:, 2]] == [-1, 1, 1, -1]   # A/D C/F Q/G S/P
    assert [order for _, _, order in PAIRS] == [-1, 1, 1, -1]
    d = sh.xyz(sh.s_upper) + shift - sh.xyz(sh.s_lower)
    tangents = [positions3d(sh.coeffs, sh.elevation, [s + 1e-6], sh.length, sh.harmonics,
                            sh.modes) - positions3d(sh.coeffs, sh.elevation, [s - 1e-6],
                                                    sh.length, sh.harmonics, sh.modes)
                for s in (*sh.s_upper, *sh.s_lower)]
    t = np.concatenate(tangents) / 2e-6
    np.testing.assert_allclose(np.einsum("ki,ki->k", d, t[:2]), 0.0, atol=1e-6)
    np.testing.assert_allclose(np.einsum("ki,ki->k", d, t[2:]), 0.0, atol=1e-6)
    assert np.all(sh.h0 >= gap(0.15, problem3d.yarn.core_radius) - 1e-7)
    np.testing.assert_allclose(sh.separations(), sh.h0, rtol=1e-12)
    end = sh.xyz([sh.length])[0]
    np.testing.assert_allclose(end, [sh.wale_spacing, 0.0, 0.0], atol=1e-8)
    assert sh.projection_rms < 0.05 * sh.length


def test_yarn_keys_are_checked() -> None:
    base = diagonal_pull(3)
    bad = [({"radius": 0.15, "geometry": "curved"}, "geometry"),
           ({"radius": 0.15, "elevation_modes": 3}, 'only with geometry = "3d"'),
           ({"radius": 0.15, "geometry": "3d", "core_radius": 0.2}, "core_radius"),
           ({"radius": 0.15, "geometry": "3d", "contact_exponent": 1.0}, "contact_exponent")]
    for yarn, said in bad:
        with pytest.raises(ProblemError, match=said):
            parse_problem({**base, "yarn": yarn}, "bad.toml")
    with pytest.raises(ProblemError, match="reduced model is planar"):
        parse_problem({**base, "yarn": {"radius": 0.15, "geometry": "3d"},
                       "reduction": {}}, "bad.toml")
    planar = parse_problem({**base, "yarn": {"radius": 0.15}}, "ok.toml")
    assert planar.yarn.geometry == "planar" and planar.yarn.natural3d is None
