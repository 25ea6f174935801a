"""``[yarn] friction`` read from user files (hypothesis): any TOML value either parses to the
μ it says (finite, >= 0, at most the package's largest magnitude, 3-D only) or is refused with one ProblemError naming the file, the
table and the key, never another exception."""
from __future__ import annotations

import copy
import math

from hypothesis import given, settings, strategies as st

from knit_nlp.errors import ProblemError
from knit_nlp.tomlio import MAX_MAGNITUDE
from knit_nlp.weft.model.problem import parse_problem

DOC = {"fabric": {"courses": 2, "wales": 2}, "loop": {"length": 11.28, "harmonics": 3},
       "material": {"R_f": 0.045},
       "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]}]}
values = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**6, 10**6),
                   st.booleans(), st.text(max_size=8), st.lists(st.floats(), max_size=2),
                   st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))


@settings(max_examples=30, deadline=None)
@given(value=values, spatial=st.booleans())
def test_any_friction_value_parses_or_is_refused_in_one_line(value, spatial) -> None:
    doc = copy.deepcopy(DOC)
    doc["yarn"] = {"radius": 0.74, "friction": value,
                   **({"geometry": "3d", "elevation_modes": 4} if spatial else {})}
    number = (isinstance(value, (int, float)) and not isinstance(value, bool)
              and math.isfinite(value) and 0 <= value <= MAX_MAGNITUDE)
    try:
        pr = parse_problem(doc, "rough.toml")
    except ProblemError as err:
        text = str(err)
        assert "rough.toml" in text and "[yarn] friction" in text and "\n" not in text, text
        assert not (spatial and number), text
        return
    assert spatial and number
    assert pr.yarn.friction == float(value)
