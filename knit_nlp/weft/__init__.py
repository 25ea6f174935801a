"""The weft-knit loop model of Wada et al. (docs/weft_model.md), as a pipeline of subpackages:

- ``model``: the basis and quadrature (eqs. 1, 14-16), the natural loop, crossings (eqs. 2-5),
  energies (eqs. 6-12), a checked problem, its parameters and parametrisations;
- ``transcription``: the NLP of eq. 13, full or condensed reduced (eqs. 22-27), through one
  factory (``transcribe``) and one written protocol (``WeftNLP``);
- ``solving``: IPOPT, continuation and starts; the forward equilibrium of a problem, built once
  in its variant (``solving.variants.equilibrium``: a fixed transcription, yarn contact, the
  adaptive strategy), with its sensitivities;
- ``output``: the typed result, its JSON, pictures, loading paths, exports, summaries;
- ``api`` and ``study``: solving and comparing from Python, many solves of one build;
  ``inverse``: control, identification and overlays through the equilibrium;
- shared load cases as problem documents (``model.cases``, what the tests, scripts and
  benchmarks pull): ``diagonal_pull(n)`` (eq. 28 scaled to n × n), ``course_pull(n)``,
  ``unclamped(m, n)``; ``parse_problem(diagonal_pull(10), "pull")`` is a problem.
"""
from __future__ import annotations

from .api import compare, solve
from .model.cases import course_pull, diagonal_pull, unclamped
from .model.parametrisation import Adaptive, Full, Parametrisation, Reduced
from .model.params import WeftParams
from .model.problem import (Clamp, Load, RigidClamp, SolverOptions, WeftProblem, load_problem,
                            parse_problem)
from .output.comparison import Comparison
from .output.reactions import ClampReaction, LoadResult, RigidClampReaction
from .output.results import WeftResult
from .study import WeftStudy
from .transcription.factory import transcribe
from .transcription.full import build_nlp
from .transcription.protocol import WeftNLP

__all__ = ["WeftProblem", "Clamp", "Load", "RigidClamp", "SolverOptions", "WeftParams", "Full",
           "Reduced", "Adaptive", "Parametrisation", "WeftNLP", "WeftResult", "ClampReaction",
           "RigidClampReaction", "LoadResult", "Comparison", "WeftStudy", "load_problem",
           "parse_problem", "transcribe", "build_nlp", "solve", "compare", "diagonal_pull",
           "course_pull", "unclamped"]
