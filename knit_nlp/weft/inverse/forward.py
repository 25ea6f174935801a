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

import numpy as np

from ..model.parametrisation import Full
from ..model.problem import WeftProblem
from ..solving.contact.equilibrium import KEEP
from ..model.params import WeftParams
from ..solving.solve import DEFAULT_START, Equilibrium, Solution, WeftSolver
from ..transcription.spatial import planar_only
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
# IPOPT iterations of one solve inside a 3-D inverse step (``SpatialSteps``): the accepted steps
# of the 2 x 2 and 6 x 6 controls took 10-60
TRIAL_ITER = 150


# the inverse commands not yet taken through the 3-D model (``[yarn] geometry = "3d"``), each
# with the reason it refuses one in a line (docs/weft3d.md): control and fit are (their
# sensitivities tested against finite differences of 3-D solves, tests/test_weft3d_inverse.py)
NOT_IN_3D = {"calibrate": "not offered for the 3-D model yet (docs/weft3d.md, 'Not done yet'); "
                          "use the planar model"}


def equilibrium_for(problem: WeftProblem, keep: int = KEEP, command: str = "calibrate"
                    ) -> Equilibrium:
    """The forward equilibrium control, fit and calibrate share: the full model (with yarn
    contact for a problem with a radius, remembering ``keep`` contact states for their
    sensitivities, its solves polished; the 3-D model's own NLP, whose crossings are energy
    terms of an equality-constrained NLP, so its sensitivities are the plain KKT system's).
    ``command`` names the caller: one in ``NOT_IN_3D`` refuses a 3-D problem (calibrate's
    curves call without it)."""
    if problem.yarn is not None and problem.yarn.spatial:
        if command in NOT_IN_3D:
            raise planar_only(problem, command, NOT_IN_3D[command])
        equilibrium(problem, Full())            # the variant's own refusals, then its build:
        return SpatialSteps(problem, Full())
    return equilibrium(problem, Full(), keep=keep, polish=POLISH)


class SpatialSteps(Equilibrium):
    """The 3-D model's equilibrium (``variants.equilibrium``: its full transcription) whose
    solves inside an inverse iteration are one load step from the last solved state: IPOPT
    from the predicted state x0 at the new parameters, and where that fails, the parameters
    stepped from the origin's (halved as needed, ``WeftSolver.continuation``). Without an
    origin, a solve is the 3-D model's own (load steps from the natural state). Measured on a
    2 x 2 control: with the default solve from x0 (four load steps from the natural
    parameters, each warm-started from the new actuation's prediction) the first trial steps
    failed and the trust radius fell to 3e-5 mm before it grew again (42 outer iterations).
    A step's IPOPT solves stop at ``TRIAL_ITER`` iterations (a failed step shrinks the control's
    trust region): on the 6 x 6 ``place_stitch_3d`` one trial of 3 mm pressed a crossing
    towards its core (objective 2.5e9) for over 1 100 iterations and 13 minutes."""

    _trial: WeftSolver | None = None        # the IPOPT instance of the steps, built on first use

    def solve(self, params: WeftParams | np.ndarray | None = None, x0: np.ndarray | None = None,
              *, continuation: int | None = None, start: str = DEFAULT_START,
              x0_params: WeftParams | np.ndarray | None = None,
              origin: tuple[np.ndarray, np.ndarray] | None = None) -> Solution:
        if origin is None or x0 is None:
            return super().solve(params, x0, continuation=continuation, start=start)
        params = self.as_params(params)
        p = params.vector()
        self.forward_solves += 1
        if self._trial is None:
            self._trial = WeftSolver(self.nlp, max_iter=TRIAL_ITER, verbose=self.solver.verbose,
                                     clock=self.solver.clock)
        self.solver.start_clock()
        rep = self._trial.once(p, x0)
        rep.attempts = [f"direct from the prediction: {rep.status} ({rep.iterations} it)"]
        if not rep.success:
            step = self._trial.continuation(p, origin[0], 1, p_from=np.asarray(origin[1]))
            step.add_effort(rep)
            step.attempts = rep.attempts + [f"load step from the last state: {step.status}"]
            rep = step
        return self.solution(rep, params)
