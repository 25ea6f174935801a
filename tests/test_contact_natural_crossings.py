"""The natural crossings of two loops, found only among segments near each other
(``natural.natural_crossings`` given the distance table, the cheap way every first solve and
check takes), are those of every segment pair intersected: on random polylines that cross
many times, and on the jersey's offsets."""
from __future__ import annotations

import numpy as np
import pytest

from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.model.contact import natural
from knit_nlp.weft.model.problem import parse_problem


@pytest.mark.parametrize("seed", [0, 1, 2, 4])
def test_the_near_segments_hold_every_crossing_of_random_polylines(seed):
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 1.0, 301)
    # two wiggly walks over one square, with steps of uneven length
    a = np.cumsum(rng.normal(size=(301, 2)) * rng.lognormal(0.0, 1.0, (301, 1)), axis=0)
    b = np.cumsum(rng.normal(size=(301, 2)) * rng.lognormal(0.0, 1.0, (301, 1)), axis=0)
    b += a.mean(0) - b.mean(0)
    dense = sorted(natural.natural_crossings(a, b, s))
    near = sorted(natural.natural_crossings(a, b, s, natural._distances(a, b)))
    assert len(dense) > 5
    np.testing.assert_allclose(near, dense, rtol=0, atol=1e-12)
    # candidate segments from a cell list (``near``) find the same crossings, to the bit
    assert sorted(natural.natural_crossings(a, b, s, near=True)) == dense


def test_the_jersey_interlocks_keep_their_crossings():
    pr = parse_problem(diagonal_pull(3), "pull3")
    fab = natural.NaturalFabric._new(pr, 0.15)
    a = fab.xy
    for di in range(3):
        for dj in range(-2, 3):
            b = a + fab.shift(np.array(di), np.array(dj))
            dense = sorted(natural.natural_crossings(a, b, fab.s))
            got = sorted(c for lock in fab._own_interlocks((di, dj)) for c in lock.crossings)
            np.testing.assert_allclose(got, dense, rtol=0, atol=1e-12)
    assert fab.crossings((1, 0)) == 4          # A, C, Q, S of the upper loop (the paper's)
