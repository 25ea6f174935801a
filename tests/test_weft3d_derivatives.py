"""The 3-D NLP's element-assembled derivatives (transcription/elements.py) against CasADi's AD
of the same NLP, exactly (rounding), at random points; and the assembly's contract on a toy
NLP (an unregistered term falls back to AD; a non-affine use of an output is refused; a lifted
block condensed away has the condensed NLP's derivatives)."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.transcription.elements import (Elements, NotElementwise,
                                                   condensed_derivatives, element_derivatives)
from knit_nlp.weft.transcription.spatial import Spatial, build_spatial

PULL_3x2 = {"fabric": {"courses": 3, "wales": 2},
            "loop": {"length": 11.28, "harmonics": 3}, "material": {"R_f": 0.045},
            "yarn": {"radius": 0.74, "geometry": "3d", "elevation_modes": 4},
            "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                      {"loop": [1, 2], "point": "H", "displacement": [1.0, 0.8]}],
            "load": [{"loop": [3, 1], "point": "C", "force": [0.01, 0.02]}]}


def _ad(nlp: dict) -> tuple[ca.Function, ca.Function]:
    x, p, f, g = nlp["x"], nlp["p"], nlp["f"], nlp["g"]
    lf, lg = ca.MX.sym("lf"), ca.MX.sym("lg", g.numel())
    jac = ca.Function("ad_jac", [x, p], [ca.jacobian(g, x)])
    hess = ca.Function("ad_hess", [x, p, lf, lg],
                       [ca.triu(ca.hessian(lf * f + ca.dot(lg, g), x)[0])])
    return jac, hess


def _compare(jac, hess, opts, x, p, lf, lg) -> tuple[float, float]:
    """Largest relative difference of the Jacobian and the Hessian's upper triangle."""
    J1, J2 = jac(x, p), opts["jac_g"](x, p)[1]
    H1, H2 = hess(x, p, lf, lg), opts["hess_lag"](x, p, lf, lg)
    dj = float(ca.mmax(ca.fabs(ca.densify(J1 - J2)))) / float(ca.mmax(ca.fabs(J1)))
    dh = float(ca.mmax(ca.fabs(ca.densify(H1 - H2)))) / float(ca.mmax(ca.fabs(H1)))
    return dj, dh


@pytest.mark.parametrize("options", [Spatial(), Spatial(springs=True),
                                     Spatial(elevation=False, contacts=False, springs=True)])
def test_element_derivatives_equal_casadis_ad(options: Spatial) -> None:
    """Jacobian of the rows and Lagrangian Hessian, assembled per loop, crossing side and
    crossing (with the paper's springs too, and in the paper's limit, φ frozen: there the
    loops' closed-form Hessians give way to AD), equal CasADi's AD of the whole NLP to rounding
    at random points away from the natural state, random multipliers and λ_f."""
    pr = parse_problem(PULL_3x2, "pull3x2.toml")
    el = build_spatial(pr, options)
    ad = build_spatial(pr, Spatial(options.elevation, options.contacts, options.springs,
                                   derivatives="casadi"))
    assert "hess_lag" in el.nlpsol_options and "hess_lag" not in ad.nlpsol_options
    jac, hess = _ad(ad.nlp)
    rng = np.random.default_rng(3)
    p = ad.params.vector() * (1 + 0.1 * rng.normal(size=ad.params.vector().size))
    for _ in range(2):
        x = ad.x0 + 0.05 * rng.normal(size=ad.x.size)
        dj, dh = _compare(jac, hess, el.nlpsol_options, x, p, rng.uniform(0.5, 2),
                          rng.normal(size=ad.g.size))
        assert dj < 1e-12 and dh < 1e-12


def _toy(extra: bool, misuse: bool = False):
    """Two loops' worth of a toy: an element F(v) = (v0² v1, sin v1) mapped over 3 instances
    on x[0:6], energy = Σ first outputs (+ an unregistered x[6]³ when ``extra``), rows
    = second outputs + x[6]."""
    x, p = ca.MX.sym("x", 7), ca.MX.sym("p", 1)
    v = ca.SX.sym("v", 2)
    fn = ca.Function("F", [v], [v[0] ** 2 * v[1], ca.sin(v[1]) * v[0]])
    els = Elements()
    out = els.call("toy", fn, 3, ca.reshape(x[0:6], 2, 3))
    f = ca.sum2(out[0]) + p * x[6] + (x[6] ** 3 if extra else 0)
    g = out[1].T + x[6]
    if misuse:
        f = f + out[0][0] ** 2
    return x, p, f, g, els


def test_an_unregistered_term_falls_back_to_ad() -> None:
    """A nonlinear term written directly in x (not an element) is differentiated by AD and
    added: the toy's derivatives equal CasADi's."""
    x, p, f, g, els = _toy(extra=True)
    opts = element_derivatives(x, p, f, g, els, 7)
    jac, hess = _ad({"x": x, "p": p, "f": f, "g": g})
    rng = np.random.default_rng(1)
    dj, dh = _compare(jac, hess, opts, rng.normal(size=7), 1.3, 0.7, rng.normal(size=3))
    assert dj < 1e-14 and dh < 1e-14


def test_a_nonaffine_use_of_an_output_is_refused() -> None:
    x, p, f, g, els = _toy(extra=False, misuse=True)
    with pytest.raises(NotElementwise, match="not affine"):
        element_derivatives(x, p, f, g, els, 7)


def _lifted_toy(g_uses_y: bool = False):
    """x = (z (4), y (4)): y = Y(z), two instances of an element Y_m(v) = (v0 sin v1,
    cos(v0) v1) on z, used by f only through f_y = Σ y² y_next (+ z's own terms); rows in z."""
    x, p = ca.MX.sym("x", 8), ca.MX.sym("p", 1)
    v = ca.SX.sym("v", 2)
    els = Elements()
    Y = els.call("samples", ca.Function("Y", [v], [ca.vertcat(v[0] * ca.sin(v[1]),
                                                             ca.cos(v[0]) * v[1])]),
                 2, ca.reshape(x[0:4], 2, 2))[0]
    y = x[4:8]
    f_y = ca.sum1(y ** 2 * ca.vertcat(y[1:], y[0])) + p * ca.exp(y[2])
    f = f_y + x[0] ** 2 * x[3] + p * x[2]
    g = ca.vertcat(x[0] * x[1] - x[2], ca.sin(x[3]) + (y[0] if g_uses_y else 0))
    return x, p, f, g, els, Y, f_y


def test_a_condensed_block_has_the_condensed_nlps_derivatives() -> None:
    """The lifted block y = Y(z) substituted (``condensed_derivatives``): Jacobian and
    Lagrangian Hessian in z equal CasADi's AD of f(z, Y(z)), g(z) at random points, and the
    returned x(z) is (z, Y(z))."""
    x, p, f, g, els, Y, f_y = _lifted_toy()
    z, xz, opts = condensed_derivatives(x, p, f, g, els, 4, Y, f_y)
    fz, gz = ca.Function("fg", [x, p], [f, g])(xz, p)
    jac, hess = _ad({"x": z, "p": p, "f": fz, "g": gz})
    rng = np.random.default_rng(5)
    for _ in range(3):
        zv = rng.normal(size=4)
        dj, dh = _compare(jac, hess, opts, zv, 1.3, rng.uniform(0.5, 2), rng.normal(size=2))
        assert dj < 1e-14 and dh < 1e-13
    zv = rng.normal(size=4)
    Yv = ca.Function("Y", [x], [ca.vec(Y)])(np.r_[zv, np.zeros(4)]).full().ravel()
    assert np.allclose(ca.Function("xz", [z], [xz])(zv).full().ravel(), np.r_[zv, Yv],
                       rtol=0, atol=1e-15)


def test_a_block_the_rows_use_cannot_be_condensed() -> None:
    x, p, f, g, els, Y, f_y = _lifted_toy(g_uses_y=True)
    with pytest.raises(NotElementwise, match="used by g"):
        condensed_derivatives(x, p, f, g, els, 4, Y, f_y)
    x, p, f, g, els, Y, f_y = _lifted_toy()
    with pytest.raises(NotElementwise, match="outside the terms"):
        condensed_derivatives(x, p, f + x[5] ** 3, g, els, 4, Y, f_y)
