"""The jacquard model from Python: solve a problem with the static (default) or explicit solver."""
from __future__ import annotations

from ..errors import quoted
from .explicit import solve_explicit
from .problem import JacquardProblem
from .result import JacquardResult
from .static import solve_static

SOLVERS = {"static": solve_static, "explicit": solve_explicit}


def solve(problem: JacquardProblem, solver: str | None = None) -> JacquardResult:
    """Solve with ``solver`` (``static`` | ``explicit``), default the problem's own method
    (``[solver] method``). An unknown solver is a ``ValueError`` naming the argument."""
    method = problem.solver.method if solver is None else solver
    if method not in SOLVERS:
        raise ValueError(f"solver must be one of {', '.join(SOLVERS)}; got {quoted(method)}")
    return SOLVERS[method](problem)
