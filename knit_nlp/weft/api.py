"""The weft model from Python: solve a problem, or compare its full and reduced models.

    result = solve(problem)                              # the file's parametrisation
    result = solve(problem, Reduced((1, 5, 10), (1, 10)), continuation=4)
    result.success, result.energy.total, result.clamps[0].reaction, result.centrelines()
    cmp = compare(problem); cmp.distance_max, cmp.speedup_reduced

Solving goes through :func:`~knit_nlp.weft.study.study`: a transcription built once
(``transcription.factory.transcribe``) for ``Full()`` and ``Reduced(...)``, the adaptive
strategy for ``Adaptive(...)``.
"""
from __future__ import annotations

import numbers
from collections.abc import Sequence

from ..errors import quoted
from .model.centrelines import SAMPLES
from .model.parametrisation import Adaptive, Full, Parametrisation, Reduced, even_grid
from .model.params import WeftParams
from .model.problem import MAX_CONTINUATION, WeftProblem
from .output.comparison import Comparison, grid_row
from .output.results import WeftResult
from .solving.blocks import WarmStart
from .solving.contact.equilibrium import refuse
from .study import study
from .transcription.spatial import planar_only


def solve(problem: WeftProblem, parametrisation: Parametrisation | None = None, *,
          params: WeftParams | None = None, continuation: int | None = None,
          start: WeftResult | None = None, warm_from_reduced: bool = False,
          verbose: bool = False) -> WeftResult:
    """Build and solve one model of a problem.

    ``parametrisation``: ``Full()``, ``Reduced(...)``, ``Adaptive(...)`` or None for the file's
    own (reduced when it has ``[reduction]``). ``params``: parameter values (the file's by
    default). ``continuation``: reach the targets in this many warm-started steps. ``start``:
    start from another solved model's loops (lifted into this one). ``warm_from_reduced``: solve
    the reduced model first and start this (full) one from it; the result's JSON then carries
    ``warm_start``. ``verbose``: show IPOPT's iterations on one updating line of stderr. Bad
    arguments raise ``ValueError`` naming the argument.
    """
    param = problem.parametrisation if parametrisation is None else parametrisation
    check_arguments(param, params, continuation, start, warm_from_reduced, verbose)
    if warm_from_reduced:
        if not isinstance(param, Full):
            raise ValueError("warm_from_reduced starts the full model: use Full()")
        if problem.yarn is not None:
            raise refuse(problem, "the warm start from the reduced model")
        return _warm_from_reduced(problem, params, continuation, verbose)[1]
    return study(problem, param, verbose=verbose).run(params, continuation=continuation,
                                                      start_from=start)


def check_arguments(param: object, params: object, continuation: object, start: object,
                    warm_from_reduced: object, verbose: object) -> None:
    """``ValueError`` (naming the argument) for anything :func:`solve` cannot take."""
    if not isinstance(param, (Full, Reduced, Adaptive)):
        raise ValueError(f"parametrisation must be Full(), Reduced(...) or Adaptive(...); "
                         f"got {quoted(param)}")
    if params is not None and not isinstance(params, WeftParams):
        raise ValueError(f"params must be WeftParams (e.g. WeftParams.of(problem).with_(...)); "
                         f"got {quoted(params)}")
    if continuation is not None and not (isinstance(continuation, numbers.Integral)
                                         and not isinstance(continuation, bool)
                                         and 1 <= continuation <= MAX_CONTINUATION):
        raise ValueError(f"continuation must be a whole number of steps in 1..{MAX_CONTINUATION}"
                         f" or None; got {quoted(continuation)}")
    if start is not None and not isinstance(start, WeftResult):
        raise ValueError(f"start must be a solved WeftResult; got {quoted(start)}")
    for name, flag in (("warm_from_reduced", warm_from_reduced), ("verbose", verbose)):
        if not isinstance(flag, bool):
            raise ValueError(f"{name} must be True or False; got {quoted(flag)}")


def _warm_from_reduced(problem: WeftProblem, params: WeftParams | None,
                       continuation: int | None,
                       verbose: bool = False) -> tuple[WeftResult, WeftResult]:
    """The reduced model (the file's representatives, or the corners), then the full model
    started from its lifted solution."""
    red = solve(problem, problem.reduction or Reduced(), params=params, continuation=continuation,
                verbose=verbose)
    full = solve(problem, Full(), params=params, continuation=continuation, start=red,
                 verbose=verbose)
    full.warm_start = WarmStart(red.success, red.iterations, red.report.solve_s)
    return red, full


def compare(problem: WeftProblem, samples: int = SAMPLES, *, warm: bool = False,
            grids: Sequence[int] = ()) -> Comparison:
    """Solve the full model and the reduced one (the file's representatives, or the corners);
    ``warm``: also the full one warm-started from the reduced (another local minimum shows as a
    different energy; it costs about as much as the full solve, so it is off by default);
    ``grids``: also the even k × k grids for each k given, each against the full model (the
    accuracy-against-time frontier, :class:`~.output.comparison.GridRow`)."""
    if not isinstance(warm, bool):
        raise ValueError(f"warm must be True or False; got {quoted(warm)}")
    ks = check_compare(problem, grids)
    full = solve(problem, Full())
    if warm:
        red, warm_full = _warm_from_reduced(problem, None, None)
    else:
        red, warm_full = solve(problem, problem.reduction or Reduced()), None
    frontier = [grid_row(k, full, solve(problem, even_grid(k, problem.courses, problem.wales)),
                         samples) for k in ks]
    return Comparison(full, red, warm_full, samples, frontier)


def check_compare(problem: WeftProblem, grids: Sequence[int] = ()) -> list[int]:
    """What ``compare`` checks before solving: the problem has no yarn radius (the reduced
    model has no contact: :func:`~.solving.contact.equilibrium.refuse`) and the grids
    (:func:`check_grids`, returned)."""
    if problem.yarn is not None:
        if problem.yarn.spatial:
            raise planar_only(problem, "compare")
        raise refuse(problem, "compare (its reduced model)")
    return check_grids(grids, problem)


def check_grids(grids: Sequence[int], problem: WeftProblem) -> list[int]:
    """The frontier's k values, sorted and unique: whole numbers from 2 (the corner form) to
    the larger side of the fabric (every course and wale)."""
    try:
        if isinstance(grids, (str, bytes)):
            raise TypeError
        items = list(grids)
    except TypeError:
        raise ValueError(f"grids must be a list of whole numbers; got {quoted(grids)}") from None
    top = max(problem.courses, problem.wales, 2)
    for k in items:
        if isinstance(k, bool) or not isinstance(k, numbers.Integral) or not 2 <= k <= top:
            raise ValueError(f"each grid k must be a whole number from 2 (the corner form) to "
                             f"{top} (every loop of this {problem.courses} x {problem.wales} "
                             f"fabric); got {quoted(k)}")
    return sorted({int(k) for k in items})
