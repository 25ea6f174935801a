"""IPOPT glue: the condensed model's oracles as ``casadi.Callback`` Functions for ``nlpsol``.

``grad_f``, ``jac_g`` and ``hess_lag`` (and the f, g Function with its reverse derivative for
the multipliers) are numpy code writing into CasADi's buffers; the solver works in scaled
variables x with w = unit ⊙ x (``Shooting._units``).
"""
from __future__ import annotations

from typing import Callable

import casadi as ca
import numpy as np

from .assembly import Assembly


class _NumericFunction(ca.Callback):
    """A CasADi Function whose outputs a Python callable computes from numpy inputs."""

    def __init__(self, name: str, fn: Callable, sp_in: list[ca.Sparsity],
                 sp_out: list[ca.Sparsity], names_in: list[str], names_out: list[str],
                 reverse: Callable[[], ca.Function] | None = None) -> None:
        ca.Callback.__init__(self)
        self.fn, self.sp_in, self.sp_out, self.reverse = fn, sp_in, sp_out, reverse
        self.names_in, self.names_out = names_in, names_out
        self.construct(name, {})

    def get_n_in(self) -> int:
        return len(self.sp_in)

    def get_n_out(self) -> int:
        return len(self.sp_out)

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return self.sp_in[i]

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return self.sp_out[i]

    def get_name_in(self, i: int) -> str:
        return self.names_in[i]

    def get_name_out(self, i: int) -> str:
        return self.names_out[i]

    def has_reverse(self, nadj: int) -> bool:
        return self.reverse is not None and nadj == 1

    def get_reverse(self, nadj: int, name: str, inames, onames, opts) -> ca.Function:
        self._reverse = self.reverse()                  # CasADi keeps no reference
        return self._reverse

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, arg, res) -> int:
        """Read the inputs' and write the outputs' nonzeros in place (measured: converting a
        million Hessian nonzeros to a DM through a list cost about 0.1 s per evaluation)."""
        outs = self.fn(*[np.frombuffer(a, dtype=np.float64) for a in arg])
        for r, o in zip(res, outs):
            if r is not None and len(r):
                np.frombuffer(r, dtype=np.float64)[:] = np.ravel(o)
        return 0


def oracles(model: Assembly) -> tuple[dict, dict, tuple]:
    """(nlp, nlpsol options, the callbacks: CasADi keeps no reference to them, so the
    model holds them as long as it lives)."""
    nw, ng, npar = model.x.size, model.g.size, model.p.size
    dense = ca.Sparsity.dense
    u = model.unit
    # nlpsol builds the Lagrangian's gradient for its multiplier outputs from the reverse
    # derivative of (f, g); only its x part is provided (lam_p is not computed)
    adjoint = lambda: _NumericFunction(                                   # noqa: E731
        "condensed_fg_adj",
        lambda x, p, f, g, sf, lg: (u * model.gradient(u * x, p, float(sf[0]), lg),
                                    np.zeros(npar)),
        [dense(nw), dense(npar), dense(1), dense(ng), dense(1), dense(ng)],
        [dense(nw), dense(npar)], ["x", "p", "out_f", "out_g", "adj_f", "adj_g"],
        ["adj_x", "adj_p"])
    fg = _NumericFunction(
        "condensed_fg", lambda x, p: (model.objective(u * x, p), model.constraints(u * x, p)),
        [dense(nw), dense(npar)], [dense(1), dense(ng)], ["x", "p"], ["f", "g"], adjoint)
    grad = _NumericFunction(
        "condensed_grad_f", lambda x, p: (model.objective(u * x, p), u * model.gradient(u * x, p)),
        [dense(nw), dense(npar)], [dense(1), dense(nw)], ["x", "p"], ["f", "grad_f_x"])
    jac = _NumericFunction(
        "condensed_jac_g", lambda x, p: (model.constraints(u * x, p),
                                         model.jacobian_nonzeros(u * x, p) * model.jac_scale),
        [dense(nw), dense(npar)], [dense(ng), model.jac_sp], ["x", "p"], ["g", "jac_g_x"])
    hess = _NumericFunction(
        "condensed_hess_lag",
        lambda x, p, sf, lg: (model.hessian_nonzeros(u * x, p, float(sf[0]), lg)
                              * model.hess_scale,),
        [dense(nw), dense(npar), dense(1), dense(ng)], [model.hess_sp],
        ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    x, p = ca.MX.sym("x", nw), ca.MX.sym("p", npar)
    f, g = fg(x, p)
    return ({"x": x, "p": p, "f": f, "g": g},
            {"grad_f": grad, "jac_g": jac, "hess_lag": hess, "calc_lam_p": False,
             "calc_lam_x": False},
            (fg, grad, jac, hess))
