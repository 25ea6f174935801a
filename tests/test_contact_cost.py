"""What keeps contact solves cheap (docs/contact.md, "Cost (measured)"): the slot pool is
rebuilt smaller once it is far larger than its pairs need, a load step that let yarns cross
is halved after one widening of the search (a diverging solve still widens further), the
contact rows are scaled so that IPOPT's line search does not creep, and a warm start at a
solution stays there."""
from __future__ import annotations

import numpy as np
import pytest

from knit_nlp.outcome import OUT_OF_TIME
from knit_nlp.weft.model.contact.pairs import Pairs
from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.solving.contact import rounds
from knit_nlp.weft.solving.contact.rounds import ContactSolver
from knit_nlp.weft.solving.solve import SolveReport, WeftSolver
from knit_nlp.weft.transcription.full import build_nlp

SQUEEZE = {"name": "squeeze", "fabric": {"courses": 1, "wales": 1}, "yarn": {"radius": 0.15},
           "rigid_clamp": [{"points": [{"loop": [1, 1], "point": "start"}]},
                           {"points": [{"loop": [1, 1], "point": "end"}],
                            "translation": [-0.5, 0.0]}],
           "clamp": [{"loop": [1, 1], "point": "start", "fix": [], "angle": 0.0},
                     {"loop": [1, 1], "point": "end", "fix": [], "angle": 0.0}]}


def _solver() -> tuple[ContactSolver, object]:
    pr = parse_problem(SQUEEZE, "squeeze")
    base = build_nlp(pr)
    return ContactSolver(WeftSolver(base), pr.yarn.radius), base


def _pairs(n: int) -> Pairs:
    z = np.zeros(n)
    return Pairs(z.astype(int), np.linspace(1, 4, n), z.astype(int), np.linspace(6, 9, n),
                 np.ones(n), np.full(n, 0.3), np.ones(n))


def test_the_slot_pool_shrinks_when_far_larger_than_its_pairs_need():
    """200 pairs, then 10: the pool of a widened search is rebuilt for the 10 (with SPARE),
    not kept; a change the pool still holds reuses it (it used to grow only)."""
    contact, _ = _solver()

    def pool(n: int) -> int:
        return int(np.ceil(n * (1 + rounds.SPARE)))

    assert contact._slots(_pairs(200)) and contact.cnlp.n_slots == pool(200)
    assert contact._slots(_pairs(10)) and contact.cnlp.n_slots == pool(10)
    assert not contact._slots(_pairs(pool(10))) and contact.cnlp.n_slots == pool(10)
    assert contact._slots(_pairs(40)) and contact.cnlp.n_slots == pool(40)


def _reaches(status: str) -> list[float]:
    """The search reach of every attempt of a run whose steps all fail with ``status``."""
    contact, base = _solver()
    seen: list[float] = []

    def step(p, x, pairs, warm, final, report, rounds_, note):
        seen.append(contact.reach)
        return rounds.Step(status)

    contact.step = step
    report = SolveReport(False, "", base.x0, np.zeros(base.n_constraints), np.nan, 0, 0.0)
    contact.run(base.params.vector(), WeftParams.natural(base.problem).vector(), base.x0, 2,
                report, max_halvings=1)
    return seen


def test_a_step_that_let_yarns_cross_is_halved_after_one_widening():
    L = 10.0
    crossed = _reaches(rounds.CROSSED)
    assert max(crossed) == rounds.WIDE_CROSSED * L and len(crossed) == 3   # widen once, halve
    deep = _reaches(rounds.DEEP_PAIRS)                        # nearly crossed: halve at once
    assert deep == [rounds.REACH * L] * 2
    diverged = _reaches("Diverging_Iterates")
    assert max(diverged) >= rounds.WIDEST * L                 # nothing stops it: widen further


def test_a_step_whose_pairs_came_from_a_widened_search_is_halved_not_searched_again():
    """The first step crosses, is widened (twice REACH) and solved; its pairs come
    from that widened search. The next step crosses: a search at the same widened reach would
    give it the same pairs (the 10 x 10 wale push solved its step twice so, 205 IPOPT
    iterations and the same crossings each time); it is halved."""
    contact, base = _solver()
    seen: list[tuple[float, str]] = []

    def step(p, x, pairs, warm, final, report, rounds_, note):
        seen.append((contact.reach, note))
        if len(seen) == 2:
            return rounds.Step("Solve_Succeeded", x, pairs, None, np.zeros(len(pairs)))
        return rounds.Step(rounds.CROSSED)

    contact.step = step
    report = SolveReport(False, "", base.x0, np.zeros(base.n_constraints), np.nan, 0, 0.0)
    contact.run(base.params.vector(), WeftParams.natural(base.problem).vector(), base.x0, 2,
                report, max_halvings=1)
    r = rounds.REACH * 10.0
    assert seen == [(r, "load 0.5"), (2 * r, "load 0.5"), (r, "load 1"), (r, "load 0.875")]


def test_a_large_fabric_halves_a_failed_step_instead_of_widening_its_search(monkeypatch):
    """A widened search widens everywhere: doubling the reach triples the pairs. The 100 x 100
    pull (215,600 pairs, 7 GB) widened its search to 641,400 pairs; an earlier run of it was
    killed for memory at 24 GB. A failed step of a search holding WIDE_PAIRS pairs or more is
    halved at once, for every status (here: a fabric "large" from its first pair)."""
    monkeypatch.setattr(rounds, "WIDE_PAIRS", 0)
    L = 10.0
    for status in (rounds.CROSSED, "Diverging_Iterates"):
        assert _reaches(status) == [rounds.REACH * L] * 2        # halved once, then given up


def test_a_step_out_of_time_neither_widens_nor_halves():
    """A step stopped at the deadline ends the run: a widened search after it (at 100 x 100 a
    search of some 700,000 pairs) or a shorter step has no time left to run."""
    assert _reaches(OUT_OF_TIME) == [rounds.REACH * 10.0]


def _pull(n: int) -> tuple[ContactSolver, object, list[tuple[str, int]]]:
    """The n x n diagonal pull (r = 0.15) with its contact solver logging every IPOPT solve."""
    from knit_nlp.weft.model.cases import diagonal_pull
    pr = parse_problem({**diagonal_pull(n), "yarn": {"radius": 0.15}}, "pull")
    base = build_nlp(pr)
    contact = ContactSolver(WeftSolver(base), pr.yarn.radius)
    solves: list[tuple[str, int]] = []
    contact.log = lambda r: solves.append((r.note, r.iterations)) if isinstance(
        r, rounds.Round) else None
    return contact, base, solves


def _run(contact: ContactSolver, base) -> rounds.ContactRun:
    report = SolveReport(False, "", base.x0, np.zeros(base.n_constraints), np.nan, 0, 0.0)
    return contact.run(base.params.vector(), WeftParams.natural(base.problem).vector(),
                       base.x0, 4, report)


def test_the_first_load_step_is_not_held_back_by_the_contact_rows():
    """The 4 x 4 pull's first load step from the natural fabric: 15 IPOPT iterations with the
    contact rows scaled (ROW_SCALE), 25 without, where the filter line search weighed the
    slots' six rows each above the model's own and cut every step (docs/contact.md)."""
    contact, base, solves = _pull(4)
    run = _run(contact, base)
    assert run.report.success
    note, iterations = solves[0]
    assert note == "load 0.25" and iterations <= 20


def test_a_contact_solve_restarted_at_its_solution_stops_at_once():
    """Warm-started at its own solution with its own multipliers (as the rounds start each
    solve), IPOPT has nothing to do: multipliers read back unscaled and written back scaled
    (ContactNLP.gap_multipliers, warm_multipliers) meet; 14 iterations when the warm start
    forgot the scale."""
    contact, base, _ = _pull(4)
    run = _run(contact, base)
    pairs, lam = run.solved.pairs, run.solved.lam_gap
    report = SolveReport(False, "", base.x0, np.zeros(base.n_constraints), np.nan, 0, 0.0)
    again, lam_again = contact.solve_once(base.params.vector(), run.report.x, pairs,
                                          rounds.Warm(run.report.lam_g, pairs, lam), report, [],
                                          "again")
    assert again.success and again.iterations == 0
    np.testing.assert_allclose(lam_again, lam, atol=1e-12)


def test_rounds_that_nearly_meet_their_gaps_settle_in_few_iterations(monkeypatch):
    """The 4 x 4 pull's last three rounds start with every pair within SETTLE of its gap and
    IPOPT at a small barrier parameter: 10, 9 and 7 iterations (16, 15 and 13 from WARM's
    mu_init), and the same minimum as without settling."""
    def solve(settle: float) -> tuple[rounds.ContactRun, list[tuple[str, int, bool]]]:
        monkeypatch.setattr(rounds, "SETTLE", settle)
        contact, base, solves = _pull(4)
        flags: list[bool] = []
        once = contact.solve_once

        def spy(p, x, pairs, warm, report, rounds_, note, settle=False):
            flags.append(settle)
            return once(p, x, pairs, warm, report, rounds_, note, settle)

        contact.solve_once = spy
        return _run(contact, base), [(n, i, f) for (n, i), f in zip(solves, flags)]

    run, solves = solve(1e-2)
    settled = [it for _, it, flag in solves if flag]
    assert run.report.success and len(settled) >= 2 and max(settled) <= 11
    plain, plain_solves = solve(-1.0)                  # no pair meets its gap "to -1": never
    assert not any(flag for *_, flag in plain_solves)
    assert run.report.objective == pytest.approx(plain.report.objective, rel=1e-8)


def _one(gap: float) -> Pairs:
    """One pair (required gap 0.3) at the given gap."""
    return Pairs(np.array([0]), np.array([1.0]), np.array([0]), np.array([7.0]), np.ones(1),
                 np.full(1, 0.3), np.full(1, gap))


def test_a_restart_repeats_its_round_not_the_whole_step():
    """A round that meets pairs deep inside their gap is solved again from where that round
    started, not from the step's start: on the 100 x 100 pull a second round's restart from
    the step's start took 97 IPOPT iterations and 1,362 s to come back to the state the second
    round had started from. Scripted searches: round 1 leaves a pair short (0.2 of 0.3), round
    2 meets one deep (0.05), and after the restart all is met."""
    contact, base = _solver()
    starts: list[np.ndarray] = []
    searches = iter([_one(0.2), _one(0.05), _one(0.3)])

    def solve_once(p, x, pairs, warm, report, rounds_, note, settle=False):
        starts.append(np.array(x))
        contact.n_pairs = len(pairs)
        rep = SolveReport(True, "Solve_Succeeded", x + 1.0, np.zeros(base.n_constraints), 0.0,
                          1, 0.0)
        return rep, np.zeros(len(pairs))

    contact.solve_once = solve_once
    contact.pairs = lambda x: next(searches)
    contact.crossed = lambda x, used, found: False
    contact.touching = lambda: np.zeros(contact.n_pairs, dtype=bool)
    contact._hold = lambda x, held: held
    contact._restart = lambda x0, pairs0, deep: pairs0.concat(deep)
    contact._again = lambda x, deep_met, pairs: Pairs.empty()
    report = SolveReport(False, "", base.x0, np.zeros(base.n_constraints), np.nan, 0, 0.0)
    out = contact.step(base.params.vector(), base.x0, _one(0.3), None, False, report, [], "load")
    assert out.success and len(starts) == 3
    np.testing.assert_array_equal(starts[2], starts[1])          # round 2's start, again
    assert not np.array_equal(starts[2], starts[0])              # not the step's start
