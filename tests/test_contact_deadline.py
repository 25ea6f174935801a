"""``[solver] max_time`` holds in every phase of a contact solve (issue 41, item 3): IPOPT stops
at the shared deadline by its iteration callback; the phases between its solves (pair
searches, the check's search, building the contact NLP) start only before the deadline, so a
solve overruns its budget by one phase at most. (A 10 x 10 pull at max_time = 5 ran its first
pair search, 5.2 s under load, after the deadline had passed: 9.9 s in all.)"""
from __future__ import annotations

import dataclasses
import time

import pytest

from knit_nlp.outcome import OUT_OF_TIME
from knit_nlp.weft.api import solve
from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.model.problem import Yarn, parse_problem
from knit_nlp.weft.solving.contact import rounds
from knit_nlp.weft.solving.contact.rounds import ContactSolver

PHASES = ("find_pairs", "checked_pairs", "transcribe")     # what rounds.py runs between solves


@pytest.mark.parametrize("expires_after", ["clean", "pairs", "solve_once"])
def test_no_phase_starts_after_the_deadline(monkeypatch, expires_after):
    """The deadline is made to pass right after the first call of ``expires_after`` (the
    paper's answer judged for crossings, the first pair search, the first contact solve);
    no pair search, check search or build of the contact NLP starts after it, and the
    solve ends out of time."""
    held: dict[str, ContactSolver] = {}
    late: list[str] = []

    def watched(name, fn):
        def call(*args, **kwargs):
            solver = held.get("solver")
            if solver is not None and time.perf_counter() >= solver.deadline:
                late.append(name)
            return fn(*args, **kwargs)
        return call

    for name in PHASES:
        monkeypatch.setattr(rounds, name, watched(name, getattr(rounds, name)))
    first = getattr(ContactSolver, expires_after)

    def expire(self, *args, **kwargs):
        out = first(self, *args, **kwargs)
        if "solver" not in held:
            held["solver"] = self
            self.deadline = time.perf_counter()
        return out

    monkeypatch.setattr(ContactSolver, expires_after, expire)
    pr = parse_problem(diagonal_pull(4), "pull4")     # the paper's answer crosses yarns
    res = solve(dataclasses.replace(pr, yarn=Yarn(0.15)), Full())
    assert "solver" in held
    assert late == []
    assert res.status == OUT_OF_TIME and not res.success
