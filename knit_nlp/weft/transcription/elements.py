"""Derivatives of an NLP assembled element by element, handed to IPOPT instead of CasADi's AD
of the whole graph (the 3-D weft model's, docs/weft3d.md "Cost").

An NLP built from *element calls*: each a small SX Function F_e (one loop's displacements, one
crossing side's segment, one crossing's energy and closest-point rows, one loop's bending, ...)
mapped over M_e instances whose inputs are either selections of the decision vector x or
quantities without x (constants, parameters). If f and g are affine in the elements' outputs
Y_e and separable (no product of x and Y), i.e.

    f = f₀(x, p) + Σ_e c_eᵀ vec(Y_e),     g = g₀(x, p) + Σ_e G_e vec(Y_e),

with c_e, G_e constant, then with the multipliers μ_e = λ_f c_e + G_eᵀ λ_g of the outputs

    ∂g/∂x = ∂g₀/∂x + Σ_e G_e ∂Y_e/∂x,
    ∇²_x (λ_f f + λ_gᵀ g) = ∇²_x (λ_f f₀ + λ_gᵀ g₀) + Σ_e Σ_m S_mᵀ ∇²_v (μ_{e,m}·F_e(v_m)) S_m,

v_m the m-th instance's local variables, S_m their selection from x. Every instance's local
Jacobian and Hessian is one small SX Function evaluated by ``map``; the sums are one constant
sparse matrix (numpy/scipy, built once) applied to the stacked local nonzeros. The part of f and
g outside the elements (f₀, g₀: loads, affine rows, or a term written directly in MX) keeps
CasADi's AD, so a new energy term is correct whether or not it is registered as an element
(registered, it is cheap). An NLP that is not of this form is refused (``NotElementwise``).

A lifted block that only f uses (y = Y(z) with rows y − Y(z) = 0) can be condensed away
(:func:`condensed_derivatives`): the NLP in z alone, its derivatives the lifted ones mapped by
the chain rule.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

import casadi as ca
import numpy as np

if TYPE_CHECKING:                 # scipy is imported where an NLP is built (tests/test_imports.py)
    import scipy.sparse as sp


# common subexpressions merged in the elements' AD Functions (exact: measured on a crossing
# side's segment Hessian, 7 984 -> 7 103 operations, 0.052 -> 0.037 s per 3 000 instances)
CSE = {"cse": True}


class NotElementwise(ValueError):
    """f or g is not affine and separable in the elements' outputs (module docstring)."""


@dataclass
class Element:
    """One mapped call: the single-instance Function, its instance count, the mapped call's
    inputs (MX or DM: x selections, parameters, constants) and outputs (MX)."""

    name: str
    fn: ca.Function
    count: int
    args: list
    outputs: list
    hessian: Callable | None = None     # (args, multipliers) -> (nonzeros × M, rows, cols)
    jacobian: Callable | None = None    # (args) -> (nonzeros × M, output rows, cols): output 0


@dataclass
class Elements:
    """The element calls of one NLP, in the order made (:meth:`call`)."""

    items: list[Element] = field(default_factory=list)

    def call(self, name: str, fn: ca.Function, count: int, *args,
             hessian: Callable | None = None, jacobian: Callable | None = None) -> list[ca.MX]:
        """Map ``fn`` over ``count`` instances on ``args`` (as ``fn.map(count)``) and record the
        call; returns its outputs. ``hessian``: the instances' local Lagrangian Hessians in
        closed form, (args, the outputs' multipliers) -> (upper-triangle nonzeros × count,
        their local rows, columns), instead of CasADi's AD of ``fn``; used when the inputs
        that depend on x are exactly its ``variables`` (input indices), AD otherwise;
        ``jacobian`` likewise, (args) -> the first output's Jacobian nonzeros × count, their
        local rows (in the output's column-major order) and columns."""
        outs = fn.map(count, "serial")(*args)
        outs = list(outs) if isinstance(outs, (list, tuple)) else [outs]
        self.items.append(Element(name, fn, count, list(args), outs, hessian, jacobian))
        return outs


def element_derivatives(x: ca.MX, p: ca.MX, f: ca.MX, g: ca.MX, elements: Elements,
                        nx: int, want: tuple[str, ...] = ("jac_g", "hess_lag")
                        ) -> dict[str, ca.Function]:
    """``jac_g`` and ``hess_lag`` Functions for ``casadi.nlpsol`` (module docstring); only
    those in ``want`` are built (each assembly costs set-up time and memory)."""
    used = [(e, o) for e in elements.items for o in range(len(e.outputs))]
    Y = [ca.MX.sym(f"{e.name}_{o}", *e.outputs[o].shape) for e, o in used]
    outs = [e.outputs[o] for e, o in used]
    f_s, g_s = ca.graph_substitute([f, g], outs, Y)
    yv = ca.vertcat(*[ca.vec(y) for y in Y])
    cf, Gy = _constant_coefficients(f_s, g_s, x, p, yv)
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.numel())

    jac_parts, hess_parts = [], []
    offset = 0
    mu_all = lam_f * ca.DM(cf) + ca.mtimes(_to_dm(Gy.T.tocsc()), lam_g) if yv.numel() else ca.MX(0, 1)
    for e in elements.items:
        local = _Local(e, x, p, nx)
        sizes = [y.numel() for y in e.outputs]
        starts = offset + np.concatenate([[0], np.cumsum(sizes)])
        offset = starts[-1]
        need_h = [bool(np.any(cf[starts[o]:starts[o + 1]]) or
                       Gy[:, starts[o]:starts[o + 1]].nnz) for o in range(len(e.outputs))]
        need_j = [bool(Gy[:, starts[o]:starts[o + 1]].nnz) for o in range(len(e.outputs))]
        if any(need_j) and "jac_g" in want:
            jac_parts.append(local.jacobian(need_j, Gy, starts))
        if any(need_h) and "hess_lag" in want:
            mus = [ca.reshape(mu_all[int(starts[o]):int(starts[o + 1])], *e.outputs[o].shape)
                   for o in range(len(e.outputs))]
            hess_parts.append(local.hessian(need_h, mus))

    # the rest (f0, g0) by CasADi's AD; separable, so evaluated with the outputs' own values
    out = {}
    if "jac_g" in want:
        G0 = ca.graph_substitute(ca.jacobian(g_s, x), Y, outs)
        jac = _assemble(g.numel(), nx, jac_parts, G0)
        out["jac_g"] = ca.Function("nlp_jac_g", [x, p], [g, jac], ["x", "p"], ["g", "jac_g_x"])
    if "hess_lag" in want:
        lag0 = lam_f * f_s + ca.dot(lam_g, g_s)
        H0 = ca.graph_substitute(ca.triu(ca.hessian(lag0, x)[0]), Y, outs)
        out["hess_lag"] = ca.Function("nlp_hess_l", [x, p, lam_f, lam_g],
                                      [_assemble(nx, nx, hess_parts, H0)],
                                      ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    return out


def _constant_coefficients(f_s: ca.MX, g_s: ca.MX, x: ca.MX, p: ca.MX, yv: ca.MX
                           ) -> tuple[np.ndarray, sp.csc_matrix]:
    """c (dense, len Y) and G (sparse, ng × len Y): ∂f/∂Y and ∂g/∂Y, refused unless constant
    and unless ∂f/∂x, ∂g/∂x do not depend on Y."""
    import scipy.sparse as sp    # with a 3-D build, not at start-up
    if yv.numel() == 0:
        return np.zeros(0), sp.csc_matrix((g_s.numel(), 0))
    jf, jg = ca.jacobian(f_s, yv), ca.jacobian(g_s, yv)
    every = ca.vertcat(x, p, yv)
    if ca.depends_on(jf, every) or ca.depends_on(jg, every):
        raise NotElementwise("f or g is not affine in the elements' outputs")
    if ca.depends_on(ca.jacobian(f_s, x), yv) or ca.depends_on(ca.jacobian(g_s, x), yv):
        raise NotElementwise("f or g multiplies the decision variables by an element output")
    fn = ca.Function("coefficients", [], [jf, jg])
    cf, cg = fn.call([])
    return np.asarray(ca.densify(cf)).ravel(), _to_scipy(cg)


def _to_dm(A: sp.spmatrix) -> ca.DM:
    import scipy.sparse as sp    # with a 3-D build, not at start-up
    A = sp.csc_matrix(A)
    A.sum_duplicates()
    A.sort_indices()
    return ca.DM(ca.Sparsity(A.shape[0], A.shape[1], A.indptr.tolist(), A.indices.tolist()),
                 A.data.tolist())


def _to_scipy(m: ca.DM) -> sp.csc_matrix:
    import scipy.sparse as sp    # with a 3-D build, not at start-up
    s = m.sparsity()
    return sp.csc_matrix((np.asarray(m.nonzeros()), s.row(), s.colind()), shape=m.shape)


class _Local:
    """One element's instances: local variables (x selections) and their derivative maps."""

    def __init__(self, e: Element, x: ca.MX, p: ca.MX, nx: int) -> None:
        self.e = e
        M = e.count
        self.sx_in = [ca.SX.sym(f"in{i}", *e.fn.size_in(i)) for i in range(e.fn.n_in())]
        self.sx_out = e.fn.call(self.sx_in)
        self.var = [i for i, a in enumerate(e.args) if isinstance(a, ca.MX) and ca.depends_on(a, x)]
        idx = []
        for i in self.var:
            a = e.args[i]
            r, c = e.fn.size_in(i)
            if a.shape != (r, c * M) or ca.depends_on(a, p):
                raise NotElementwise(f"{e.name}: input {i} is not a selection of x per instance")
            sel = ca.Function("sel", [x], [a])
            base = np.arange(1, nx + 1, dtype=float)
            v1 = np.asarray(sel(base)).reshape(r, c * M, order="F")
            if not np.allclose(np.asarray(sel(2 * base)).reshape(r, c * M, order="F"), 2 * v1) \
                    or not np.allclose(v1, np.round(v1)):
                raise NotElementwise(f"{e.name}: input {i} is not a selection of x")
            idx.append(np.round(v1).astype(int).reshape(r, c, M, order="F").reshape(r * c, M, order="F") - 1)
        self.idx = np.vstack(idx) if idx else np.zeros((0, M), dtype=int)   # local var × instance
        self.v = ca.vertcat(*[ca.vec(self.sx_in[i]) for i in self.var])

    def jacobian(self, need: list[bool], Gy: sp.csc_matrix, starts: np.ndarray):
        """The needed outputs' local Jacobian nonzeros (MX, instance-major) and, for every
        nonzero of G_Y ∂Y/∂x they make, its global (row, column), source nonzero and
        coefficient (the ``_assemble`` part)."""
        import scipy.sparse as sp    # with a 3-D build, not at start-up
        e, M = self.e, self.e.count
        closed = e.jacobian is not None and tuple(self.var) == e.jacobian.variables
        parts, yidx, cols = [], [], []
        for o, want in enumerate(need):
            if not want:
                continue
            if closed and o == 0:
                vals, jr, jc = e.jacobian(e.args)
            else:
                J = ca.jacobian(ca.vec(self.sx_out[o]), self.v)
                jr, jc = J.sparsity().get_triplet()
                fn = ca.Function(f"{e.name}_jac{o}", self.sx_in, [ca.vertcat(*J.nonzeros())],
                                 CSE)
                vals = fn.map(M, "serial")(*self.e.args)
            parts.append(vals)                                            # nnz × M
            size = self.sx_out[o].numel()
            # global Y index and x column of every (instance, nonzero), instance-major
            m = np.arange(M)[:, None]
            yidx.append((starts[o] + m * size + np.asarray(jr)[None, :]))
            cols.append(self.idx[np.asarray(jc, dtype=int)].T)             # M × nnz
        vals = ca.vec(ca.vertcat(*parts))
        # order of vals: instance-major, within an instance the outputs' nonzeros in order
        ycat = np.hstack(yidx).ravel()
        ccat = np.hstack(cols).ravel()
        # global (row r, col c) += Gy[r, y] · val
        P = sp.csc_matrix((np.ones(ycat.size), (ycat, np.arange(ycat.size))),
                          shape=(Gy.shape[1], ycat.size))
        GP = (Gy @ P).tocoo()
        return vals, GP.row, ccat[GP.col], GP.col, GP.data

    def hessian(self, need: list[bool], mus: list[ca.MX]):
        """(local nonzeros MX, and the global upper-triangle (row, col) of each)."""
        e, M = self.e, self.e.count
        if e.hessian is not None and tuple(self.var) == e.hessian.variables:
            vals, hr, hc = e.hessian(e.args, mus)
            vals = ca.vec(vals)
        else:
            mu_sx = [ca.SX.sym(f"mu{o}", *self.sx_out[o].shape) for o in range(len(need))]
            lag = sum((ca.dot(mu_sx[o], self.sx_out[o]) for o, w in enumerate(need) if w),
                      ca.SX(0))
            H = ca.triu(ca.hessian(lag, self.v)[0])
            hr, hc = H.sparsity().get_triplet()
            fn = ca.Function(f"{e.name}_hess", [*self.sx_in, *mu_sx],
                             [ca.vertcat(*H.nonzeros())], CSE)
            vals = ca.vec(fn.map(M, "serial")(*self.e.args, *mus))
        r = self.idx[np.asarray(hr, dtype=int)].T.ravel()     # instance-major
        c = self.idx[np.asarray(hc, dtype=int)].T.ravel()
        lo, hi = np.minimum(r, c), np.maximum(r, c)
        # an off-diagonal local entry on one global variable (repeated in an instance) counts twice
        twice = (r == c) & np.tile(np.asarray(hr) != np.asarray(hc), M)
        return vals, lo, hi, np.arange(lo.size), np.where(twice, 2.0, 1.0)


def _assemble(nrow: int, ncol: int, parts: list, rest: ca.MX) -> ca.MX:
    """Σ parts (local nonzeros scattered to (row, col) with coefficients) + rest, as one sparse
    MX: a constant sparse matrix times the stacked local nonzeros."""
    import scipy.sparse as sp    # with a 3-D build, not at start-up
    rest_sp = rest.sparsity()
    rr, rc = rest_sp.get_triplet()
    rows, cols, src, coef, vals = [np.asarray(rr, dtype=int)], [np.asarray(rc, dtype=int)], [], [], []
    base = 0
    for v, r, c, k, w in parts:
        rows.append(r)
        cols.append(c)
        src.append(base + k)
        coef.append(w)
        vals.append(v)
        base += v.numel()
    R, C = np.concatenate(rows), np.concatenate(cols)
    key = C.astype(np.int64) * nrow + R
    uniq, inv = np.unique(key, return_inverse=True)
    sparsity = ca.Sparsity.triplet(nrow, ncol, (uniq % nrow).tolist(), (uniq // nrow).tolist())
    nz = ca.MX(uniq.size, 1)
    if vals:
        n_rest = len(rr)
        A = sp.csc_matrix((np.concatenate(coef), (inv[n_rest:], np.concatenate(src))),
                          shape=(uniq.size, base))
        nz = ca.mtimes(_to_dm(A), ca.vertcat(*vals))
    if len(rr):
        # the rest's nonzeros go to their places
        E = sp.csc_matrix((np.ones(len(rr)), (inv[:len(rr)], np.arange(len(rr)))),
                          shape=(uniq.size, len(rr)))
        nz = nz + ca.mtimes(_to_dm(E), rest.nz[:])
    return ca.MX(sparsity, nz)


def condensed_derivatives(x: ca.MX, p: ca.MX, f: ca.MX, g: ca.MX, elements: Elements,
                          nz: int, Y: ca.MX, f_y: ca.MX
                          ) -> tuple[ca.MX, ca.MX, dict[str, ca.Function]]:
    """An NLP whose decision vector x = (z, y) ends in a lifted block y that only f uses,
    condensed onto z: y = Y(z) substituted, not a variable with its rows y − Y(z) = 0.
    Its derivatives are those of the lifted NLP (f, (g, y − Y)) (:func:`element_derivatives`)
    mapped by the chain rule, with T = ∂(z, Y(z))/∂z = [I; ∂Y/∂z] (∂Y/∂z = minus the lifted
    rows' Jacobian in z):

        ∂g_c/∂z = ∂g/∂z,     ∇²_z L_c = Tᵀ ∇²_x L(x(z), λ_f, (λ_g, μ)) T,

    the lifted rows' multipliers μ = −λ_f ∇_y f (they make the lifted Lagrangian stationary in
    y, whence its (z, z) block carries Σ λ_f ∂f/∂y_i ∇²Y_i, the condensed curvature); ``f_y``:
    the terms of f that use y (∇_y f = ∇_y f_y, refused otherwise). Returns
    z, x(z) (to evaluate the lifted expressions at) and the ``jac_g`` and ``hess_lag`` Functions
    (g and its Jacobian evaluated at y = 0: they do not use y).
    The condensed KKT system has neither y nor its rows: the 3-D model's repulsion samples,
    lifted, tripled its size and filled its factor sevenfold (docs/weft3d.md, "Cost")."""
    nx, ng = x.numel(), g.numel()
    ny, Yv = nx - nz, ca.vec(Y)
    _condensable(x, f, g, Yv, f_y, nz)
    hess_l = element_derivatives(x, p, f, ca.vertcat(g, x[nz:] - Yv), elements, nx,
                                 ("hess_lag",))["hess_lag"]
    # ∂Y/∂z alone (the elements that Y uses), not the whole Jacobian again in every Hessian
    dY = element_derivatives(x, p, ca.MX(0), x[nz:] - Yv, elements, nx, ("jac_g",))["jac_g"]
    grad_y = ca.Function("grad_y", [x, p], [ca.gradient(f_y, x)[nz:]])
    z = ca.MX.sym("x", nz)
    z0 = ca.vertcat(z, ca.DM.zeros(ny))          # where y does not matter (g, Y)
    xz = ca.vertcat(z, ca.Function("Y", [x], [Yv])(z0))
    g_c, jac = element_derivatives(x, p, ca.MX(0), g, elements, nx, ("jac_g",))["jac_g"](z0, p)
    jac = jac[:, :nz]
    T = ca.vertcat(ca.MX(ca.DM.eye(nz)), -dY(xz, p)[1][:, :nz])
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", ng)
    mu = -lam_f * grad_y(xz, p)
    H = ca.triu2symm(hess_l(xz, p, lam_f, ca.vertcat(lam_g, mu)))
    hess = ca.triu(ca.mtimes(T.T, ca.mtimes(H, T)))
    return z, xz, {"jac_g": ca.Function("nlp_jac_g", [z, p], [g_c, jac], ["x", "p"],
                                        ["g", "jac_g_x"]),
                   "hess_lag": ca.Function("nlp_hess_l", [z, p, lam_f, lam_g], [hess],
                                           ["x", "p", "lam_f", "lam_g"],
                                           ["triu_hess_gamma_x_x"])}


def _condensable(x: ca.MX, f: ca.MX, g: ca.MX, Yv: ca.MX, f_y: ca.MX, nz: int) -> None:
    """Refuse (``NotElementwise``) a block y = x[nz:] that g or Y uses, that f uses outside
    ``f_y``, or whose size is not Y's."""
    if Yv.numel() != x.numel() - nz:
        raise NotElementwise(f"the lifted block has {x.numel() - nz} variables and "
                             f"{Yv.numel()} values")
    if _uses(g, x, nz) or _uses(Yv, x, nz):
        raise NotElementwise("the condensed block is used by g, or Y depends on it")
    if _uses(ca.graph_substitute(f, [f_y], [ca.MX.sym("f_y")]), x, nz):
        raise NotElementwise("f uses the condensed block outside the terms given")


def _uses(expr: ca.MX, x: ca.MX, nz: int) -> bool:
    """Whether ``expr`` depends (structurally) on x[nz:]."""
    return bool(np.any(np.asarray(ca.jacobian_sparsity(expr, x).get_triplet()[1]) >= nz))
