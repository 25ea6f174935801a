"""The jacquard model from Python: solve a problem with the static (default) or explicit solver."""
from __future__ import annotations

from ..errors import ProblemError, quoted
from .explicit import solve_explicit
from .problem import JacquardProblem
from .result import JacquardResult
from .static import solve_static

SOLVERS = {"static": solve_static, "explicit": solve_explicit}


def solve(problem: JacquardProblem, solver: str | None = None) -> JacquardResult:
    """Solve with ``solver`` (``static`` | ``explicit``), default the problem's own method."""
    method = problem.solver.method if solver is None else solver
    if method not in SOLVERS:      # what the file reader says about [solver] method
        raise ProblemError(problem.source or "<api>", "solver", "method",
                           f"must be one of {', '.join(SOLVERS)}; got {quoted(method)}")
    return SOLVERS[method](problem)
