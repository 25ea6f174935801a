"""knit_nlp: mechanics of knitted fabrics as nonlinear programs.

Two published models: the weft-knit loop model of Wada et al. (``knit_nlp.weft``) and the
double-jacquard warp-knit mass-spring model of Zhang et al. (``knit_nlp.jacquard``).

    import knit_nlp
    problem = knit_nlp.load_problem("wada_fig7")     # a shipped name or a path
    result = knit_nlp.solve(problem)                  # typed: result.success, result.energy, ...
    result.save("results")                            # the files `knit-nlp solve` writes
    knit_nlp.compare("diagonal_pull")                 # full against reduced (weft)
    knit_nlp.calibrate("problems/real_fabric/acrylic_fit_x.toml")   # fit on measured tests
"""
__version__ = "0.1.0"

from .api import MODELS, calibrate, compare, load_problem, parse_problem, solve  # noqa: E402
from .errors import ProblemError  # noqa: E402
from .outcome import Energy  # noqa: E402

__all__ = ["__version__", "MODELS", "ProblemError", "Energy", "load_problem", "parse_problem",
           "solve", "compare", "calibrate"]

