"""Compression with a radius finishes (issue 41, item 6): a fabric pushed together by a third of
its size ends converged and clean by the independent check, or not converged with its status,
within its time budget; never in rounds that widen their reach without end
(scripts/bench_compression_contact.py measures 4 x 4 and 10 x 10 pushes, docs/contact.md)."""
from __future__ import annotations

import dataclasses
import time

from knit_nlp.weft.api import solve
from knit_nlp.weft.model.cases import course_pull
from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.model.problem import Yarn, parse_problem
from knit_nlp.weft.output.check import check

BUDGET = 120.0             # [solver] max_time (measured: 17 s under a load of 10 on 2 cores)


def test_a_4x4_pushed_together_by_a_third_along_the_courses_converges_clean():
    """Every course's last end pushed towards its first by a third of the natural width: the
    paper's model folds courses through each other; with r = 0.15 the answer converges, the
    check finds it clean, contacts push, and the solve ends well within its budget."""
    doc = course_pull(4, -1 / 3)
    pr = parse_problem(doc, "push4")
    pr = dataclasses.replace(pr, yarn=Yarn(0.15),
                             solver=dataclasses.replace(pr.solver, max_time=BUDGET))
    start = time.perf_counter()
    res = solve(pr, Full())
    took = time.perf_counter() - start
    assert res.success, res.message
    assert check(res.to_json(), pr).ok
    assert res.contact.active > 0 and res.contact.new_crossings == 0
    assert took < BUDGET
