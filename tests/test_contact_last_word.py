"""The checker has the last word (issue 41, item 3): no contact answer is called converged that
the independent check (``output.check``, at its own sampling) refutes. The contact rounds judge
their answer by the check's own search (``pairs.checked_pairs``) and solve on with the pairs it
finds short, or end not converged naming them (``rounds.REFUTED``)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from knit_nlp.weft.api import solve
from knit_nlp.weft.model.cases import _jersey, unclamped
from knit_nlp.weft.model.contact import rule
from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.model.problem import Yarn, parse_problem
from knit_nlp.weft.output.check import check
from knit_nlp.weft.solving.contact import rounds

BUDGET = 20.0              # [solver] max_time of each solve: a slow one ends honestly, not green
THICKEST = 0.8             # below the jersey's largest admitted radius at L = 10 (0.852)


def _pull(m: int, n: int, d: tuple[float, float], r: float):
    """An m x n jersey fabric, loop (1, 1)'s start pinned, H of loop (m, n) moved by d."""
    doc = unclamped(m, n)
    doc.update(name=f"pull{m}x{n}", clamp=[
        {"loop": [1, 1], "point": "start", "position": [0.0, 0.0]},
        {"loop": [m, n], "point": "H", "displacement": [float(d[0]), float(d[1])]}])
    pr = parse_problem(doc, "pull")
    return dataclasses.replace(pr, yarn=Yarn(r),
                               solver=dataclasses.replace(pr.solver, max_time=BUDGET))


def _moved(m: int, n: int, frac: float, angle: float) -> tuple[float, float]:
    """A pull (or push) of ``frac`` of the fabric's size in the direction ``angle``."""
    loop = _jersey()
    return (frac * n * loop.wale_spacing * math.cos(angle),
            frac * m * loop.course_spacing * math.sin(angle))


def test_the_radii_drawn_are_admitted():
    """THICKEST lies inside the admitted range, so every draw below is a legal problem."""
    assert rule.refusal(_jersey(), THICKEST) is None


@settings(max_examples=4, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(m=st.integers(2, 4), n=st.integers(2, 4), frac=st.floats(0.05, 0.5),
       angle=st.floats(0.0, 2 * math.pi), log_r=st.floats(math.log(0.05), math.log(THICKEST)))
# answers the rounds accepted before the check had the last word and check refuted (thick-yarn
# pairs 0.98-0.995 of their natural gap; free pairs at 0.94 x 2r), found by drawing as above
@example(m=3, n=3, frac=0.3864, angle=4.8789, log_r=math.log(0.636))
@example(m=3, n=4, frac=0.3311, angle=3.2027, log_r=math.log(0.403))
def test_no_contact_answer_called_converged_is_refuted_by_check(m, n, frac, angle, log_r):
    r = math.exp(log_r)
    res = solve(_pull(m, n, _moved(m, n, frac, angle), r), Full())
    report = check(res.to_json(), res.problem)
    assert res.success is False or report.ok, (res.status, report.line())
    assert res.to_json()["check"]["ok"] == report.ok
    if res.status == rounds.REFUTED:
        assert not report.ok and "short of their gap" in res.message


def test_an_answer_the_check_refutes_is_not_converged_and_names_the_pairs(monkeypatch):
    """With no rounds left for the check's pairs (CHECKS = 0) an answer it refutes ends
    REFUTED: not converged, "success": false, the message naming the loops and how short."""
    monkeypatch.setattr(rounds, "CHECKS", 0)
    res = solve(_pull(3, 3, _moved(3, 3, 0.3864, 4.8789), 0.636), Full())
    out = res.to_json()
    assert res.status == rounds.REFUTED and out["success"] is False
    assert not check(out, res.problem).ok
    assert "independent check finds" in res.message and ") at 0.9" in res.message
    assert out["message"] == res.message


def test_the_solver_and_check_search_alike():
    """One definition of the search: check's short pairs on a state are the rounds' refutation
    of it (``ContactSolver.refuted``), pair for pair."""
    from knit_nlp.weft.model.contact.crossings import designed_zones, find_crossings, judge
    from knit_nlp.weft.model.contact.curves import Curves
    from knit_nlp.weft.model.contact.natural import NaturalFabric
    from knit_nlp.weft.model.contact.pairs import Grid, checked_pairs, short
    from knit_nlp.weft.solving.contact.rounds import ContactSolver
    from knit_nlp.weft.solving.solve import WeftSolver
    from knit_nlp.weft.transcription.factory import transcribe
    pr = _pull(3, 3, _moved(3, 3, 0.3864, 4.8789), 0.636)
    free = solve(dataclasses.replace(pr, yarn=None), Full())   # crossed yarns, short gaps
    nlp = transcribe(pr, Full())
    contact = ContactSolver(WeftSolver(nlp), pr.yarn.radius)
    x = free.x
    mine = contact.refuted(x)
    curves = Curves.of(nlp.coefficients(x), nlp.starts(x), pr.L)
    fab = NaturalFabric.of(pr, pr.yarn.radius)
    grid = Grid(pr.courses, pr.wales, pr.L, 200)
    found = find_crossings(curves, grid)
    zones = designed_zones(fab, curves, grid, found, judge(fab, found, pr.courses, pr.wales).new)
    theirs, _ = checked_pairs(fab, curves, pr.courses, pr.wales, zones)
    theirs = theirs.select(short(theirs))
    assert len(mine) == len(theirs) > 0
    assert np.allclose(mine.gap, theirs.gap) and np.array_equal(mine.kA, theirs.kA)
    assert check(free.to_json(), pr).n_short == len(mine)
