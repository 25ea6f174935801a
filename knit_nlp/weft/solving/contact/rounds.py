"""Solving the full weft model with yarn contact: an active set grown between IPOPT solves.

1. The paper's model is solved as before (no contact): usually most pairs never touch.
2. The state is searched for contact pairs (pairs.py): closest points within reach of their
   required gap, and samples that passed through a yarn (with the side the natural fabric
   gives them, so a state with crossings is repaired, not trusted). Pieces around the state's
   designed crossings, wherever they slid, need no gap (zones.py).
3. Every pair goes into a slot of the contact NLP (rows.py) — slots are per pair of loops and
   reused: their material points, sides and bounds are parameters — and IPOPT solves the NLP
   with the gap rows as inequalities, from the current state.
4. The new state is searched again; the rounds stop when every pair meets its required gap to
   ``TOL`` (relative) with no crossing, and the contact points stopped moving along the yarns.
   A round whose pairs all nearly meet their gaps already starts IPOPT at a small barrier
   parameter (``SETTLE``). In the last step, contacts whose closest points keep sliding beside
   their slots are held a little wider apart than their gap (``SLIDE``) and need not stop.
5. The checker has the last word: at the target, the answer the rounds accept is searched as
   ``check`` searches it (pairs.checked_pairs: its own, finer sampling, its reach, its
   tolerance; the same rule, zones and crossing count). Pairs it finds short join the rounds
   (kept, reseated, in every later round of the step) and the rounds go on from the answer;
   after ``CHECKS`` such refutations the solve ends ``REFUTED`` (not converged), naming what
   is left.
A round needs a new build only when some pair of loops needs more slots than it has.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ...model.contact.crossings import Crossings, Verdict, designed_zones, find_crossings, judge
from ...model.contact.curves import Curves
from ...model.contact.natural import NaturalFabric
from ...model.contact.near import TooLarge
from ...model.contact.pairs import (Grid, Pairs, checked_pairs, find_pairs, pair_samples,
                                    reseat, short)
from ...model.contact.zones import Zones
from ...model.parametrisation import Full
from ...transcription.contact import ContactNLP, Slots
from ...transcription.factory import transcribe
from ...transcription.full import FullNLP
from ....limits import CHECK_ROWS
from ....outcome import OUT_OF_TIME
from ....progress import loading
from ..solve import OnClock, SolveReport, WeftSolver
from .active import active_gaps
from .matching import carry, contacts_moved, loop_pair_counts, lost_contacts, match, unrepeated

TOL = 1e-4                 # relative gap shortfall accepted at the end (target: 1e-3)
STEP_TOL = 0.05            # relative gap shortfall accepted at intermediate load steps
REACH = 0.02               # pairs within this many loop lengths of their required gap get a slot
MAX_ROUNDS = 12
# IPOPT from the last solve's point and multipliers (measured on the 10 x 10 pull, load 0.25 to
# 0.375 with 160 pairs: 13 iterations warm against 24 cold, the same energy to 4e-8)
WARM = {"warm_start_init_point": "yes", "mu_init": 1e-5, "warm_start_bound_push": 1e-9,
        "warm_start_mult_bound_push": 1e-9, "warm_start_slack_bound_push": 1e-9,
        "warm_start_slack_bound_frac": 1e-9, "warm_start_bound_frac": 1e-9}
WIDEST = 0.4               # the reach is widened (x2 per failed step) up to this many L ...
# ... but a step that let yarns cross is halved after one widening (to this many L): on the 6 x 6
# pull each such failed attempt cost ~40 s (a 100-200 iteration round) and widening to 0.4 L took
# 4 of them; halving then is 3x cheaper there. A solve that diverges (a body pushed by a load
# with nothing else to stop it) still widens to WIDEST.
WIDE_CROSSED = 0.04
# ... and a step whose contact NLP IPOPT found locally infeasible is halved at once: more pairs
# are more rows, they cannot make it feasible. The 6 x 6 jersey stretched between rigid edges at
# the acrylic's radius (docs/contact.md, "Stiffening") spent its whole 300 s budget at strain
# 0.10 on five widenings (500-860 IPOPT iterations each, every one infeasible)
INFEASIBLE = "Infeasible_Problem_Detected"
# ... and a search holding this many pairs is not widened at all: the reach widens everywhere,
# and doubling it triples the pairs (the natural 10 x 10 jersey: 1,760 pairs at 0.02 L, 5,640 at
# 0.04 L, 12,910 at 0.08 L, 61,958 at 0.4 L), each pair a slot of some 30 kB in the contact NLP
# (7 GB at 215,600 pairs: the 100 x 100 pull's first load step, whose widened search held
# 641,400; an earlier run of that pull was killed for memory at 24 GB: docs/contact.md); a
# fabric this large halves the step instead
WIDE_PAIRS = 20_000
MOVED = 0.5                # contact points that moved less than this many samples have settled
# a pair the search finds within this many samples of a pushing pair's points (s_A, s_B) is that
# contact; a pushing pair with none that close stays in the next solve (matching.lost_contacts).
# With one sample (the old rule) a line contact on the 4-loop wale pull cycled between two
# minima 0.035 samples apart: each round replaced the pair that pushed by the search's other
# one, the yarns rolled back, and the shortfall grew (5e-4 to 1.1e-3 over 12 rounds, then the
# reach was widened)
SAME = 0.01
FLIP = 1e-6               # a pair now this far (relative to L) on its other side passed through
CROSSED = "Contact_Crossing"        # the status of a step that let yarns cross
DEEP_PAIRS = "Contact_Deep_Pairs"   # ... and of one still nearly crossed after its restarts
ROUNDS_EXCEEDED = "Contact_Rounds_Exceeded"   # ... and of one whose rounds did not settle
REFUTED = "Contact_Check_Refuted"   # ... and of an answer the check still finds short (CHECKS)
# answers the check may refute in the last step before the solve gives up (REFUTED): each
# refutation adds the check's short pairs and costs a round or more (on 40 random 2 x 2 to
# 4 x 4 pulls and pushes with r 0.05-0.8 no solve came to REFUTED; tests/test_contact_last_word.py)
CHECKS = 3
# every slot, used or not, costs its rows in every evaluation and its 5 variables and 6 rows in
# every KKT factorisation, and a rebuild is cheap (0.2 s at 3,000 slots): measured on the 10 x
# 10 diagonal pull, SPARE 0.5 / SHRINK 2 held 2.85 slots per pair (16.1 s), 0.1 / 1.2 held
# 1.4 (10.0 s), 0 / 1 (a rebuild nearly every round) 7.9 s but 6 x 6 in 7.5 s against 4.3 s
SPARE = 0.1                # extra slots per pair of loops, relative, when (re)building
SHRINK = 1.2               # a pool above this many times the pairs' need (with SPARE) is rebuilt
MIN_POOL = 64              # ... but a pool of this many slots is never too large
# a solve that ends with pairs below (1 - DEEP) of their required gap (pairs it had no slot for,
# out of reach where it started: the yarns nearly crossed) restarts its round from the round's
# start with those pairs, at most RESTARTS times a step: on the 6 x 6 pull continuing from the
# nearly crossed state took 100-220 IPOPT iterations a round and still let yarns cross. (From
# the step's start, a second round's restart on the 100 x 100 pull cost a first round over
# again, 97 iterations and 1,362 s, to reach the state the second round had started from.) A
# step still nearly crossed after its restarts fails (DEEP_PAIRS) and is halved
DEEP = 0.5
RESTARTS = 2
# a round whose pairs all meet their gaps to SETTLE (relative) already starts IPOPT at the barrier
# parameter a solve ends with (SETTLE_MU x tol) instead of WARM's mu_init, from which IPOPT walked
# the barrier down again every round: the last rounds of the 4 x 4 pull take 10, 9 and 7
# iterations instead of 16, 15 and 13, of the 6 x 6 pull 17, 13 and 14 instead of 18, 18 and 22,
# the 10 x 10 pull's last 8 instead of 19 (same minima). A round that starts with pairs far from
# their gaps is slower so (started so, the 10 x 10 pull's round with 30 pairs short by up to 0.86
# took 37 iterations instead of 26)
SETTLE = 1e-2
SETTLE_MU = 0.1
# the closest points of a contact slide along the yarns while the slot holds the gap at fixed
# material points: in the final step, after SLIDES rounds in a row whose short pairs all lie
# within a sample of a slot of the solve that just ended (sliding contacts, not new ones) and
# are short by at most SLIDE_MOST / SLIDE, the slots keep SLIDE times that shortfall more than
# the required gap (the margin only grows within a step). Without it the 10 x 10 pushes by a
# third found 10-30 pairs 0.1-0.9 % short beside the slots round after round (7.0e-3, 6.2e-3,
# 1.1e-3, 6.0e-3 on the diagonal push) and ran out of time. After one such round already, the
# squeezed loop's single contact ended 1.0033 x 2r apart instead of touching. The answer is
# judged against the required gap itself, by the rounds (TOL) and by the check.
SLIDE = 2.0
SLIDE_MOST = 0.02
SLIDES = 2


@dataclass
class Round:
    """One IPOPT solve with contact: what it was for, pairs, slots, iterations and status."""

    note: str
    pairs: int
    slots: int
    rebuilt: bool
    iterations: int
    status: str
    seconds: float


@dataclass
class Look:
    """What a state's pair search, crossing check and held pairs need: its centrelines, its
    crossings, their verdict against the natural fabric and the designed zones (zones.py)."""

    x: np.ndarray
    curves: Curves
    found: Crossings
    verdict: Verdict
    zones: Zones


@dataclass
class Warm:
    """What a contact solve starts its multipliers from: the base rows' multipliers of the last
    solve, its pairs and their gap multipliers (carried to the new pairs by matching)."""

    lam_base: np.ndarray
    pairs: Pairs
    lam_gap: np.ndarray


@dataclass
class ContactRun:
    """The outcome of a contact solve: the base-layout solution and what contact did."""

    report: SolveReport
    pairs: Pairs
    lam_gap: np.ndarray                # multiplier of each pair's gap row (≤ 0: pushing apart)
    rounds: list[Round] = field(default_factory=list)
    n_variables: int = 0
    n_constraints: int = 0
    solved: Warm | None = None     # the last solve's pairs and multipliers (its warm start)


@dataclass
class ContactSolve:
    """An accepted solve of the contact NLP (what the sensitivities with contact and the
    result's active contacts need): the NLP, its parameters (base p, s_A, s_B, σ, cell masks),
    its solution and multipliers, per slot which are in use, their sides σ and required gaps;
    per pair its slot's gap multiplier and the gap row's value."""

    cnlp: ContactNLP
    params: np.ndarray
    x: np.ndarray
    lam_g: np.ndarray
    used: np.ndarray
    sigma: np.ndarray
    required: np.ndarray
    pairs: Pairs
    lam: np.ndarray
    gap: np.ndarray


@dataclass
class Step:
    """The outcome of a load step (:meth:`ContactSolver.step`): ``status`` (``Solve_Succeeded``,
    or why it failed: IPOPT's status, ``CROSSED``, ``DEEP_PAIRS``, rounds exceeded); when it
    succeeded, the state, its pairs, the warm start for the next step and the pairs'
    multipliers."""

    status: str
    x: np.ndarray | None = None
    pairs: Pairs | None = None
    warm: Warm | None = None
    lam: np.ndarray | None = None
    left: Pairs | None = None          # REFUTED: the pairs the check still finds short

    @property
    def success(self) -> bool:
        return self.x is not None


class ContactSolver(OnClock):
    """Contact rounds for one problem: the base NLP is ``solver``'s (the paper's IPOPT
    instance); the contact NLP's solvers share its clock (:meth:`WeftSolver.sibling`)."""

    def __init__(self, solver: WeftSolver, radius: float, per_loop: int | None = None) -> None:
        base = solver.wnlp
        pr = base.problem
        self.base_solver = solver
        self.clock = solver.clock        # the deadline shared with the paper's solves
        self.base, self.radius = base, float(radius)
        self.fabric = NaturalFabric.of(pr, radius)
        per_loop = per_loop or pair_samples(pr.L, radius)     # the rule check shares
        self.grid = Grid(pr.courses, pr.wales, pr.L, per_loop)
        self.reach = REACH * pr.L
        self.cnlp: ContactNLP | None = None
        self.solver: WeftSolver | None = None
        self.settler: WeftSolver | None = None     # the same NLP's IPOPT for settling rounds
        self.build_s = 0.0
        self.log = None                  # a callable receiving every Round as it ends
        self.last: ContactSolve | None = None   # the last successful solve of the contact NLP
        self.left = Pairs.empty()        # what the check found short in a REFUTED answer
        self._look: Look | None = None

    def out_of_time(self) -> bool:
        """Whether the shared deadline has passed: checked before every phase that is not an
        IPOPT solve (a pair search, the check's search, a build of the contact NLP), so that
        ``[solver] max_time`` is overrun by one phase at most (a 10 x 10 pull at max_time = 5
        ran its first pair search, 5.2 s under load, after the deadline had passed)."""
        return time.perf_counter() >= self.deadline

    def look(self, x_base: np.ndarray) -> Look:
        """A base-layout state's curves, crossings, verdict and designed zones. The last
        state's are kept: a round asks for them in its pair search, its crossing check and
        its held pairs, and the result block once more."""
        if self._look is None or not np.array_equal(self._look.x, x_base):
            curves = Curves.of(self.base.coefficients(x_base), self.base.starts(x_base),
                               self.base.problem.L)
            found = find_crossings(curves, self.grid)
            verdict = judge(self.fabric, found, self.grid.courses, self.grid.wales)
            zones = designed_zones(self.fabric, curves, self.grid, found, verdict.new)
            self._look = Look(np.array(x_base, dtype=float), curves, found, verdict, zones)
        return self._look

    def pairs(self, x_base: np.ndarray) -> Pairs:
        """Contact pairs of a base-layout state."""
        look = self.look(x_base)
        return find_pairs(self.fabric, look.curves, self.grid, self.reach, look.zones)

    def _slots(self, pairs: Pairs) -> bool:
        """Make sure every pair of loops has enough slots; True when rebuilt. The pool grows by
        ``SPARE`` where a pair of loops lacks slots, and is rebuilt for the pairs alone (with
        ``SPARE``) once it holds more than ``SHRINK`` times that: every slot costs its
        quadrature in every evaluation, used or not (a widened search once left 4,700 slots
        for 430 pairs on the 6 x 6 pull)."""
        need = loop_pair_counts(pairs.kA, pairs.kB)
        have = {} if self.cnlp is None else loop_pair_counts(self.cnlp.kA, self.cnlp.kB)
        want = {k: int(np.ceil(v * (1 + SPARE))) for k, v in need.items()}
        small = max(sum(want.values()), MIN_POOL)
        fits = self.cnlp is not None and all(have.get(k, 0) >= v for k, v in need.items())
        if fits and self.cnlp.n_slots <= SHRINK * small:
            return False
        if self.cnlp is not None and self.cnlp.n_slots > SHRINK * small:
            have = {}                          # too large: the pairs' own slots only
        merged = {k: (have[k] if have.get(k, 0) >= need.get(k, 0) else want[k])
                  for k in {**have, **want}}
        if not merged:
            merged = {(0, 0): 1}               # one unused slot: the NLP exists from the start
        kA, kB = [], []
        for (a, b), v in sorted(merged.items()):
            kA += [a] * v
            kB += [b] * v
        t0 = time.perf_counter()
        self.cnlp = transcribe(self.base.problem, Full(), contact=Slots(np.array(kA), np.array(kB)),
                               base=self.base)
        self.solver = self.base_solver.sibling(self.cnlp, ipopt=WARM)
        self.settler = None                        # built again when a round settles
        self.build_s += time.perf_counter() - t0
        return True

    def _assign(self, pairs: Pairs) -> tuple[np.ndarray, ...]:
        """Per slot: s_A, s_B, σ, required gap, in use; and each pair's slot."""
        c = self.cnlp
        n = c.n_slots
        sA, sB = np.full(n, 0.5 * self.base.problem.L), np.full(n, 0.5 * self.base.problem.L)
        sigma, required, used = np.ones(n), np.zeros(n), np.zeros(n, dtype=bool)
        slot_of = np.zeros(len(pairs), dtype=int)
        free: dict[tuple[int, int], list[int]] = {}
        for q, key in enumerate(zip(c.kA.tolist(), c.kB.tolist())):
            free.setdefault(key, []).append(q)
        for i, key in enumerate(zip(pairs.kA.tolist(), pairs.kB.tolist())):
            q = free[key].pop(0)
            slot_of[i] = q
            sA[q], sB[q], sigma[q] = pairs.sA[i], pairs.sB[i], pairs.sigma[i]
            required[q], used[q] = pairs.required[i], True
        return sA, sB, sigma, required, used, slot_of

    def refuted(self, x_base: np.ndarray) -> Pairs:
        """The pairs the independent check finds short at a state (``check``'s own search,
        pairs.checked_pairs, on this state's curves and zones): empty when the check agrees.
        A search too large for check (CHECK_ROWS) is not made here either: check then says
        "not checked"."""
        look = self.look(x_base)
        pr = self.base.problem
        try:
            found, _ = checked_pairs(self.fabric, look.curves, pr.courses, pr.wales, look.zones,
                                     limit=CHECK_ROWS)
        except TooLarge:
            return Pairs.empty()
        return found.select(short(found))

    def named(self, pairs: Pairs, most: int = 4) -> str:
        """The loops and gaps of (the first ``most`` of) some pairs, for a message."""
        n = self.grid.wales
        order = np.argsort(pairs.gap / np.maximum(pairs.required, 1e-300))[:most]
        text = ", ".join(f"({a // n + 1},{a % n + 1})-({b // n + 1},{b % n + 1}) at "
                         f"{g / q:.4g} of its gap" for a, b, g, q in zip(
                             pairs.kA[order], pairs.kB[order], pairs.gap[order],
                             pairs.required[order]))
        return text + (f" and {len(pairs) - most} more" if len(pairs) > most else "")

    def violations(self, pairs: Pairs, tol: float) -> np.ndarray:
        """Pairs that miss their required gap by more than tol (relative)."""
        return pairs.gap < pairs.required * (1 - tol)

    def clean(self, x_base: np.ndarray) -> bool:
        """Whether a state has no yarns that passed through each other: no pair of loops
        crosses more often than in the natural fabric (crossings.judge)."""
        verdict = self.look(x_base).verdict
        if not verdict.clean:
            n = self.grid.wales
            self.why = "new crossings between loops " + ", ".join(
                f"({a // n + 1},{a % n + 1})-({b // n + 1},{b % n + 1})"
                for a, b in list(verdict.new)[:4])
        return verdict.clean

    def crossed(self, x_base: np.ndarray, used: Pairs, found: Pairs) -> bool:
        """Whether a solve let yarns pass through each other: a new crossing, or a pair of
        the solve now on its other side."""
        if not self.clean(x_base):
            return True
        if len(used) == 0 or len(found) == 0:
            return False
        idx, dist = match(used, found)
        # not in an interlock's box (required gap 0): there the designed crossing slides
        # along the yarns, and a pair next to it changes side without anything passing
        # through (a 10 x 10 pull's last step was halved five times for this); a new
        # crossing there is what the count above finds
        near = (idx >= 0) & (dist < self.grid.h) & (used.required[np.maximum(idx, 0)] > 0)
        through = near & (used.sigma[np.maximum(idx, 0)] * found.sigma * found.gap
                          < -FLIP * self.grid.L)
        if through.any():
            self.why = f"{int(through.sum())} pairs passed through"
        return bool(np.any(through))

    def solve_once(self, p_base: np.ndarray, x_base: np.ndarray, pairs: Pairs,
                   warm: Warm | None, report: SolveReport,
                   rounds: list[Round], note: str, settle: bool = False
                   ) -> tuple[SolveReport, np.ndarray]:
        """One IPOPT solve with a slot for every pair, from x_base (warm: the last solve's
        base multipliers, pairs and their gap multipliers; ``settle``: the pairs nearly meet
        their gaps, IPOPT starts at a small barrier parameter); the pairs' gap multipliers."""
        t0 = time.perf_counter()
        if self.out_of_time():          # no build of a contact NLP that cannot be solved
            return (SolveReport(False, OUT_OF_TIME, x_base, np.zeros(0), np.nan, 0, 0.0),
                    np.zeros(len(pairs)))
        rebuilt = self._slots(pairs)
        sA, sB, sigma, required, used, slot_of = self._assign(pairs)
        c = self.cnlp
        lbg, ubg = c.bounds(required, used)
        x0 = c.lift_slots(x_base, sA, sB)
        lam0 = None
        if warm is not None:
            lam_gap = np.zeros(c.n_slots)
            lam_gap[slot_of] = carry((warm.pairs, warm.lam_gap), pairs)
            lam0 = np.concatenate([warm.lam_base, c.warm_multipliers(x0, sigma, lam_gap)])
        params = c.parameters(p_base, sA, sB, sigma)
        ipopt = self._ipopt(settle and warm is not None)
        # the progress line names the step: a long contact solve is several IPOPT solves
        ipopt.progress.stage = f"yarn contact, {note} ({len(pairs):,} pairs): "
        rep = ipopt.once(params, x0, lbg=lbg, ubg=ubg, lam_g0=lam0)
        report.add_effort(rep)
        rounds.append(Round(note, len(pairs), c.n_slots, rebuilt, rep.iterations, rep.status,
                            time.perf_counter() - t0))
        if self.log is not None:
            self.log(rounds[-1])
        lam = c.gap_multipliers(rep.lam_g)[slot_of]
        if rep.success:
            self.last = ContactSolve(c, params, rep.x, rep.lam_g, used, sigma, required, pairs,
                                     lam, c.gaps(rep.x, sigma)[slot_of])
        return rep, lam

    def _ipopt(self, settle: bool) -> WeftSolver:
        """The contact NLP's IPOPT: WARM's, or for a settling round one that starts at the
        barrier parameter a solve ends with (built once per build of the NLP)."""
        if not settle:
            return self.solver
        if self.settler is None:
            t0 = time.perf_counter()
            mu = SETTLE_MU * self.base.problem.solver.tol
            self.settler = self.base_solver.sibling(self.cnlp, ipopt={**WARM, "mu_init": mu})
            self.build_s += time.perf_counter() - t0
        return self.settler

    def step(self, p: np.ndarray, x: np.ndarray, pairs: Pairs, warm: Warm | None, final: bool,
             report: SolveReport, rounds: list[Round], note: str) -> Step:
        """Solve at parameters p from the uncrossed state x and its pairs; solve again from
        the result with its own pairs until they meet their gaps (and, at the target, stop
        moving). A solve that ends with pairs it had no slot for far inside their gap (yarns
        out of reach where it started, now nearly crossed) is not continued from there: the
        round is solved again from its start (for the first round the step's) with those pairs
        added (:meth:`_restart`), and they stay in every later round (:meth:`_again`).
        The :class:`Step`: its status says why when a solve failed or yarns crossed."""
        tol = TOL if final else STEP_TOL
        restarts, settle, checks, margin, slid = 0, False, 0, 0.0, 0
        deep_met = Pairs.empty()        # the pairs a restart was for: in every later round
        checked = Pairs.empty()         # the pairs the check found short: in every later round
        for k in range(MAX_ROUNDS):
            begun_x, begun_pairs, begun_warm = x, pairs, warm   # a restart repeats this round
            held_apart = _margined(pairs, margin)        # the rows this solve holds
            rep, lam = self.solve_once(p, x, held_apart, warm, report, rounds,
                                       note if k == 0 else f"{note}, round {k + 1}", settle)
            if not rep.success:
                return Step(rep.status)
            if self.out_of_time():
                return Step(OUT_OF_TIME)
            xn = rep.x[:self.base.n_variables]
            found = self.pairs(xn)
            if self.crossed(xn, pairs, found):
                if self.log is not None:
                    self.log(self.why)
                return Step(CROSSED)
            deep = found.gap < found.required * (1 - DEEP)
            if deep.any() and restarts == RESTARTS:
                # still nearly crossed after the restarts: continuing from here took 370+
                # IPOPT iterations a round on the 30 x 30 pull and drove the energy 100x up;
                # a shorter step is cheaper
                if self.log is not None:
                    self.log(f"  {int(deep.sum())} pairs still deep inside their gap after "
                             f"{RESTARTS} restarts: the step fails")
                return Step(DEEP_PAIRS)
            if deep.any():
                more = self._restart(begun_x, begun_pairs, found.select(deep))
                if more is not None:
                    restarts += 1
                    deep_met = deep_met.concat(found.select(deep))
                    x, pairs, warm = begun_x, more, begun_warm
                    settle = False
                    if self.log is not None:
                        self.log(f"  restart: {int(deep.sum())} pairs met deep inside their "
                                 f"gap; from the round's start with {len(more)} pairs")
                    continue
            touching = pairs.select(self.touching())
            lost = lost_contacts(touching, found, self.grid.h * SAME)
            held = unrepeated(found, self._hold(xn, lost), self.grid.h * SAME)
            # sliding contacts held by a margin (SLIDE) need not stop moving: the margin is
            # for them (the 10 x 10 diagonal push, margin 1.4e-2: no pair short in its
            # rounds 2-4, a contact moved more than half a sample in each)
            moved = final and margin == 0 and contacts_moved(touching, found.concat(held),
                                                              self.grid.h * MOVED)
            x, warm = xn, Warm(rep.lam_g[:self.base.n_constraints], held_apart, lam)
            report.x, report.objective = x, rep.objective
            report.lam_g = rep.lam_g[:self.base.n_constraints]
            if not self.violations(found, tol).any() and not moved:
                if final and self.out_of_time():
                    return Step(OUT_OF_TIME)   # an answer the check has not judged
                refuted = self.refuted(xn) if final else Pairs.empty()
                if len(refuted) == 0:
                    return Step("Solve_Succeeded", x, found, warm, carry((pairs, lam), found))
                if checks == CHECKS:
                    return Step(REFUTED, left=refuted)
                checks += 1
                checked = checked.concat(refuted)
                if self.log is not None:
                    self.log(f"  the check finds {len(refuted)} pairs short: "
                             f"{self.named(refuted)}; solving on with them")
                found = found.concat(unrepeated(found, refuted, self.grid.h * SAME))
            wanted = slide_margin(pairs, found, tol, self.grid.h) if final else 0.0
            slid = slid + 1 if wanted > 0 else 0
            if slid >= SLIDES:
                margin = max(margin, wanted)
            if self.log is not None:
                short = np.max(1 - found.gap / np.maximum(found.required, 1e-300), initial=0)
                self.log(f"  again: {int(self.violations(found, tol).sum())} short (worst "
                         f"{short:.2e}), moved {moved}, margin {margin:.2e}")
            pairs = found.concat(held)
            pairs = pairs.concat(self._again(xn, deep_met.concat(checked), pairs))
            settle = not self.violations(pairs, SETTLE).any()
        return Step(ROUNDS_EXCEEDED)

    def polish(self, p: np.ndarray, rep: SolveReport, times: int) -> bool:
        """Solve again (warm) at p from the accepted solution ``rep`` (its x, multipliers and
        objective are replaced) with the pairs searched on it, ``times`` times or until a
        solve fails or lets yarns cross (the last accepted solve is then kept); whether any
        re-solve was accepted. The rounds accept contact points that moved less than half a
        sample, so two paths to the same parameters end up to ~1e-3 apart; the re-solves make
        x(p) smooth enough for the inverse problems' outer iteration and forward check
        (measured: tests/test_contact_control.py)."""
        polished = False
        for _ in range(times):
            kept = self.last
            found = self.pairs(rep.x)
            out, _ = self.solve_once(p, rep.x, found, Warm(rep.lam_g, kept.pairs, kept.lam), rep,
                                     [], "polish")
            xn = out.x[:self.base.n_variables]
            if not out.success or self.crossed(xn, found, self.pairs(xn)):
                self.last = kept
                break
            rep.x, rep.lam_g = xn, out.lam_g[:self.base.n_constraints]
            rep.objective = out.objective
            polished = True
        return polished

    def touching(self) -> np.ndarray:
        """Which pairs of the last solve (``last``) hold a contact: ``active.active_gaps``
        on the solve's gap rows, as the result lists them."""
        last = self.last
        return active_gaps(last.gap, last.pairs.required, last.lam, np.ones(len(last.pairs), dtype=bool),
                           self.base.problem.solver.tol, 2 * self.radius)

    def solved_at(self, x_base: np.ndarray) -> bool:
        """Whether the last successful contact solve (``last``) ended at the base state x."""
        return self.last is not None and np.array_equal(
            self.last.x[:self.base.n_variables], x_base)

    def _hold(self, x: np.ndarray, held: Pairs) -> Pairs:
        """Held pairs (``matching.lost_contacts``) at the state x: A's point against its foot on
        B now, dropped when farther than the reach; one that has no foot there (it slid into an
        interlock's box, where the required gap is 0: a contact at the box's border) stays at
        its old points."""
        look = self.look(x)
        now, kept = reseat(self.fabric, look.curves, self.grid, held, look.zones)
        return now.select(now.gap < now.required + self.reach).concat(held.select(~kept))

    def _again(self, x: np.ndarray, deep_met: Pairs, pairs: Pairs) -> Pairs:
        """The pairs a restart of this step was for (``deep_met``), reseated at the state x
        (wherever they are: the search, whose reach they may be out of here, found them
        deep later in the step), that ``pairs`` does not hold yet: a later round may start
        where they are out of reach again. (When restarts went back to the step's start, the
        100 x 100 pull's first step, restarted for 2 pairs met deep in its second round, came
        back to its first round's state, the same 22 pairs short, and began its second round
        again without them: 1,362 s lost.)"""
        if len(deep_met) == 0:
            return deep_met
        look = self.look(x)
        now, _ = reseat(self.fabric, look.curves, self.grid, deep_met, look.zones)
        return unrepeated(pairs, now, self.grid.h * SAME)

    def _restart(self, x0: np.ndarray, pairs0: Pairs, deep: Pairs) -> Pairs | None:
        """A round's starting pairs with ``deep`` (pairs its solve met far inside their gap)
        carried back to the round's start, where they are still apart; None when
        none of them is new there (nothing to gain)."""
        look = self.look(x0)
        back = reseat(self.fabric, look.curves, self.grid, deep, look.zones)[0]
        back = back.select(back.gap >= back.required)
        _, dist = match(pairs0, back)
        back = back.select(~(dist < self.grid.h))           # not a pair the start already has
        return None if len(back) == 0 else pairs0.concat(back)

    def run(self, p_target: np.ndarray, p_natural: np.ndarray, x_start: np.ndarray,
            steps: int, report: SolveReport, max_halvings: int = 8,
            extra: Pairs | None = None) -> ContactRun:
        """Load steps from an uncrossed state x_start (at p_natural) to p_target, each solved
        by :meth:`step` and halved when it fails or lets yarns cross; ``extra``: pairs of
        x_start the first solve holds besides those the search finds (the check's)."""
        rounds: list[Round] = []
        x, tau, dtau, halvings = x_start, 0.0, 1.0 / steps, 0
        if self.out_of_time():
            report.success, report.status = False, OUT_OF_TIME
            return ContactRun(report, Pairs.empty(), np.zeros(0), rounds)
        pairs, lam, warm = self.pairs(x), None, None
        searched = self.reach              # the reach the step's pairs were searched at
        if extra is not None:
            pairs = pairs.concat(unrepeated(pairs, extra, self.grid.h * SAME))
        self.left = Pairs.empty()
        solved = pairs                 # the pairs of the last solved step (lam's pairs)
        while tau < 1.0:
            if time.perf_counter() >= self.deadline:
                report.success, report.status = False, OUT_OF_TIME
                break
            nxt = min(1.0, tau + dtau)
            loading(tau)                              # the progress line's share and estimate
            out = self.step(p_natural + nxt * (p_target - p_natural), x, pairs, warm,
                            nxt >= 1.0, report, rounds, f"load {nxt:.4g}")
            if not out.success:
                report.status = out.status
            if not out.success and out.status in (OUT_OF_TIME, REFUTED):
                # no time for a wider search or a shorter step; or the answer the check
                # refutes is the target's: neither would change what it finds short
                report.success = False
                self.left = out.left if out.left is not None else Pairs.empty()
                break
            if not out.success:
                # first widen the reach (a pair farther away may be what the step needed:
                # a body pushed by a load has nothing else to stop it), then halve the step
                # (a step still nearly crossed after its restarts is halved at once: on the
                # 30 x 30 pull the doubled reach held 50,000 pairs, 72 s a solve, and the
                # pairs it met deep had been 2-12 times their gap apart at the step's start;
                # a step whose rounds did not settle is halved at once too: its rounds found
                # pairs, they did not miss any, and a wider reach only makes every round
                # dearer: the 10 x 10 diagonal push by a third, each round of its last step
                # finding ~10 pairs 0.3-0.9 % short beside its slots, 30-220 IPOPT
                # iterations a round at 3,400 pairs)
                widest = {CROSSED: WIDE_CROSSED, DEEP_PAIRS: 0.0, INFEASIBLE: 0.0,
                          ROUNDS_EXCEEDED: 0.0}.get(report.status, WIDEST)
                # the step's pairs may come from a search already this wide (the last
                # step's, widened: its rounds searched at that reach): the same pairs again
                # solved the 10 x 10 wale push's step 0.25 to 0.625 a second time, 205
                # IPOPT iterations and the same crossings, 104 s
                if (max(self.reach, searched) < widest * self.base.problem.L
                        and len(pairs) < WIDE_PAIRS):
                    self.reach = 2 * max(self.reach, searched)
                    searched = self.reach
                    if not self.out_of_time():      # else the loop's head ends the run
                        pairs = self.pairs(x)
                    continue
                if np.array_equal(p_target, p_natural):
                    # no load to step (a start at unknown parameters): a shorter step is the
                    # same step; the caller tries the natural fabric
                    report.success = False
                    break
                halvings += 1
                if halvings > max_halvings:
                    report.success = False
                    break
                dtau /= 2
                continue
            x, pairs, warm, lam = out.x, out.pairs, out.warm, out.lam
            solved = pairs
            searched = self.reach          # the reach of the search that found out.pairs
            tau, halvings, self.reach = nxt, 0, REACH * self.base.problem.L
            report.success, report.status = True, "Solve_Succeeded"
            report.continuation_steps += 1
            report.path.append((tau, x, report.lam_g))
            dtau = min(1.0, dtau * 1.5)
        # a failed step may have widened the reach and found more pairs since: report the
        # pairs of the last solved step with their multipliers
        if lam is None:
            lam = np.zeros(len(solved))
        return ContactRun(report, solved, lam, rounds,
                          0 if self.cnlp is None else self.cnlp.n_variables,
                          0 if self.cnlp is None else self.cnlp.n_constraints, warm)


def _margined(pairs: Pairs, margin: float) -> Pairs:
    """The pairs with their required gaps ``margin`` (relative) wider (``SLIDE``)."""
    if margin <= 0:
        return pairs
    return replace(pairs, required=pairs.required * (1 + margin))


def slide_margin(slots: Pairs, found: Pairs, tol: float, h: float) -> float:
    """The margin (relative to the required gap) the next round's slots keep when the pairs of
    ``found`` short by more than ``tol`` are contacts that slid (``SLIDE``): each within a
    sample ``h`` (in s_A, s_B) of a pair of the solve that just ended (``slots``), none short by
    more than ``SLIDE_MOST / SLIDE``; else 0 (a new contact, or one far inside its gap, is
    met by its own slot, not by a margin)."""
    short = found.select((found.gap < found.required * (1 - tol)) & (found.required > 0))
    if len(short) == 0 or len(slots) == 0:
        return 0.0
    _, dist = match(slots, short)
    worst = float(np.max(1 - short.gap / short.required))
    if np.all(dist < h) and SLIDE * worst <= SLIDE_MOST:
        return SLIDE * worst
    return 0.0
