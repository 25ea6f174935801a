"""The one way to turn a weft problem into an NLP: ``transcribe(problem, parametrisation)``.

``Full()`` gives the full NLP of eq. 13 with its closed-form Jacobian and Lagrangian Hessian
(``derivatives``; measured faster than CasADi's AD on large fabrics, docs/measurements.md);
``Reduced(...)`` gives the condensed reduced model (with the clamped courses and wales added
where the clamps would otherwise be dependent: ``condensed.build_condensed``). ``Adaptive``
chooses its representatives by solving (``solving.adaptive``): it is a solve strategy, not a
transcription, and is refused here. ``contact=Slots(...)`` with ``Full()`` gives the full NLP
with yarn contact slots (``contact.ContactNLP``).
"""
from __future__ import annotations

from ..model.parametrisation import Adaptive, Full, Parametrisation, Reduced
from ..model.problem import WeftProblem
from .condensed.nlp import build_condensed
from .contact import Slots, build_contact_nlp
from .derivatives import closed_form_derivatives
from .full import FullNLP, build_nlp
from .protocol import WeftNLP
from .spatial import build_spatial

DERIVATIVES = ("closed_form", "casadi")


def transcribe(problem: WeftProblem, parametrisation: Parametrisation | None = None, *,
               derivatives: str = "closed_form", segment: int | None = None,
               contact: Slots | None = None, base: FullNLP | None = None) -> WeftNLP:
    """The NLP of ``problem`` in ``parametrisation`` (None: the problem's own, reduced when the
    file has ``[reduction]``).

    ``derivatives`` (full model): ``"closed_form"`` (default) or ``"casadi"`` (CasADi's AD of
    the NLP expressions, for comparisons); the condensed model has only its own hand-assembled
    derivatives. ``segment``: loops per shooting segment of the condensed model. ``contact``
    (full model): yarn contact slots (``contact.Slots``) appended to ``base``, the problem's
    full NLP (built here when not given).
    """
    param = problem.parametrisation if parametrisation is None else parametrisation
    if derivatives not in DERIVATIVES:
        raise ValueError(f"derivatives must be one of {', '.join(DERIVATIVES)}; got {derivatives!r}")
    if isinstance(param, Adaptive):
        raise ValueError("Adaptive() chooses representatives by solving: use "
                         "knit_nlp.weft.solve(problem, Adaptive(...)), not transcribe")
    if problem.yarn is not None and problem.yarn.spatial:      # [yarn] geometry = "3d"
        if not isinstance(param, Full):
            raise ValueError("the reduced model is planar: the 3-D model is solved in full")
        return build_spatial(problem)
    if contact is not None:
        if not isinstance(param, Full):
            raise ValueError("yarn contact is built on the full model: use Full()")
        return build_contact_nlp(base or _full(problem, derivatives), contact)
    if isinstance(param, Full):
        return _full(problem, derivatives)
    if isinstance(param, Reduced):
        if derivatives != "closed_form":
            raise ValueError("the condensed reduced model has only its closed-form derivatives")
        return build_condensed(problem, param, segment=segment)
    raise ValueError(f"parametrisation must be Full() or Reduced(...); got {param!r}")


def _full(problem: WeftProblem, derivatives: str) -> FullNLP:
    full = build_nlp(problem)
    if derivatives == "closed_form":
        full.nlpsol_options = closed_form_derivatives(full)
    return full
