"""Solving a weft problem that has a yarn radius: :class:`ContactEquilibrium`, the forward
equilibrium with yarn contact (``variants.equilibrium`` chooses it for studies, ``solve``,
control, fit and calibrate).

The paper's model is solved first, as always; if its state has no new crossing and no gap
short of its requirement the contact is inactive and that is the answer. Otherwise contact
rounds start from it when it has no new crossing (its sides are then right), or load steps
with contact start from the last uncrossed state (the natural fabric, or the given start) —
see rounds.py. The report is on the paper's NLP (the contact variables and rows are dropped:
its solution, clamp reactions and loading path read exactly as without contact; by the
envelope theorem the reactions are still dU/d(target) with the active contacts), with the
result JSON's ``contact`` block beside it.
"""
from __future__ import annotations

import time
from collections import OrderedDict

import numpy as np

from ....errors import ProblemError
from ...model.contact.pairs import Pairs
from ...model.parametrisation import Full
from ...model.params import WeftParams
from ...model.problem import WeftProblem
from ...transcription.full import FullNLP
from ..blocks import Contact, ContactBlock
from ..sensitivity import ContactState
from ..solve import (DEFAULT_START, Equilibrium, Solution, SolveReport, WeftSolver,
                     solve_nlp, start_point)
from ..starts import needs_perturbation
from .active import ACTIVE, active_gaps
from .rounds import REFUTED, TOL, ContactRun, ContactSolver

STEPS = 4                  # first load steps of a contact path when none are asked for
KEEP = 16                  # solved contact states remembered (by base solution) for the KKT


class ContactRefused(ProblemError, ValueError):
    """A model or option that has no yarn contact yet (one line; exit 2 on the command line)."""


REDUCED_WHY = ("its loops are interpolated from representatives and contact pairs are between "
               "actual loops; solve the full model (knit-nlp solve --full, or Full() in Python)")


def refuse(problem: WeftProblem, what: str, why: str = REDUCED_WHY) -> ContactRefused:
    """The refusal of ``what`` for a problem with a yarn radius, naming ``[yarn] radius``,
    saying why and what to do instead."""
    return ContactRefused(problem.source, "yarn", "radius", f"{what}: no yarn contact yet: "
                          f"{why}, or remove [yarn] for the paper's model")


def solve_with_contact(base: FullNLP, solver: WeftSolver, contact: ContactSolver,
                       params: WeftParams, continuation: int | None = None,
                       x_start: np.ndarray | None = None, p_start: np.ndarray | None = None
                       ) -> tuple[SolveReport, ContactBlock]:
    """Solve the full model of a problem with ``[yarn] radius`` (module docstring) at
    ``params``, from ``x_start`` (a vector of ``base``, at parameters ``p_start``: load steps
    from there; unknown, the target's) if given: the report and the result JSON's ``contact``
    block. Load steps from a start that fail are tried again from the natural fabric."""
    problem = base.problem
    solver.start_clock()            # the contact solves share its clock (ContactSolver)
    p = params.vector()
    start = WeftParams.natural(problem).vector(), base.x0
    if x_start is not None and contact.clean(x_start):
        start = (p if p_start is None else p_start), x_start
    first = _paper_first(base, solver, params, x_start, continuation)
    if solver.progress is not None:
        solver.progress.done()
    run, route, why, fresh = _from_paper(base, contact, p, first)
    if run is None:
        run, route = _load_steps(base, contact, p, start, continuation, why, fresh)
    _tell_refuted(contact, run.report)
    return run.report, contact_block(problem, contact, run, route, problem.solver.tol)


def _tell_refuted(contact: ContactSolver, report: SolveReport) -> None:
    """An answer the check still refutes (``REFUTED``) says what is left, in its message."""
    if report.status == REFUTED and len(contact.left):
        report.detail = (f"not converged: the independent check finds {len(contact.left)} "
                         f"pairs short of their gap after the rounds with its pairs: "
                         f"{contact.named(contact.left)}")


def _from_paper(base: FullNLP, contact: ContactSolver, p: np.ndarray, first: SolveReport
                ) -> tuple[ContactRun | None, str, str, SolveReport]:
    """The paper's solution ``first`` as the answer (no contact needed) or contact rounds from
    it (it crosses no yarn): the run and its route; else None, why not, and a fresh report
    for the load steps that counts the effort spent (``_fresh``)."""
    if not first.success:
        return None, "", "the paper's model did not converge", _fresh(base, first)
    if not contact.out_of_time() and not contact.clean(first.x):
        return None, "", "yarns crossed in the paper's solution", _fresh(base, first)
    if contact.out_of_time():            # the load steps end at once, out of time
        return None, "", "out of time after the paper's model", _fresh(base, first)
    pairs = contact.pairs(first.x)
    refuted = None
    if not contact.violations(pairs, TOL).any() and not contact.out_of_time():
        refuted = contact.refuted(first.x)       # the check's last word (rounds.py, 5.)
        if len(refuted) == 0:
            return (ContactRun(first, pairs, np.zeros(len(pairs))),
                    "paper's model: no contact needed", "", first)
    run = contact.run(p, p, first.x, 1, _fresh(base, first), extra=refuted)
    _keep_path(run.report, first)
    if run.report.success:
        return run, "contact rounds from the paper's solution (no yarn crossed in it)", "", first
    spent = _fresh(base, run.report, f"contact rounds from the paper's solution: "
                   f"{run.report.status}")
    return None, "", "the contact rounds from the paper's solution failed", spent


def _load_steps(base: FullNLP, contact: ContactSolver, p: np.ndarray,
                start: tuple[np.ndarray, np.ndarray], continuation: int | None, why: str,
                report: SolveReport) -> tuple[ContactRun, str]:
    """Load steps with contact from ``start`` (parameters, state: uncrossed) into ``report``
    (``_fresh``), and from the natural fabric where those fail; the run and its route. From a
    start at unknown parameters every step is at the target: one is enough, and a failed one
    is not halved."""
    p_from, x_from = start
    natural = x_from is base.x0
    where = "the natural fabric" if natural else "the start"
    steps = 1 if np.array_equal(p_from, p) else continuation or STEPS
    run = contact.run(p, p_from, x_from, steps, report)
    if run.report.success or natural:
        return run, f"load steps with contact from {where} ({why})"
    run = contact.run(p, WeftParams.natural(base.problem).vector(), base.x0,
                      continuation or STEPS,
                      _fresh(base, run.report, f"load steps from the start: {run.report.status}"))
    return run, (f"load steps with contact from the natural fabric ({why}; the steps from the "
                 "start failed)")


def _paper_first(base: FullNLP, solver: WeftSolver, params: WeftParams, x0, continuation):
    """The paper's model, tried once: a continuation when one is asked for, else one IPOPT
    solve from the usual start (no retries: where it fails, contact takes over), or the
    perturbed starts where the natural yarn is straight and compressed."""
    if continuation or (x0 is None and needs_perturbation(base, params.vector())):
        # asked-for steps, or a straight yarn under compression: the paper's perturbed starts
        return solve_nlp(base, solver, params=params, x0=x0, continuation=continuation)
    t0 = time.perf_counter()
    levels: list[str] = []
    x = x0 if x0 is not None else start_point(base, params.vector(), DEFAULT_START, levels)
    rep = solver.once(params.vector(), x)
    rep.solve_s = time.perf_counter() - t0
    rep.attempts = levels + [f"direct: {rep.status} ({rep.iterations} it)"]
    return rep


def _fresh(base: FullNLP, spent: SolveReport,
           note: str = "paper's model (no contact) first") -> SolveReport:
    """An empty report that already counts the effort (and the attempts, ``note`` added) of
    what was tried before."""
    rep = SolveReport(False, "", base.x0, np.zeros(base.n_constraints), np.nan, 0, 0.0)
    rep.add_effort(spent)
    rep.attempts = list(spent.attempts) + [note]
    return rep


def _keep_path(report: SolveReport, first: SolveReport) -> None:
    """Rounds at the target after a continuation keep that continuation's loading path."""
    if first.path:
        report.path = first.path[:-1] + report.path[-1:]
        report.continuation_steps = first.continuation_steps


def contact_block(problem, contact: ContactSolver, run: ContactRun, route: str,
                  tol: float) -> ContactBlock:
    """The result JSON's ``contact``: radius, pairs in reach, active contacts with their
    forces (minus the gap rows' multipliers, in the problem's force unit), smallest gaps,
    the thick-yarn pairs, crossings against the natural fabric, and the effort."""
    pairs, force, gap, active = _active(contact, run, tol)
    largest = float(force[active].max(initial=0.0))
    x = run.report.x
    look = contact.look(x)
    verdict = look.verdict
    two_r = 2 * contact.radius
    pts = _contact_points(look.curves, pairs.select(active))
    n = problem.wales
    found = run.pairs
    free = found.required >= two_r
    thick = (found.required > 0) & ~free
    return ContactBlock(
        radius=contact.radius, route=route, pairs_in_reach=len(found),
        active=int(active.sum()),
        smallest_gap=float(found.gap[free].min()) if free.any() else None,
        smallest_gap_over_2r=float(found.gap[free].min() / two_r) if free.any() else None,
        thick_pairs=int(thick.sum()),
        thick_smallest_gap_over_required=float(np.min(found.gap[thick] / found.required[
            thick])) if thick.any() else None,
        interlock_pairs=int(np.sum(found.required <= 0)),
        largest_force=largest if active.any() else 0.0, force_unit=problem.units.force,
        new_crossings=verdict.n_new, lost_designed_crossings=verdict.lost,
        contacts=tuple(Contact(((int(a // n) + 1, int(a % n) + 1),
                                (int(b // n) + 1, int(b % n) + 1)),
                               (float(sa), float(sb)), tuple(pt.tolist()), float(f), float(g),
                               float(q))
                       for a, sa, b, sb, pt, f, g, q in zip(
                           pairs.kA[active], pairs.sA[active], pairs.kB[active], pairs.sB[active],
                           pts, force[active], gap[active], pairs.required[active])),
        solves=len(run.rounds),
        contact_nlp={"n_variables": run.n_variables, "n_constraints": run.n_constraints})


def _active(contact: ContactSolver, run: ContactRun, tol: float
            ) -> tuple[Pairs, np.ndarray, np.ndarray, np.ndarray]:
    """The pairs whose contacts the block lists, their forces, gaps and which are active.
    When the last contact solve ended at the run's state: its pairs with their gap rows'
    values, judged by ``ContactSolver.touching`` (``active.active_gaps``: the set the rounds
    hold and the control's sensitivities use).
    Otherwise (no contact solve, or a failed run): the run's pairs with their carried
    multipliers and searched gaps, active where they push."""
    if contact.solved_at(run.report.x):
        last = contact.last
        return last.pairs, -last.lam, last.gap, contact.touching()
    # a failed run's state is no solve's: the rows' values are unknown, the force alone judges
    force = -run.lam_gap
    largest = float(force.max(initial=0.0))
    return run.pairs, force, run.pairs.gap, force > max(ACTIVE * largest, 10 * tol)


def _contact_points(curves, pairs: Pairs) -> np.ndarray:
    """Midpoints of the contacts' two centreline points."""
    if len(pairs) == 0:
        return np.zeros((0, 2))
    return 0.5 * (curves.points(pairs.kA, pairs.sA) + curves.points(pairs.kB, pairs.sB))


class ContactEquilibrium(Equilibrium):
    """The full model of a problem with ``[yarn] radius``: the paper's NLP and IPOPT instance
    built once (its solutions, reactions and loading paths read as without contact) and the
    contact NLP grown with the pairs the solves meet (:class:`ContactSolver`). Every solve's
    contact block and its accepted contact solve (:class:`ContactState`, with its active gap
    rows) are kept for the last ``keep`` base solutions: the sensitivities and the stability
    check at a solution hold its active contacts (``sensitivity``). ``polish``: re-solves with
    the pairs searched on each solution (``ContactSolver.polish``; the inverse problems')."""

    with_contact = True

    def __init__(self, problem: WeftProblem, *, verbose: bool | None = False, keep: int = KEEP,
                 polish: int = 0) -> None:
        super().__init__(problem, Full(), verbose=verbose)
        self.contact = ContactSolver(self.solver, problem.yarn.radius)
        self.keep, self.polish = keep, polish
        self.states: OrderedDict[bytes, ContactState | None] = OrderedDict()
        self.blocks: dict[bytes, ContactBlock] = {}
        self._run: ContactRun | None = None

    @property
    def build_s(self) -> float:
        """The paper's NLP and IPOPT instance, every contact NLP built, the KKT Functions."""
        return self._build_s + self.contact.build_s

    def solve(self, params: WeftParams | np.ndarray | None = None, x0: np.ndarray | None = None,
              *, continuation: int | None = None, start: str = DEFAULT_START,
              x0_params: WeftParams | np.ndarray | None = None,
              origin: tuple[np.ndarray, np.ndarray] | None = None) -> Solution:
        """Solve with contact at ``params``: one load step from ``origin`` (a solved state and
        its parameters) when given and it succeeds (the path the clamps travel in the control
        iteration, halved where yarns would cross), else :func:`solve_with_contact` from
        ``x0`` (load steps from it, at ``x0_params`` if known) or the paper's solution or the
        natural fabric. ``start`` is the paper's model's own (its multilevel start)."""
        params = self.as_params(params)
        p = params.vector()
        self.forward_solves += 1
        self.contact.last = None
        rep = self._from_origin(p, origin) if origin is not None else None
        if rep is None:
            p_start = None if x0_params is None else self.as_params(x0_params).vector()
            rep, block = solve_with_contact(self.nlp, self.solver, self.contact, params,
                                            continuation, x0, p_start)
        else:
            block = contact_block(self.problem, self.contact, self._run,
                                  "one load step with contact from the last solved state",
                                  self.problem.solver.tol)
        if (self.polish and rep.success and self.contact.last is not None
                and self.contact.polish(p, rep, self.polish)):
            last = self.contact.last
            block = contact_block(self.problem, self.contact, ContactRun(rep, last.pairs, last.lam),
                                  block.route + ", polished", self.problem.solver.tol)
        self._remember(rep, block)
        return self.solution(rep, params)

    def solution(self, report: SolveReport, params: WeftParams | np.ndarray) -> Solution:
        """As :meth:`Equilibrium.solution`, with the contact solve behind x (``contact``) and
        the result JSON's ``contact`` block (None for an x this equilibrium did not solve)."""
        sol = super().solution(report, params)
        key = np.asarray(report.x).tobytes()
        sol.contact = self.states.get(key)
        sol.contact_block = self.blocks.get(key)
        return sol

    def _from_origin(self, p: np.ndarray, origin: tuple[np.ndarray, np.ndarray]
                     ) -> SolveReport | None:
        """contact.run from a solved, uncrossed state to p in one load step (halved as needed)."""
        x, p_from = origin
        if not self.contact.clean(x):
            return None
        self.solver.start_clock()           # the contact solves share its clock
        report = SolveReport(False, "", x, np.zeros(self.nlp.n_constraints), np.nan, 0, 0.0)
        self._run = self.contact.run(p, np.asarray(p_from, dtype=float), x, 1, report)
        _tell_refuted(self.contact, self._run.report)
        return self._run.report if self._run.report.success else None

    def _remember(self, rep: SolveReport, block: ContactBlock) -> None:
        """Keep the contact NLP's solution that belongs to the base solution rep.x."""
        key = np.asarray(rep.x).tobytes()
        state = None
        if rep.success and self.contact.solved_at(rep.x):
            last = self.contact.last
            cnlp = last.cnlp
            active = active_gaps(cnlp.gaps(last.x, last.sigma), last.required,
                                 cnlp.gap_multipliers(last.lam_g), last.used,
                                 self.problem.solver.tol, 2 * self.contact.radius)
            state = ContactState(cnlp, last.params, last.x, last.lam_g, active, block)
        self.states[key] = state
        self.blocks[key] = block
        while len(self.states) > self.keep:
            old, _ = self.states.popitem(last=False)
            self.blocks.pop(old, None)

    def state(self, x: np.ndarray) -> ContactState | None:
        """The contact solve behind base solution x (None: no contact solve, none active).
        A ValueError for an x this equilibrium did not solve (or forgot: ``keep``): its
        sensitivities would silently miss the contacts."""
        key = np.asarray(x).tobytes()
        if key not in self.states:
            raise ValueError(f"no contact solve of this equilibrium ends at this state (it "
                             f"keeps the last {self.keep}): solve it here first")
        return self.states[key]

    contact_state = state
