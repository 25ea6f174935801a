"""What a transcribed weft NLP offers to solving, results and inverse problems: the one protocol.

``factory.transcribe(problem, parametrisation)`` returns a :class:`WeftNLP`: the full NLP of
eq. 13 (``full.FullNLP``) for ``Full()``, the condensed reduced model of eqs. 22-27
(``condensed.CondensedNLP``) for ``Reduced(...)``. Everything downstream (``WeftSolver``, the
solve strategies, ``WeftResult``, studies, inverse problems) uses these members only.

The NLP is  min f(x, p)  s.t.  lbg ≤ g(x, p) ≤ ubg,  with x the transcription's own decision
vector (its layout ``x``) and p the problem's parameters (layout ``p``, values
:class:`~knit_nlp.weft.model.params.WeftParams`), so one build serves every parameter value.
Every constraint row of today's models is an equality (lbg = ubg = 0); rows with other bounds
(contact, g ≥ 0) are declared through ``lbg``/``ubg`` and the solver passes them as given.

Members a transcription provides (data):

- ``problem``, ``parametrisation`` (``Full()`` or the resolved ``Reduced``), ``model`` (the
  result's name: ``"full"`` or ``"reduced"``);
- ``nlp`` (``x``, ``p``, ``f``, ``g`` for ``casadi.nlpsol``) and ``nlpsol_options`` (its
  derivative oracles: closed forms for both models);
- layouts ``x``, ``p``, ``g``; bounds ``lbg``, ``ubg`` (arrays of g's size); start ``x0``
  (the natural configuration); ``params`` (the problem's own values);
- ``clamp_table`` (``rows.ClampTable``): the clamped and loaded material points, each clamp's,
  load's and rigid clamp's indices among them, and the clamps' rows of g (reactions are read
  from the multipliers there);
- ``n_parameters`` (counted as the paper counts, ``rows.n_parameters``).

Methods it provides: ``energy``, ``coefficients``, ``starts``, ``special_positions``, ``lift``
and ``representatives``. The protocol itself implements what follows from those (``p0``,
``n_variables``, ``n_constraints``, ``centrelines``, ``violation``); a transcription class
inherits them by naming the protocol as its base. The transcriptions assembled as one CasADi
graph (full, 3-D) hold the data members their builders fill in :class:`Assembled`.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import casadi as ca
import numpy as np

from ...layout import Layout
from ..model.centrelines import SAMPLES, centrelines
from ..model.parametrisation import Full, Reduced
from ..model.params import WeftParams
from ..model.problem import WeftProblem
from .rows import ClampTable


class WeftNLP(Protocol):
    """A weft NLP ready to solve and to read back (module docstring)."""

    problem: WeftProblem
    parametrisation: Full | Reduced
    model: str
    nlp: dict[str, ca.MX]
    nlpsol_options: dict[str, Any]
    x: Layout
    p: Layout
    g: Layout
    lbg: np.ndarray
    ubg: np.ndarray
    x0: np.ndarray
    params: WeftParams
    clamp_table: ClampTable
    n_parameters: int

    def energy(self, x: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
        """(U_spring, U_bend, W_loads) at a decision vector x and parameters p (eqs. 6-12 and
        the loads' work from the natural state); the NLP minimises U_spring + U_bend − W."""
        ...

    def coefficients(self, x: np.ndarray) -> np.ndarray:
        """Every loop's coefficients (m, n, 2t+2) of a decision vector."""
        ...

    def starts(self, x: np.ndarray) -> np.ndarray:
        """Every loop's start point (m, n, 2) of a decision vector."""
        ...

    def special_positions(self, x: np.ndarray) -> np.ndarray:
        """Positions (2 × specials) of the clamped and loaded material points."""
        ...

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """The decision vector of loops with coefficients (m, n, 2t+2) and starts (m, n, 2):
        exact where the loops lie in this transcription's space, else closest in the
        coefficients (least squares)."""
        ...

    def representatives(self) -> dict[str, Any] | None:
        """The representative courses and wales solved (None for the full model), with
        ``asked`` where the factory added the clamped ones."""
        ...

    # -- implemented here: what follows from the members above ---------------------------
    @property
    def p0(self) -> np.ndarray:
        """The problem's own parameter vector."""
        return self.params.vector()

    @property
    def n_variables(self) -> int:
        return self.x.size

    @property
    def n_constraints(self) -> int:
        return self.g.size

    def centrelines(self, x: np.ndarray, samples: int = SAMPLES) -> np.ndarray:
        """Sampled deformed centrelines (m, n, samples, 2) of a decision vector (eq. 1)."""
        pr = self.problem
        return centrelines(self.coefficients(x), self.starts(x), pr.L, pr.t, samples)[0]

    def violation(self, g: np.ndarray) -> float:
        """Largest bound violation of constraint values g: max over rows of lbg − g, g − ubg."""
        g = np.asarray(g, dtype=float).ravel()
        if not g.size:
            return 0.0
        return float(np.max(np.maximum(np.maximum(self.lbg - g, g - self.ubg), 0.0)))


@dataclass
class Assembled(WeftNLP):
    """The data members a CasADi-assembled transcription's builder fills (``full.FullNLP``,
    ``spatial.SpatialNLP``), as dataclass fields; each subclass adds its own and the members
    set after the build (``x0``, ``nlpsol_options``)."""

    problem: WeftProblem
    nlp: dict[str, ca.MX]
    x: Layout
    p: Layout
    g: Layout
    lbg: np.ndarray
    ubg: np.ndarray
    params: WeftParams
    clamp_table: ClampTable
    n_parameters: int
