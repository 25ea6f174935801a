"""The reduced model condensed to the paper's variables, with derivatives assembled by hand.

Variables: the reduced parameters z (eqs. 22-27, ``reduction.course_map``) and the start of
every shooting segment of ``segment`` loops along each course (the first is the course start
(x_i^0, y_i^0)); with one segment per course this is the paper's count p·q·2t + 2p + 2m. Inside
a segment loop starts are not variables: the start of loop (i, j) is its segment's start plus
the end displacements of the segment's earlier loops (eq. 1); between segments the chaining
of eq. (1) is a constraint ("chain" rows: the next segment starts where this one ends).
Multiple shooting, because single shooting along whole courses made IPOPT take 42-89
iterations on diagonal pulls (the chained positions are far more nonlinear in z than each
segment's), against 8-12 in segments of 12 loops, to the same minimum
(docs/measurements.md).

Every nonlinear term is one loop's integral D_k(a_k) (2 × P displacements at the material points
the model needs) with a_k = T_k·z; D_k, J_k and Σ_p μ_kp∇²D_kp are closed forms over all loops
at once (``kinematics.LoopIntegrals``, the full model's quadrature; measured faster than mapped
CasADi Functions). The model is split by job, each step a class adding to the last:

- ``shooting.Shooting``: the space (maps, segments, points, layouts, units) and the state at w;
- ``lagrangian.Lagrangian``: energy, constraints, the gradient of the Lagrangian by adjoints;
- ``assembly.Assembly``: the Jacobian and the Hessian of the Lagrangian, block by block;
- ``glue.oracles``: the ``casadi.Callback`` oracles IPOPT calls; ``lifting.lift``: loops into z;
- here, :class:`CondensedNLP` (the transcription protocol) and :func:`build_condensed`.
"""
from __future__ import annotations

from functools import cached_property

import numpy as np

from ...model.parametrisation import Reduced
from ...model.problem import WeftProblem
from ..protocol import WeftNLP
from ..reduction import with_clamped
from .assembly import Assembly
from .glue import oracles
from .lifting import Pattern, lift, normal_pattern

RANK_TOL = 1e-8        # singular values below this fraction of the largest count as zero


class CondensedNLP(Assembly, WeftNLP):
    """The condensed reduced NLP: the transcription protocol over the shooting space."""

    model = "reduced"
    extended_from: Reduced | None = None   # the representatives asked for, if build_condensed
    #                                        added the clamped courses and wales

    def __init__(self, pr: WeftProblem, reduced: Reduced, segment: int | None = None) -> None:
        super().__init__(pr, reduced, segment)
        self._sparsities()
        self.nlp, self.nlpsol_options, self._callbacks = oracles(self)
        self.x0 = self.lift(np.broadcast_to(pr.natural.coeffs,
                                            (pr.courses, pr.wales, self.nc)).copy(),
                            pr.natural_starts())

    def coefficients(self, x: np.ndarray) -> np.ndarray:
        """Loop coefficients (m, n, 2t+2) of a solver vector."""
        return self._coeffs(self.w(x))

    def starts(self, x: np.ndarray) -> np.ndarray:
        """Loop start points (m, n, 2): segment starts plus the chained end displacements."""
        st = self._state(self.w(x))
        return st["pos"][:, :, self.pL] - st["Y"][:, :, self.pL]

    def special_positions(self, x: np.ndarray) -> np.ndarray:
        """Positions (2 × specials) of the clamped and loaded material points."""
        st = self._state(self.w(x))
        return np.array([st["pos"][q.i, q.j, q.col] for q in self.sp_points]).T.reshape(2, -1)

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """The solver vector whose loops are closest (least squares in the coefficients) to
        ``coeffs`` (m, n, 2t+2), with the segment starts of ``starts`` (``lifting``)."""
        return lift(self, self.normal_pattern, coeffs, starts)

    @cached_property
    def normal_pattern(self) -> Pattern:
        """The lifting's normal-matrix sparsity (``lifting.normal_pattern``), built once."""
        return normal_pattern(self)

    def representatives(self) -> dict:
        out: dict = {"courses": list(self.reduction.courses),
                     "wales": list(self.reduction.wales)}
        if self.extended_from is not None:
            asked = self.extended_from
            out["asked"] = {"courses": list(asked.courses), "wales": list(asked.wales)}
        return out

    def clamp_rank(self) -> tuple[int, int]:
        """(rank, rows) of the clamps' rows of the single-shooting Jacobian at the natural
        start (the chaining rows eliminated, so it does not depend on the segments): rank <
        rows means the clamps are not independent in this reduced space (no LICQ; see
        ``with_clamped``)."""
        jac = self.clamp_jacobian(self.w(self.x0), self.p0)
        if jac.size == 0:
            return 0, jac.shape[0]
        sv = np.linalg.svd(jac, compute_uv=False)
        return int(np.sum(sv > RANK_TOL * sv[0])), jac.shape[0]


def build_condensed(pr: WeftProblem, reduced: Reduced = Reduced(),
                    segment: int | None = None) -> CondensedNLP:
    """The condensed reduced model of a problem over ``reduced`` (default: the corner form),
    with shooting segments of ``segment`` loops (default ``SEGMENT``).

    Where the clamps' constraints are dependent at the natural start (``clamp_rank``: the
    clamp rows of single shooting), the courses and wales of the
    clamped loops are made representative (``reduction.with_clamped``) and ``extended_from``
    records the representatives asked for. Measured: the 20 × 20 course pull over an even
    6 × 6 grid took 8 905 iterations to a "solved to acceptable level" and the corner form on
    30 × 30 converged to a state with every course alike; extended, 19 and 6 iterations, 0.06
    and 0.11 RMS from the full model (docs/measurements.md)."""
    cnlp = CondensedNLP(pr, reduced, segment=segment)
    rank, rows = cnlp.clamp_rank()
    wider = with_clamped(cnlp.reduction, pr) if rank < rows else cnlp.reduction
    if wider != cnlp.reduction:
        asked = cnlp.reduction
        cnlp = CondensedNLP(pr, wider, segment=segment)
        cnlp.extended_from = asked
    return cnlp
