"""The double-jacquard warp-knit mass-spring model (spec/jacquard_mass_spring.md).

Public API::

    problem = load_problem("problems/jacquard_diamond.toml")   # or parse_problem(doc, path)
    result = solve_static(problem)        # CasADi/IPOPT equilibrium (default method)
    result = solve_explicit(problem)      # the paper's explicit midpoint relaxation
    result.positions, result.success, result.residual_force, result.network.zero_modes

``solve_file`` is what ``knit-nlp solve`` calls for ``model = "jacquard"`` files.
"""
from __future__ import annotations

from .explicit import solve_explicit
from .problem import JacquardProblem, JacquardSystem, SolverOptions, load_problem, parse_problem
from .result import JacquardResult
from .run import result_dict, solve, solve_file
from .springs import Network, build_network
from .static import solve_static

__all__ = ["JacquardProblem", "JacquardSystem", "SolverOptions", "JacquardResult", "Network",
           "load_problem", "parse_problem", "build_network", "solve", "solve_static",
           "solve_explicit", "solve_file", "result_dict"]
