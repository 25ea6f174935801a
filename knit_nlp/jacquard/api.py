"""The jacquard model from Python: solve a problem with the static (default) or explicit solver."""
from __future__ import annotations

from .explicit import solve_explicit
from .problem import JacquardProblem
from .result import JacquardResult
from .static import solve_static

SOLVERS = {"static": solve_static, "explicit": solve_explicit}


def solve(problem: JacquardProblem, solver: str | None = None) -> JacquardResult:
    """Solve with ``solver`` (``static`` | ``explicit``), default the problem's own method."""
    method = solver or problem.solver.method
    if method not in SOLVERS:
        raise ValueError(f"unknown jacquard solver {method!r}; use {' or '.join(SOLVERS)}")
    return SOLVERS[method](problem)
