"""IPOPT's progress on one updating line of stderr, through CasADi's ``iteration_callback``.

Installed only when asked for (``--verbose``): a quiet solve has no callback at all.
"""
from __future__ import annotations

import sys
from typing import TextIO

import casadi as ca
import numpy as np


class IterationLine(ca.Callback):
    """Called by ``nlpsol`` after every IPOPT iteration with the current iterate; rewrites one
    line: iterates so far (each solve's first is its start), objective, largest constraint residual."""

    def __init__(self, nx: int, ng: int, stream: TextIO | None = None) -> None:
        ca.Callback.__init__(self)
        self.nx, self.ng, self.count = nx, ng, 0
        self.stream = stream or sys.stderr
        self.construct("iteration_line", {})

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "ret"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        if name in ("g", "lam_g"):
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def eval(self, arg: list[ca.DM]) -> list[int]:
        self.count += 1
        g = np.asarray(arg[2]).ravel()
        viol = float(np.max(np.abs(g))) if g.size else 0.0
        self.stream.write(f"\r  IPOPT iterate {self.count:5d}  objective "
                          f"{float(arg[1]):.10g}  max |g| {viol:.2e}  ")
        self.stream.flush()
        return [0]

    def done(self) -> None:
        """End the updating line."""
        if self.count:
            self.stream.write("\n")
            self.stream.flush()
