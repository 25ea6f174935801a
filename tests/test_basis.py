"""φ(s) of eq. (15) is written once (``basis.basis_terms``): its numbers, its derivative and its
CasADi evaluation against the closed form and against each other. The integrals of eq. (1) by a
fixed rule are written once too (``quadrature.rule_integrals``): by panels and by cells, the
numbers and the CasADi expressions the NLPs use agree, and both converge to the integral; so
does the cell rule's partial cell (``curves.partial_cell``), written once for both."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from knit_nlp.weft.model.basis import basis_at, dbasis_at, dphi, n_coeffs, phi
from knit_nlp.weft.model.contact.curves import Curves, cell_of, cells, partial_cell
from knit_nlp.weft.model.kinematics import LoopIntegrals, loop_displacements
from knit_nlp.weft.model.quadrature import positions
from knit_nlp.weft.transcription.contact import _Cells, basis_mx

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


def test_the_integrals_of_eq_1_by_panels_and_by_cells_agree_in_numbers_and_casadi():
    """Random loops (t = 3): the panel rule's displacements to material points as numbers
    (``LoopIntegrals``) and as the full NLP's CasADi Function (``loop_displacements``) agree to
    1e-13, the cells' increments as numbers (``Curves``) and as the contact rows' CasADi
    expressions (``_Cells``) too, and both rules give the fine reference (``positions``)."""
    t, N = 3, 5
    rng = np.random.default_rng(7)
    A = rng.normal(0.0, 0.4, (N, n_coeffs(t)))
    A[:, 0] += 2.0                                          # the jersey's θ = 2 sin(2πs/L)
    s = np.array([1.3, 4.0, 7.7, L])
    _, D = LoopIntegrals(L, t, s, 12).values(A)             # N × P × 2
    fn = loop_displacements(L, t, s, 12)
    cas = np.stack([np.asarray(fn(a)).T for a in A])
    np.testing.assert_allclose(D, cas, rtol=0, atol=1e-13)
    np.testing.assert_allclose(D, positions(A, s, L, t, 48), rtol=0, atol=1e-8)
    curves = Curves(A, np.zeros((N, 2)), L, t)
    sym = ca.MX.sym("A", n_coeffs(t), N)
    cells = _Cells(sym, L, t)
    inc = ca.Function("inc", [sym], [cells.dx, cells.dy])(A.T)
    prefix = np.cumsum(np.stack([np.asarray(inc[0]).T, np.asarray(inc[1]).T], -1), axis=1)
    np.testing.assert_allclose(curves.prefix[:, 1:], prefix, rtol=0, atol=1e-13)
    ends = positions(A, np.linspace(0, L, prefix.shape[1] + 1)[1:], L, t, 48)
    np.testing.assert_allclose(prefix, ends, rtol=0, atol=1e-7)


def test_the_partial_cell_is_one_definition_in_numbers_and_casadi():
    """The partial cell [s_j, s] of the cell rule (``curves.partial_cell``) as numbers (what
    ``Curves.points`` adds to the whole cells) and as the CasADi expressions of the contact
    rows (``transcription.contact``) agree to 1e-13, for points inside cells, on a cell's
    start and just outside [0, L] (feet past a loop's end); the integral is a 40-node
    Gauss-Legendre rule's on [s_j, s] (an independent evaluation of eq. 1) to 1e-8 (the 8-node
    rule's error, ``curves.cells``), and
    ``Curves.points`` is the loops' start plus the whole cells and this part."""
    t, n = 3, 9
    rng = np.random.default_rng(11)
    A = rng.normal(0.0, 0.4, (n_coeffs(t), n))
    A[0] += 2.0                                             # the jersey's θ = 2 sin(2πs/L)
    s = np.concatenate([rng.uniform(0, L, n - 3), [-0.3, L + 0.3, 2 * L / cells(t)]])
    start = cell_of(s, L, t) * (L / cells(t))
    num = partial_cell(start[None], s[None], A, L, t, np.sin, np.cos, np.matmul,
                       lambda v, q: v)
    S0, S, AA = ca.MX.sym("s0", 1, n), ca.MX.sym("s", 1, n), ca.MX.sym("A", n_coeffs(t), n)
    sym = partial_cell(S0, S, AA, L, t, ca.sin, ca.cos, ca.mtimes,
                       lambda v, q: ca.repmat(v, q, 1))
    fn = ca.Function("part", [S0, S, AA], [sym.length, sym.cos, sym.sin, sym.dx, sym.dy,
                                            *sym.terms])
    got = [np.asarray(v) for v in fn(start[None], s[None], A)]
    want = [num.length, num.cos, num.sin, num.dx, num.dy, *num.terms]
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, np.broadcast_to(w, g.shape), rtol=0, atol=1e-13)
    x, w = np.polynomial.legendre.leggauss(40)
    u = start + (s - start) * (x[:, None] + 1) / 2                   # 40 × n
    theta = np.einsum("qnc,cn->qn", basis_at(u, L, t), A)
    ref = (s - start) / 2 * np.stack([w @ np.cos(theta), w @ np.sin(theta)])
    part = np.vstack([num.dx, num.dy])
    np.testing.assert_allclose(part, ref, rtol=0, atol=1e-8)     # the cell rule's error
    curves = Curves(A.T, rng.normal(size=(n, 2)), L, t)
    k = np.arange(n)
    points = curves.starts + curves.prefix[k, cell_of(s, L, t)] + part.T
    np.testing.assert_allclose(curves.points(k, s), points, rtol=0, atol=1e-13)
