"""IPOPT options and the meaning of success, shared by both models.

A solve succeeds only when IPOPT reports ``Solve_Succeeded``: ``acceptable_iter = 0`` keeps its
"solved to acceptable level" exit off, so a weaker convergence is reported as not converged.
"""
from __future__ import annotations

from typing import Any

SUCCESS = "Solve_Succeeded"


def succeeded(status: str) -> bool:
    """True only for IPOPT's ``Solve_Succeeded``."""
    return status == SUCCESS


def ipopt_options(tol: float, max_iter: int, print_level: int = 0, **extra: Any) -> dict[str, Any]:
    """The ``nlpsol`` options for IPOPT with MUMPS: tolerance, iteration limit, quiet output,
    success meaning ``Solve_Succeeded``; ``extra`` adds or overrides IPOPT options."""
    ipopt = {"tol": tol, "max_iter": max_iter, "print_level": print_level, "sb": "yes",
             "linear_solver": "mumps", "acceptable_iter": 0}
    ipopt.update(extra)
    return {"print_time": False, "ipopt": ipopt}
