"""The forward equilibrium of a weft problem: the one place its variant is chosen.

``equilibrium(problem, parametrisation)`` builds, once, what solves the problem at any
parameters (``solve(params, x0) -> Solution``) for studies and sweeps, continuation, control,
fit and calibrate:

- ``Equilibrium`` (``solve.py``): a fixed transcription, ``Full()`` or ``Reduced(...)``
  (``transcription.factory.transcribe``), with its sensitivities and stability check;
- ``ContactEquilibrium`` (``contact/equilibrium.py``): the full model of a problem with
  ``[yarn] radius`` (the reduced models refuse a radius: their loops are interpolated);
- ``AdaptiveEquilibrium`` (``adaptive.py``): the adaptive-representatives strategy, which
  refines its grid afresh at every solve and has no sensitivities;
- the 3-D model (``[yarn] geometry = "3d"``): a ``SpatialEquilibrium`` (``rounds3d.py``) of its
  full transcription (``transcription.spatial``, through ``transcribe``); its designed crossings
  are persistent contacts in the NLP itself, and the other contacts' rounds add the pairs the
  independent check finds closer than touch; the reduced models are planar and refuse it.

A new model variant (a new transcription, or a new kind of contact) joins here.
"""
from __future__ import annotations

from ..model.parametrisation import Adaptive, Full, Parametrisation, Reduced
from ..model.problem import WeftProblem
from .adaptive import AdaptiveEquilibrium
from .contact.equilibrium import KEEP, ContactEquilibrium, refuse
from ..transcription.spatial import planar_only
from .rounds3d import SpatialEquilibrium
from .solve import Equilibrium

ForwardEquilibrium = Equilibrium | AdaptiveEquilibrium


def equilibrium(problem: WeftProblem, parametrisation: Parametrisation | None = None, *,
                verbose: bool | None = False, keep: int = KEEP,
                polish: int = 0) -> ForwardEquilibrium:
    """How ``problem`` is solved in ``parametrisation`` (None: the file's own): a fixed
    transcription built once, the adaptive strategy, or the full model with yarn contact
    (``[yarn] radius``; the reduced models refuse it, ``contact.equilibrium.refuse``). ``verbose``:
    IPOPT's progress line (None: never, a study's workers); ``keep`` and ``polish``: the
    contact solves remembered for their sensitivities and the re-solves that smooth x(p)
    (``ContactEquilibrium``)."""
    param = problem.parametrisation if parametrisation is None else parametrisation
    if problem.yarn is not None and problem.yarn.spatial:
        if isinstance(param, (Reduced, Adaptive)):
            raise planar_only(problem, "the reduced model")
        return SpatialEquilibrium(problem, Full(), verbose=verbose)   # rounds3d: other contacts
    if problem.yarn is not None:
        if isinstance(param, (Reduced, Adaptive)):
            own = " (the file's [reduction])" if parametrisation is None else ""
            raise refuse(problem, f"the reduced model{own}")
        return ContactEquilibrium(problem, verbose=verbose, keep=keep, polish=polish)
    if isinstance(param, Adaptive):
        return AdaptiveEquilibrium(problem, param)
    return Equilibrium(problem, param, verbose=verbose)
