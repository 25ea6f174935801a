"""A designed crossing as a persistent sliding contact (docs/weft3d.md, S5-S7), on two straight
yarns where the answers are closed forms of the compression law (``compression``, C1-C2).

The yarns are the model's own curves (``curve3d.segment``, a constant θ and φ = 0) and the
crossing its own terms (``crossing_contact.crossing_terms``): closest-point rows, the signed
separation and the soft-shell crossing energy.
"""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from knit_nlp.weft.model.basis import n_coeffs
from knit_nlp.weft.model.compression import ACRYLIC
from knit_nlp.weft.model.spatial.crossing_contact import crossing_terms
from knit_nlp.weft.model.spatial.curve3d import segment

L, T, Q = 10.0, 1, 2
ALPHA = np.pi / 3              # the crossing angle (sin α ≠ 1, so 1/sin α matters)


def _yarn(angle: float) -> tuple[np.ndarray, np.ndarray]:
    a = np.zeros(n_coeffs(T))
    a[-1] = angle
    return a, np.zeros(n_coeffs(Q))


def _crossing(push: float | None, z_held: float | None, slide: float = 0.0) -> dict:
    """Upper yarn along x at height z, lower yarn at angle α through the origin in z = 0.
    Either a load ``push`` presses the upper yarn down (work −push·z) or its height is held
    at ``z_held`` (the row z − z_held, whose multiplier is the reaction). ``slide`` moves the
    upper yarn's start along its own axis."""
    seg = segment(L, T, Q, 8)
    terms = crossing_terms(ACRYLIC)
    z, su, sl = ca.SX.sym("z"), ca.SX.sym("su"), ca.SX.sym("sl")
    au, bu = _yarn(0.0)
    al, bl = _yarn(ALPHA)
    start_u = ca.vertcat(-L / 2 + slide, 0.0, z)
    start_l = ca.DM([-L / 2 * np.cos(ALPHA), -L / 2 * np.sin(ALPHA), 0.0])
    du, tu = seg(au, bu, 0.0, su)
    dl, tl = seg(al, bl, 0.0, sl)
    energy, rows, h, _ = terms(start_u + du, tu, start_l + dl, tl, 1.0, 1.0)
    g, f = rows, energy
    if push is not None:
        f = energy + push * z
    if z_held is not None:
        g = ca.vertcat(rows, z - z_held)
    x = ca.vertcat(z, su, sl)
    solver = ca.nlpsol("c", "ipopt", {"x": x, "f": f, "g": g},
                       {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-12}})
    sol = solver(x0=[2 * ACRYLIC.radius, L / 2, L / 2], lbg=0, ubg=0)
    assert solver.stats()["success"]
    xs = np.asarray(sol["x"]).ravel()
    hval = float(ca.Function("h", [x], [h])(xs))
    return {"z": xs[0], "su": xs[1], "sl": xs[2], "h": hval, "f": float(sol["f"]),
            "lam": np.asarray(sol["lam_g"]).ravel(), "energy": float(ca.Function("e", [x], [energy])(xs))}


def test_a_pressed_yarn_stops_where_the_law_says() -> None:
    """A push F on the upper yarn: it settles where F(h, α) = F (eq. C2), at the crossing's
    closest points (σ at the two yarns' common point), h = z."""
    push = 0.002
    got = _crossing(push, None)
    assert got["h"] == pytest.approx(got["z"], rel=1e-12)
    assert float(ACRYLIC.crossing_force(got["h"], np.sin(ALPHA))) == pytest.approx(push, rel=1e-8)
    assert 2 * ACRYLIC.core_radius < got["h"] < 2 * ACRYLIC.radius
    assert got["su"] == pytest.approx(L / 2, abs=1e-9) and got["sl"] == pytest.approx(L / 2, abs=1e-9)


def test_the_reaction_equals_the_push() -> None:
    """Held at a height z inside the shell, the holding row's reaction (minus its multiplier)
    is the law's crossing force at h = z (eq. C2)."""
    z = 1.2
    got = _crossing(None, z)
    assert got["h"] == pytest.approx(z, rel=1e-12)
    assert -got["lam"][-1] == pytest.approx(-float(ACRYLIC.crossing_force(z, np.sin(ALPHA))), rel=1e-8)


def test_a_yarn_slides_through_a_frictionless_crossing() -> None:
    """Moving the upper yarn along its own axis by δ at a held, pressed height: the contact's
    material coordinate on it moves by −δ, on the lower yarn not at all, and the energy does not
    change (no friction, no spring along the yarn)."""
    z, delta = 1.25, 0.8
    before, after = _crossing(None, z), _crossing(None, z, slide=delta)
    assert before["energy"] > 1e-6
    assert after["su"] - before["su"] == pytest.approx(-delta, abs=1e-9)
    assert after["sl"] == pytest.approx(before["sl"], abs=1e-9)
    assert after["energy"] == pytest.approx(before["energy"], rel=1e-10)
