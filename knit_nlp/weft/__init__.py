"""The weft-knit loop model of Wada et al. (docs/weft_model.md).

Reading order follows the model: ``basis`` and ``quadrature`` (eqs. 1, 14-16) -> ``natural``
(the unloaded loop) -> ``crossings`` (eqs. 2-5) -> ``problem`` (a checked problem description)
-> ``energy`` and ``kinematics`` (eqs. 6-12) -> ``params`` (what a solve may change) and
``parametrisation`` (``Full`` / ``Reduced`` / ``Adaptive``, the map of eqs. 22-27 in
``reduction``) -> ``nlp`` (eq. 13 with continuity 18-19 and clamps) and ``condensed`` (the
reduced model as solved) -> ``guesses``, ``solve`` (IPOPT) and ``adaptive`` -> ``results``
(typed, and the result JSON) -> ``sampling``, ``plot`` -> ``api`` (the Python entry points),
``study`` (many solves of one build) and ``summary`` (what the CLI prints).
"""
from __future__ import annotations

from .api import Comparison, compare, solve
from .transcription.full import WeftNLP, build_nlp
from .model.params import WeftParams
from .model.parametrisation import Adaptive, Full, Parametrisation, Reduced
from .model.problem import Clamp, Load, RigidClamp, SolverOptions, WeftProblem, load_problem, parse_problem
from .output.results import ClampReaction, LoadResult, RigidClampReaction, WeftResult

__all__ = ["WeftProblem", "Clamp", "Load", "RigidClamp", "SolverOptions", "WeftParams", "Full",
           "Reduced", "Adaptive", "Parametrisation", "WeftNLP", "WeftResult", "ClampReaction",
           "RigidClampReaction", "LoadResult", "Comparison", "load_problem", "parse_problem",
           "build_nlp", "solve", "compare"]
