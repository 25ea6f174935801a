"""Contacts that slide (issue 41, item 6): in the final load step a round whose short pairs all
lie within a sample of a slot of the solve that just ended, and are shallow, is followed by
rounds whose slots keep a margin of twice that shortfall (rounds.slide_margin); a new contact
or one far inside its gap gets no margin (its own slot meets it)."""
from __future__ import annotations

import numpy as np
import pytest

from knit_nlp.weft.model.contact.pairs import Pairs
from knit_nlp.weft.solving.contact.rounds import SLIDE, SLIDE_MOST, TOL, _margined, slide_margin

H = 0.15                  # one sample along the yarn (L / 67 at r = 0.15)
R = 0.3                   # the required gap 2r


def _pairs(rows: list[tuple[int, int, float, float, float]], required: float = R) -> Pairs:
    """Pairs (kA, kB, s_A, s_B, gap) with one required gap."""
    kA, kB, sA, sB, gap = (np.array(v, dtype=float) for v in zip(*rows))
    return Pairs(kA.astype(int), sA, kB.astype(int), sB, np.ones(len(kA)),
                 np.full(len(kA), required), gap)


SLOTS = _pairs([(0, 5, 2.0, 3.0, R), (1, 6, 4.0, 1.0, R)])


def test_a_shallow_shortfall_beside_a_slot_asks_twice_its_depth():
    found = _pairs([(0, 5, 2.0 + 0.3 * H, 3.0 - 0.2 * H, R * (1 - 4e-3)),
                    (1, 6, 4.0, 1.0, R * (1 - 1e-3)), (1, 6, 7.0, 7.0, 2 * R)])
    assert slide_margin(SLOTS, found, TOL, H) == pytest.approx(SLIDE * 4e-3, rel=1e-9)


def test_a_new_contact_beside_a_sliding_one_gets_no_margin():
    sliding = (0, 5, 2.0 + 0.3 * H, 3.0, R * (1 - 4e-3))
    assert slide_margin(SLOTS, _pairs([sliding]), TOL, H) > 0
    new = (0, 5, 2.0 + 3 * H, 3.0, R * (1 - 1e-3))          # three samples from any slot
    assert slide_margin(SLOTS, _pairs([sliding, new]), TOL, H) == 0.0
    other_loops = (2, 7, 2.0, 3.0, R * (1 - 1e-3))          # no slot on its loops at all
    assert slide_margin(SLOTS, _pairs([sliding, other_loops]), TOL, H) == 0.0


def test_a_deep_pair_or_none_short_gets_no_margin():
    deep = SLIDE_MOST / SLIDE * 1.5
    assert slide_margin(SLOTS, _pairs([(0, 5, 2.0, 3.0, R * (1 - deep))]), TOL, H) == 0.0
    assert slide_margin(SLOTS, _pairs([(0, 5, 2.0, 3.0, R * (1 - TOL / 2))]), TOL, H) == 0.0
    box = _pairs([(0, 5, 2.0, 3.0, -0.1)], required=0.0)    # in a designed interlock's box
    assert slide_margin(SLOTS, box, TOL, H) == 0.0


def test_the_margin_widens_the_required_gap_of_every_pair_and_nothing_else():
    pairs = _pairs([(0, 5, 2.0, 3.0, 0.29), (1, 6, 4.0, 1.0, 0.31)])
    wide = _margined(pairs, 0.01)
    np.testing.assert_array_equal(wide.required, pairs.required * 1.01)
    for name in ("kA", "sA", "kB", "sB", "sigma", "gap"):
        np.testing.assert_array_equal(getattr(wide, name), getattr(pairs, name))
    assert _margined(pairs, 0.0) is pairs
