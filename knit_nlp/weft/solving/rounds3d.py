"""The 3-D model's rounds of other contacts (docs/weft3d.md, "Other contacts"): after a solve,
the independent check over all pairs of yarn pieces (``model.spatial.proximity``); pairs of
pieces closer than touch (2r) that are neither one piece of yarn nor a designed crossing's own
contact, and whose sample points the neighbour list (``model.spatial.repulsion``) does not
hold, are added to the list, and the NLP is built again and solved from the answer (one
direct solve: load steps from the natural state would start over), each new pair's law thinned
by its natural distance (C3) and shifted to start at most half way into the shell. A
designed contact's own pairs are judged by windows at its crossing's current material
coordinates σ (the yarn slides through its crossings), not the natural ones. When a pair is
found already inside the hard core (the yarns passed each other between the list's sample
points), a shift would keep it there, so the round starts over instead: load steps from the
natural state, the new pairs' law unshifted, so that they hold from the start. Where that
solve fails, the answer before it stands and the round says so. At most ``ROUNDS`` rounds.

When the check still finds pairs of loops inside the hard core after them, the samples are
too far apart for the list to hold the yarns: the repulsion judges sample pairs, the check
the curves between them (on the 6 × 6 pushes the sample pairs nearest the check's pairs in
the core were 0.70 and 0.72 mm apart, the curves 0.638 and 0.644 mm; core 0.65 mm). The list
is then rebuilt on samples ``FINER`` times finer, once, the solve starts over by load steps
from the natural state, and the rounds follow again on the finer samples (its record: ``"samples"``, the new count per loop). Each
round's pairs and status are recorded on the NLP (``SpatialNLP.rounds``) for the result JSON
and the summary. The check has the last word, as in the plane (``contact.rounds``): an answer it
still finds with yarns through each other after the rounds (pairs of loops inside the hard
core, or a designed crossing flipped) is not converged, ``REFUTED`` (exit 1), its message
naming what is left.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..model.spatial.proximity import ProximityReport
from ..model.spatial.state import spatial_samples, spatial_state
from ..model.spatial.repulsion import MOST, Neighbours, missing, natural_distance, none
from ..transcription.spatial import SpatialNLP, build_spatial
from .contact.rounds import REFUTED
from .solve import Solution, SpatialSteps

ROUNDS = 3
FINER = 2                   # a refuted answer's samples made this many times finer, once


class SpatialEquilibrium(SpatialSteps):
    """The 3-D model's equilibrium: ``SpatialSteps`` (the inverse problems' trial steps) with
    the rounds of other contacts. ``rounds``: at most this many (0 in the inverse problems,
    ``inverse.forward``: a round rebuilds the NLP with more variables, and the states an
    outer iteration keeps would no longer fit it). ``refute``: an answer the check still
    finds through each other is not converged (``REFUTED``; off in the inverse problems,
    whose trial states are judged by their own outer iteration)."""

    extra: Neighbours | None = None
    rounds_max: int = ROUNDS
    refute: bool = True

    def solve(self, params: Any = None, x0: np.ndarray | None = None, **kw: Any) -> Solution:
        """The forward solve, its rounds and, where refuted, the finer samples: one answer on
        one ``[solver] max_time`` budget (the clock held while the rounds and the finer
        samples solve again, ``solve.Clock``: each start-over had restarted it, so a refuted
        20 x 20 pull with a 900 s budget ran past 20 minutes)."""
        sol = super().solve(params, x0, **kw)
        clock = self.solver.clock
        clock.held = True
        try:
            sol, rounds = self._rounds(sol)
            if self._coarse(sol):
                sol, more = self._finer(sol)
                rounds += more
        finally:
            clock.held = False
        self.nlp.rounds = rounds
        if sol.success and self.refute:
            _refuted(sol, self.report(sol.x))
        return sol

    def _rounds(self, sol: Solution) -> tuple[Solution, list[dict[str, Any]]]:
        """At most ``rounds_max`` rounds of other contacts from ``sol`` (module docstring)."""
        rounds: list[dict[str, Any]] = []
        for _ in range(self.rounds_max):
            if not sol.success or self.nlp.neighbours is None:
                break
            new, through = self.missing(sol.x)
            if not len(new):
                break
            sol, status = self._again(sol, new, through)
            rounds.append({"added": len(new), "status": status, "started_over": through})
            if status != "Solve_Succeeded":
                break
        return sol, rounds

    def _coarse(self, sol: Solution) -> bool:
        """Whether the check still finds pairs of loops inside the hard core after the rounds
        and the list's samples can be made FINER (at most ``repulsion.MOST`` per loop)."""
        nb = self.nlp.neighbours
        if not (sol.success and self.refute and self.rounds_max and nb is not None
                and FINER * nb.samples <= MOST):
            return False
        return self.report(sol.x).n_inside_core > 0

    def _finer(self, sol: Solution) -> tuple[Solution, list[dict[str, Any]]]:
        """The samples FINER times finer (module docstring): the natural list rebuilt on them,
        load steps from the natural state, then the rounds again, which find the other
        contacts on the finer samples; where that solve fails, ``sol`` and the failure's
        status."""
        pr, old, old_solver, old_kkt = self.problem, self.nlp, self.solver, self._kkt
        S = FINER * old.neighbours.samples
        # the coarse rounds' pairs are not carried over: split onto the finer samples (each
        # piece cut in two, unshifted) they stalled the 6 x 6 wale push at 25 % of its load,
        # objective 2,087 N·mm; the rounds find the other contacts again (clean, 77 s)
        extra = none(S)
        self.rebuild(build_spatial(pr, extra=extra))
        again = SpatialSteps.solve(self, sol.params)
        record = {"added": 0, "status": again.status, "started_over": True, "samples": S}
        if not again.success:
            self.nlp, self.solver, self._kkt = old, old_solver, old_kkt
            sol.add_effort(again)
            return sol, [record]
        self.extra = extra
        again.add_effort(sol)
        again, rounds = self._rounds(again)
        return again, [record] + rounds

    def report(self, x: np.ndarray) -> ProximityReport:
        """The independent all-pairs check of the state x (``model.spatial.proximity``)."""
        pr = self.problem
        return spatial_state(pr, self.nlp.centrelines3d(x, spatial_samples(pr)))

    def missing(self, x: np.ndarray) -> tuple[Neighbours, bool]:
        """The pairs the check finds closer than touch that the list lacks (module docstring),
        no designed contact's own by the windows at the crossings' current σ (a round rebuilds
        the NLP: the windows follow the yarn sliding through its crossings), their law thinned
        by their natural distance (C3: a pair beside a wrap may be pressed at rest), each
        shifted so that it starts no deeper than half way into the shell (R1: a pair found
        inside the core would make the energy infinite at the answer), and whether one is
        inside the core (then unshifted: the round starts over)."""
        nlp: SpatialNLP = self.nlp
        pr, shape = self.problem, nlp.shape
        rep = self.report(x)
        sigma = nlp.sigmas(x)
        new = missing(rep.touching, nlp.neighbours, pr.L, pr.wales, shape, sigma)
        if not len(new):
            return new, False
        scale = pr.yarn.shell().thinning(natural_distance(new, shape, pr.courses, pr.wales))
        inside = rep.touching.select(rep.touching.d < 2 * pr.yarn.core_radius)
        if len(missing(inside, nlp.neighbours, pr.L, pr.wales, shape, sigma)):
            return Neighbours(new.ka, new.qa, new.kb, new.qb, new.shift, scale,
                              new.samples), True
        pts = nlp.sample_points(x, new.samples)
        d = np.linalg.norm(pts[new.ka, new.qa] - pts[new.kb, new.qb], axis=1)
        half = pr.yarn.radius + pr.yarn.core_radius
        return Neighbours(new.ka, new.qa, new.kb, new.qb, np.maximum(0.0, half - d),
                          scale, new.samples), False

    def _again(self, sol: Solution, new: Neighbours, over: bool = False) -> tuple[Solution, str]:
        """The NLP with ``new`` pairs added, solved from ``sol``'s answer (or, ``over``, by
        load steps from the natural state); where that fails, the answer before it (and the
        failure's status)."""
        old, old_solver, old_kkt, x = self.nlp, self.solver, self._kkt, sol.x
        extra = new if self.extra is None else self.extra.plus(new)
        self.rebuild(build_spatial(self.problem, extra=extra))
        if over:
            again = SpatialSteps.solve(self, sol.params)
        else:
            x0 = self.nlp.lift3d(old.coefficients(x), old.elevations(x), old.starts3d(x),
                                 old.sigmas(x))
            again = self.solver.once(sol.params.vector(), x0)
        if not again.success:
            self.nlp, self.solver, self._kkt = old, old_solver, old_kkt
            sol.add_effort(again)
            return sol, again.status
        self.extra = extra
        again.add_effort(sol)                   # the solve it replaces was paid for too
        return (again if over else self.solution(again, sol.params)), again.status


def _refuted(sol: Solution, rep: ProximityReport) -> None:
    """Mark ``sol`` not converged (``REFUTED``) when the check ``rep`` finds yarns through each
    other: pairs of loops inside the hard core or a flipped designed crossing (a crossing order
    it could not read is no refutation: the check says so itself)."""
    if rep.n_inside_core == 0 and not rep.flipped:
        return
    what = [f"{rep.n_inside_core} pairs of loops inside the hard core 2R_c = {rep.core:.4g}"]
    if rep.flipped:
        what.append(f"{len(rep.flipped)} designed crossings flipped")
    if rep.smallest is not None:
        what.append(f"smallest distance {rep.smallest:.4g}")
    sol.success, sol.status = False, REFUTED
    sol.detail = ("not converged: after the rounds of other contacts the independent check "
                  f"still finds the yarns through each other ({'; '.join(what)})")
