"""After the solve: springs stretched beyond a loop length, a course folded onto another and a
loop turned inside out are named (knit_nlp/weft/output/plausibility.py), each on a fabric moved
by hand from its natural state so that the answer is known exactly."""
from __future__ import annotations

import numpy as np
import pytest

from knit_nlp.weft.model.problem import load_problem
from knit_nlp.weft.output.plausibility import describe, findings

FABRIC = """
[fabric]
courses = 4
wales = 3
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
"""


@pytest.fixture
def natural(write_problem):
    pr = load_problem(write_problem(FABRIC))
    coeffs = np.broadcast_to(pr.natural.coeffs, (4, 3, pr.natural.coeffs.size)).copy()
    return pr, coeffs, pr.natural_starts().copy()


def test_the_natural_fabric_is_plausible(natural):
    assert not findings(*natural) and describe(findings(*natural)) == ""


@pytest.mark.parametrize("lift", [0.9, 2.0])
def test_a_course_moved_away_stretches_its_springs_by_exactly_the_move(natural, lift):
    """Course 3 translated by lift·L up: every spring pair between courses 2 and 3 stretches by
    lift·L (a rigid translation of the upper loops), named only beyond L; those between 3 and
    4 by the same, the rest not at all. Course 4, not moved, now lies under course 3: folded."""
    pr, coeffs, starts = natural
    starts[2] += [0.0, lift * pr.L]
    found = findings(pr, coeffs, starts)
    assert found.folds == [(4, 1), (4, 2), (4, 3)] and not found.inside_out
    if lift < 1:
        assert not found.springs
        return
    assert sorted((up, pair) for _, up, pair in found.springs) == sorted(
        ((i, j), pair) for i in (3, 4) for j in (1, 2, 3) for pair in ("B-E", "R-H"))
    np.testing.assert_allclose([x for x, _, _ in found.springs], lift, rtol=1e-9)


def test_a_course_pushed_below_the_one_under_it_is_folded_there(natural):
    """Course 2 moved down by 2.5 course spacings lies below course 1 (a fold of course 2 onto
    1 at every wale) and 3.5 spacings below course 3, which is therefore not folded."""
    pr, coeffs, starts = natural
    c = pr.natural.course_spacing
    starts[1] -= [0.0, 2.5 * c]
    found = findings(pr, coeffs, starts)
    assert found.folds == [(2, 1), (2, 2), (2, 3)]
    assert not found.inside_out
    assert "course 2 onto 1 at wale 1" in describe(found)


def test_a_mirrored_loop_is_inside_out_and_a_flattened_one_is_not(natural):
    """Loop (2, 2) mirrored across its chord (every tangent angle negated: θ → −θ) encloses
    the natural area with the other sign; a loop all but straightened (θ/100) with the sign
    turned encloses too little to count."""
    pr, coeffs, starts = natural
    coeffs[1, 1] = -coeffs[1, 1]
    coeffs[2, 0] = -coeffs[2, 0] / 100
    assert findings(pr, coeffs, starts).inside_out == [(2, 2)]
