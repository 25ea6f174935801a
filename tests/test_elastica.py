"""A tip-loaded cantilever against the elastica's closed-form large deflection.

Why this setup. The basis (eqs. 14-16) makes θ'(0) = θ'(L) on every loop, and continuity
(eqs. 18-19) makes the curvature equal at every junction of a course. A cantilever clamped at
s = 0 with a dead tip load F has curvature F·ℓ·cos(...)/R_f ≠ 0 at the root and 0 at the free
tip, so no course of one or several loops clamped at its start can converge to it. The
symmetric double cantilever can: one straight loop of length L = 2ℓ, clamped in position and
angle at its middle s = ℓ, with the same force F ⟂ to the yarn at both ends. By the mirror
symmetry each half is a cantilever of length ℓ with a tip load F (the clamp carries 2F and the
two root moments), the curvature vanishes at both free ends, so θ'(0) = θ'(L) = 0 as the basis
requires, and θ' − mean(θ') is continuous and periodic: its Fourier series converges (θ' has a
kink at the clamp, where the shear force jumps, so the coefficients fall off algebraically and
so does the error as the harmonics t grow).

Closed form (dead load P = |F| ⟂ to the undeformed axis, rigidity R_f, ψ the slope, from the
root): R_f ψ'' = −P cos ψ, ψ(0) = 0, ψ'(ℓ) = 0, so R_f ψ'²/2 = P(sin ψ_tip − sin ψ). With
1 + sin ψ = 2k² sin²φ, k² = (1 + sin ψ_tip)/2, φ₁ = arcsin(1/(k√2)):
    √α = K(k) − F(φ₁, k),  α = Pℓ²/R_f,
    δ/ℓ = 1 − (2/√α)(E(k) − E(φ₁, k)),       (deflection along the force)
    x_tip/ℓ = √(2 sin ψ_tip/α).               (projection on the undeformed axis)
For small α, δ/ℓ → α/3 (Euler-Bernoulli, Pℓ³/(3R_f)); checked below.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

from conftest import solve_text

HALF = 10.0        # ℓ, each half of the loop
R_F = 1.0
ALPHA = 2.0        # Pℓ²/R_f: a large deflection (tip slope 44.8 degrees)


def cantilever_tip(alpha: float) -> tuple[float, float, float]:
    """(δ/ℓ, x_tip/ℓ, ψ_tip) of the elastica cantilever with a dead tip load, α = Pℓ²/R_f."""
    def gap(m: float) -> float:
        phi1 = np.arcsin(np.sqrt(1.0 / (2.0 * m)))
        return ellipk(m) - ellipkinc(phi1, m) - np.sqrt(alpha)
    m = brentq(gap, 0.5 + 1e-15, 1.0 - 1e-15)
    phi1 = np.arcsin(np.sqrt(1.0 / (2.0 * m)))
    delta = 1.0 - 2.0 / np.sqrt(alpha) * (ellipe(m) - ellipeinc(phi1, m))
    psi_tip = np.arcsin(2.0 * m - 1.0)
    return delta, np.sqrt(2.0 * np.sin(psi_tip) / alpha), psi_tip


def test_closed_form_reduces_to_euler_bernoulli():
    """Small loads: δ/ℓ = α/3 − (4/105)·α³ + ... (the first nonlinear correction, from a
    regular expansion ψ = αψ₁ + α³ψ₃, ψ₁ = s − s²/2: −(2/3)∫ψ₁³ = −4/105), x_tip/ℓ = 1 − α²/15,
    the tip slope α/2; and Bisshopp & Drucker's tabulated δ/ℓ = 0.3017 at α = 1."""
    for alpha in (1e-3, 1e-2, 0.05):
        delta, x_tip, psi = cantilever_tip(alpha)
        assert delta == pytest.approx(alpha / 3 - 4 / 105 * alpha ** 3, rel=1e-6, abs=1e-12)
        assert psi == pytest.approx(alpha / 2, rel=1e-3)
        assert x_tip == pytest.approx(1 - alpha ** 2 / 15, rel=1e-4)
    assert cantilever_tip(1.0)[0] == pytest.approx(0.3017, abs=1e-4)


def _double_cantilever(write_problem, t: int):
    P = ALPHA * R_F / HALF ** 2
    return solve_text(write_problem(f"""
        [fabric]
        courses = 1
        wales = 1
        [loop]
        preset = "straight"
        length = {2 * HALF}
        harmonics = {t}
        quadrature_nodes = 16
        [material]
        R_f = {R_F}
        [[clamp]]
        loop = [1, 1]
        point = {HALF}
        displacement = [0.0, 0.0]
        angle = 0.0
        [[load]]
        loop = [1, 1]
        point = "start"
        force = [0.0, {-P}]
        [[load]]
        loop = [1, 1]
        point = "end"
        force = [0.0, {-P}]
        """, f"cantilever{t}.toml"))


def test_tip_loaded_cantilever_converges_to_the_elastica(write_problem):
    delta, x_tip, _ = cantilever_tip(ALPHA)
    assert ALPHA / 3 - delta > 0.1          # far from the linear result: the nonlinear regime
    errors = []
    for t in (2, 4, 8, 16):
        s = _double_cantilever(write_problem, t)
        assert s.success, s.report.attempts
        start, end = (ld.position for ld in s.loads)
        mid = s.clamps[0].position
        # mirror symmetry about the clamp; both tips move along the force (downwards)
        np.testing.assert_allclose(start[1], end[1], atol=1e-8)
        np.testing.assert_allclose(mid[0] - start[0], end[0] - mid[0], atol=1e-8)
        err = max(abs((mid[1] - end[1]) / HALF - delta), abs((end[0] - mid[0]) / HALF - x_tip))
        errors.append(err)
    assert all(a > 4 * b for a, b in zip(errors, errors[1:])), errors   # about t^-3
    assert errors[-1] < 1e-5, errors
