"""The double-jacquard warp-knit mass-spring model (docs/jacquard.md).

Public API::

    problem = load_problem("problems/jacquard_diamond.toml")   # or parse_problem(doc, source)
    result = solve(problem)               # the file's method; "static" (CasADi/IPOPT) by default
    result = solve(problem, "explicit")   # the paper's explicit midpoint relaxation
    result.success, result.energy, result.positions, result.residual_force, result.to_json()
    result.save("results")                # what ``knit-nlp solve`` writes
"""
from __future__ import annotations

from .api import SOLVERS, solve
from .explicit import solve_explicit
from .problem import JacquardProblem, JacquardSystem, SolverOptions, load_problem, parse_problem
from .result import JacquardResult
from .springs import Network, build_network
from .static import solve_static

__all__ = ["JacquardProblem", "JacquardSystem", "SolverOptions", "JacquardResult", "Network",
           "SOLVERS", "load_problem", "parse_problem", "build_network", "solve", "solve_static",
           "solve_explicit"]
