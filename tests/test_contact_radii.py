"""Hostile radii (issue 41, items 3 and 4): a radius the contact rule cannot judge is refused in
one line with its reason, fast; any other radius is accepted and the natural fabric checks
clean at it; a tiny radius costs no more memory than a usual one."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from knit_nlp.errors import ProblemError
from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.model.contact import rule
from knit_nlp.weft.model.contact.pairs import check_samples, pair_samples
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.output.check import check


def _pull(radius, n: int = 3) -> dict:
    return {**diagonal_pull(n), "yarn": {"radius": radius}}


def _natural(pr) -> dict:
    m, n = pr.courses, pr.wales
    return {"loops": {"coefficients": np.broadcast_to(pr.natural.coeffs, (m, n, 8)).tolist(),
                      "course_starts": pr.natural_starts()[:, 0].tolist()}}


@pytest.mark.parametrize("radius, words", [
    (2.4, "at or above the course spacing 1.977"),
    (2.45, "at or above the course spacing"),
    (1.0, "makes the same-yarn rule ambiguous: .* closer than 2r = 2, .* use r <= 0.852"),
    (1e-9, "below 1e-06 of the loop length"),
    # 1e-6 L = 1e-5 for L = 10: red with THINNEST / L (1e-7), a survivor of scripts/mutate.py
    (5e-6, "below 1e-06 of the loop length")])
def test_a_radius_the_rule_cannot_judge_is_refused_with_its_reason(radius, words):
    start = time.perf_counter()
    with pytest.raises(ProblemError, match=words) as err:
        parse_problem(_pull(radius), "pull.toml")
    assert str(err.value).startswith("pull.toml: [yarn] radius: ") and "\n" not in str(err.value)
    assert time.perf_counter() - start < 5


@dataclass(frozen=True)
class _Circle:
    """A natural loop that is a circle of radius R, each loop on the last (no wale shift)."""

    R: float

    @property
    def length(self) -> float:
        return 2 * math.pi * self.R

    wale_spacing: float = 0.0
    rise: float = 0.0
    course_spacing: float = 100.0

    def xy(self, s):
        s = np.asarray(s, dtype=float)
        return np.stack([self.R * np.sin(s / self.R), self.R * (1 - np.cos(s / self.R))], -1)


def test_on_a_circle_the_cut_is_its_chord_and_the_largest_radius_is_the_circle_s():
    """Pieces π·r apart along a circle of radius R are 2R·sin(π·r / 2R) apart (the chord);
    that is below 2r exactly when r > R, so the largest radius a circle admits is R."""
    loop = _Circle(1.5)
    for r in (0.1, 0.7, 1.4, 2.0):
        gap, _ = rule.cut_gap(loop, r)
        assert gap == pytest.approx(2 * 1.5 * math.sin(math.pi * r / 3.0), abs=1e-5)
    assert rule.largest_clean(loop, 3.0) == pytest.approx(1.5, rel=3e-3)
    assert rule.refusal(loop, 1.49) is None and "use r <= 1.5" in rule.refusal(loop, 1.6)


def test_a_tiny_radius_samples_the_pair_search_no_finer_than_a_usual_one():
    """r = 1e-3 asked for 10,000 samples per loop (4.3 GB on a 4 x 4 fabric), r = 1e-9 for
    298 GiB; the pair search samples about once per radius, between 16 and 200 per loop."""
    assert pair_samples(10.0, 0.15) == 67 and pair_samples(10.0, 2.0) == 16
    assert pair_samples(10.0, 1e-3) == pair_samples(10.0, 1e-9) == 200
    # check looks no coarser than 200 per loop at r = 0.15: at 134 it missed the 20 x 20 contact
    # pull's 5 gaps of 0.75 x 2r; a thick yarn's check is coarser (r = 0.85: 48 per loop)
    assert check_samples(10.0, 0.15) == 200 and check_samples(10.0, 0.85) == 48
    pr = parse_problem(_pull(1e-3), "pull.toml")
    assert check(_natural(pr), pr).ok


@settings(max_examples=12, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.floats(1e-12, 3.0), st.floats(0.8, 0.9), st.sampled_from([1e-6 * 10.0])))
def test_any_radius_is_refused_in_one_line_or_the_natural_fabric_checks_clean(radius):
    start = time.perf_counter()
    try:
        pr = parse_problem(_pull(radius, 2), "pull.toml")
    except ProblemError as err:
        assert "[yarn] radius" in str(err) and "\n" not in str(err)
        assert time.perf_counter() - start < 5
        return
    assert check(_natural(pr), pr).ok
    assert time.perf_counter() - start < 5
