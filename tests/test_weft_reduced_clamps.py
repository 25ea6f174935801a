"""Clamps on interpolated courses: the reduced model makes the clamped courses and wales
representative where the clamps would otherwise be dependent (no LICQ), and then agrees with
the full model."""
import numpy as np
import pytest

from knit_nlp.weft.api import solve
from knit_nlp.weft.model.cases import course_pull, diagonal_pull
from knit_nlp.weft.transcription.condensed.nlp import CondensedNLP, build_condensed
from knit_nlp.weft.model.parametrisation import Full, Reduced
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.transcription.reduction import with_clamped


@pytest.fixture(scope="module")
def pull():
    return parse_problem(course_pull(12), "<course pull 12 x 12>")


def test_course_pull_clamps_are_dependent_over_the_corner_form(pull):
    # both ends of every course are held in x; with the inner courses interpolated their
    # end-minus-start rows are combinations of courses 1 and 12's at the natural state
    rank, rows = CondensedNLP(pull, Reduced()).clamp_rank()
    assert rows == 2 * 12 + 1 and rank < rows
    # the chaining rows of shorter shooting segments are eliminated: the same clamp rows
    one, seg = CondensedNLP(pull, Reduced()), CondensedNLP(pull, Reduced(), segment=3)
    assert (one.n_seg, seg.n_seg) == (1, 4)
    course_start = np.concatenate([[k, k + 1] for k in range(one.nz, one.x.size, 2)])
    seg_start = np.concatenate([[k, k + 1] for k in range(seg.nz, seg.x.size, 2 * 4)])
    for pick, c in ((np.r_[:one.nz, course_start], one), (np.r_[:seg.nz, seg_start], seg)):
        assert not np.any(np.delete(c.clamp_jacobian(c.w(c.x0), c.p0), pick, axis=1))
    np.testing.assert_allclose(
        seg.clamp_jacobian(seg.w(seg.x0), seg.p0)[:, np.r_[:seg.nz, seg_start]],
        one.jacobian(one.w(one.x0), one.p0)[:, np.r_[:one.nz, course_start]], atol=1e-12)
    assert seg.clamp_rank() == (rank, rows)
    extended = build_condensed(pull, Reduced())
    assert extended.reduction == Reduced(tuple(range(1, 13)), (1, 12))
    assert extended.extended_from == Reduced((1, 12), (1, 12))
    assert extended.clamp_rank() == (rows, rows)


def test_independent_clamps_keep_the_representatives_asked_for():
    pr = parse_problem(diagonal_pull(12), "<diagonal pull 12 x 12>")
    cnlp = build_condensed(pr, Reduced((1, 6, 12), (1, 12)))
    assert cnlp.reduction == Reduced((1, 6, 12), (1, 12)) and cnlp.extended_from is None


def test_with_clamped_adds_the_clamped_courses_and_wales_only(pull):
    red = with_clamped(Reduced((1, 12), (1, 6, 12)), pull)
    assert red.courses == tuple(range(1, 13))          # every course is clamped at both ends
    assert red.wales == (1, 6, 12)                     # the clamps sit in wales 1 and 12


def test_extended_reduced_course_pull_converges_fast_and_close_to_full(pull):
    full, red = solve(pull, Full()), solve(pull, Reduced())
    assert full.success and red.success
    assert red.iterations <= 30                        # measured 6-8; without: hundreds or fails
    d = np.linalg.norm(red.centrelines(11) - full.centrelines(11), axis=-1)
    assert np.sqrt(np.mean(d ** 2)) < 0.2              # L = 10: within 2 % of a loop's length
    assert red.energy.total >= full.energy.total - 1e-9   # a subspace cannot do better
    reps = red.to_json()["representatives"]
    assert reps["asked"] == {"courses": [1, 12], "wales": [1, 12]}
    assert reps["courses"] == list(range(1, 13)) and reps["wales"] == [1, 12]
    assert "representatives" not in full.to_json()
