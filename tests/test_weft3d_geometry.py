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
from knit_nlp.weft.model.spatial.natural3d import PAIRS, WRAPS
from knit_nlp.weft.model.spatial.natural_fit import gap, natural_check, touching

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


def test_natural_3d_loop_touches_in_the_plain_knit_order(problem3d) -> None:
    """At every designed crossing the closest points are 2r apart, the upper course's yarn is
    in front (+z) at C/F and Q/G (its legs over the head below) and behind at A/D and S/P (its
    sinker loop under the legs below); the loop closes on the planar lattice."""
    sh = problem3d.yarn.natural3d
    np.testing.assert_allclose(sh.separations(), 2 * 0.15, rtol=1e-9)
    up = sh.xyz(sh.s_upper) + [0.0, sh.course_spacing, 0.0]
    dz = up[:, 2] - sh.xyz(sh.s_lower)[:, 2]
    assert [np.sign(v) for v in dz] == [-1, 1, 1, -1]       # A/D, C/F, Q/G, S/P
    assert [order for _, _, order in PAIRS] == [-1, 1, 1, -1]
    end = sh.xyz([sh.length])[0]
    np.testing.assert_allclose(end, [problem3d.natural.wale_spacing, 0.0, 0.0], atol=1e-9)
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


def test_a_thick_yarn_wraps_where_touching_crossings_pass_through_each_other() -> None:
    """The acrylic (L = 11.28 mm, r = 0.74 mm, core 0.325 mm): four closest-point pairs touching
    at the crossings of the projections (``natural_fit.touching``) sit on saddle points of the
    distance, and the independent all-pairs check finds the yarns inside the core between them
    (0.028 mm apart); the natural loop the problem gets instead has two wraps per loop, each a
    pair of closest points (N4) at least g apart, the projections crossing in the plain-knit
    order (N3), and the check calls four courses of four loops clean (N5)."""
    doc = {"fabric": {"courses": 2, "wales": 2}, "loop": {"length": 11.28},
           "yarn": {"radius": 0.74, "geometry": "3d", "elevation_modes": 4}}
    pr = parse_problem(doc, "acrylic3d.toml")
    core = pr.yarn.core_radius
    cr = pr.crossings
    four = touching(pr.natural.coeffs.tobytes(), pr.L, pr.t, 4, 0.74, pr.natural.wale_spacing,
                    pr.natural.course_spacing, tuple(float(cr.s[u]) for u, _, _ in PAIRS),
                    tuple(float(cr.s[lo]) for _, lo, _ in PAIRS))
    bad = natural_check(four, core)
    assert not bad.ok and bad.smallest < 0.1 < 2 * core
    sh = pr.yarn.natural3d
    assert sh.labels == WRAPS and sh.s_upper.size == 2
    rep = natural_check(sh, core)
    assert rep.ok and rep.n_designed == 4 * 3 * 4 and rep.smallest >= 2 * core
    assert np.all(sh.h0 >= gap(0.74, core) - 1e-7)
    shift = [0.0, sh.course_spacing, 0.0]
    up, low = sh.xyz(sh.cross_upper) + shift, sh.xyz(sh.cross_lower)
    np.testing.assert_allclose(up[:, :2], low[:, :2], atol=1e-7)
    assert [int(np.sign(v)) for v in up[:, 2] - low[:, 2]] == [-1, 1, 1, -1]   # A/D C/F Q/G S/P
    h = 1e-6
    d = sh.xyz(sh.s_upper) + shift - sh.xyz(sh.s_lower)
    for s in (sh.s_upper, sh.s_lower):
        t = (sh.xyz(s + h) - sh.xyz(s - h)) / (2 * h)
        np.testing.assert_allclose(np.einsum("ki,ki->k", d, t), 0.0, atol=1e-6)
    np.testing.assert_allclose(sh.xyz([sh.length])[0], [sh.wale_spacing, 0.0, 0.0], atol=1e-8)
