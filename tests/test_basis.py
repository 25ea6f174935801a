"""φ(s) of eq. (15) is written once (``basis.basis_terms``): its numbers, its derivative and its
CasADi evaluation against the closed form and against each other."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from knit_nlp.weft.model.basis import basis_at, dbasis_at, dphi, phi
from knit_nlp.weft.transcription.contact import basis_mx

L = 10.0


@pytest.mark.parametrize("t", [1, 2, 3, 6])
def test_the_basis_is_the_closed_form_on_numbers_and_in_casadi(t):
    """φ(u) = (sin 2πku/L, cos 2πku/L (k = 1..t), u, 1) by the recurrence, on numpy arrays of
    any shape and on a CasADi matrix, equals the closed form written out here to 1e-13; dφ/du
    is the closed form's derivative (and central differences of φ)."""
    rng = np.random.default_rng(t)
    u = rng.uniform(-0.5, L + 0.5, (3, 4))
    k = np.arange(1, t + 1)
    arg = 2 * np.pi * u[..., None] * k / L
    want = np.concatenate([np.sin(arg), np.cos(arg), u[..., None], np.ones(u.shape + (1,))], -1)
    np.testing.assert_allclose(basis_at(u, L, t), want, rtol=0, atol=1e-13)
    np.testing.assert_allclose(phi(u[0], L, t), want[0], rtol=0, atol=1e-13)
    om = 2 * np.pi * k / L
    dwant = np.concatenate([om * np.cos(arg), -om * np.sin(arg), np.ones(u.shape + (1,)),
                            np.zeros(u.shape + (1,))], -1)
    np.testing.assert_allclose(dbasis_at(u, L, t), dwant, rtol=0, atol=1e-12)
    h = 1e-6
    fd = (phi(u[0] + h, L, t) - phi(u[0] - h, L, t)) / (2 * h)
    np.testing.assert_allclose(dphi(u[0], L, t), fd, rtol=0, atol=1e-7)
    U = ca.MX.sym("u", *u.shape)
    terms = ca.Function("phi", [U], basis_mx(U, L, t))(u)
    got = np.stack([np.asarray(m) for m in terms], axis=-1)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-13)
