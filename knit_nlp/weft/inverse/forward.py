"""The forward equilibrium of the inverse problems (control, fit, calibrate): the problem's full
model, with yarn contact where it has ``[yarn] radius`` (``solving.variants.equilibrium``, the
one choice of variant), its solves and their implicit-function sensitivities and stability
check (``solving.sensitivity``).

With contact, inside the control iteration a forward solve is one load step from the last
solved state (``origin``) to the new actuation, halved where yarns would cross — the path the
clamps actually travel — and every solve is polished (``POLISH`` re-solves with the pairs
searched on its solution) so that x(p) is smooth enough for the outer iteration.
"""
from __future__ import annotations

from ..model.parametrisation import Full
from ..model.problem import WeftProblem
from ..solving.contact.equilibrium import KEEP
from ..solving.solve import Equilibrium, refuse_friction
from ..solving.rounds3d import SpatialEquilibrium
from ..solving.variants import equilibrium

try:    # with the module, not inside the first stability check: a one-time 0.15-0.5 s import,
    import scipy.sparse.linalg  # noqa: F401  (Python's, not a solve's cost; measured)
except ImportError:             # pragma: no cover  (scipy is optional: the dense check then)
    pass

# re-solves with the pairs searched on a forward solution: with 2, place_stitch_yarn's forward
# check ended 1.64e-3 from the control's state (over its radius / 100), the forward solve less
# settled (its energy 6.6e-7 higher, measured on a variant of the rows); with 4, 1.42e-4
POLISH = 4
# solved contact states remembered for a calibration curve, whose nodes' sensitivities are taken
# after the whole pull (up to curve.NODES x 10 steps, each possibly halved): every state stays
CURVE_KEEP = 1024


def equilibrium_for(problem: WeftProblem, keep: int = KEEP, *,
                    load_path: bool = False) -> Equilibrium:
    """The forward equilibrium control, fit and calibrate share: the full model (with yarn
    contact for a problem with a radius, remembering ``keep`` contact states for their
    sensitivities, its solves polished; the 3-D model's ``SpatialEquilibrium``, whose
    crossings are energy terms of an equality-constrained NLP, so its sensitivities are the
    plain KKT system's, without the other contacts' rounds). Lagged friction is refused
    (``solve.refuse_friction``) unless the caller's solves follow one forward load path
    (``load_path``: calibrate's curves, each node a step lagged from the last, ``curve.py``);
    control's and fit's do not."""
    if not load_path:
        refuse_friction(problem, "control and fit")
    eq = equilibrium(problem, Full(), keep=keep, polish=POLISH)
    if isinstance(eq, SpatialEquilibrium):
        eq.rounds_max = 0        # the outer iteration's states must keep fitting its NLP
        eq.refute = False        # its trial states are the outer iteration's to judge
    return eq
