"""``knit-nlp check``'s input (issue 41, item 8): JSON that is not a weft result is refused by
what it is, and a ``--problem`` other than the one the result was solved from (its sha256 is
in the result) is refused unless it differs only where a check may differ (the radius): one
line, exit 2, never a traceback."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from knit_nlp.cli import main
from problem_texts import small_pull

ROOT = Path(__file__).resolve().parent.parent
PULL = small_pull("pull") + "[loop]\nlength = LENGTH\n"


@pytest.fixture(scope="module")
def solved(tmp_path_factory):
    folder = tmp_path_factory.mktemp("src")
    path = folder / "pull.toml"
    path.write_text(PULL.replace("LENGTH", "10.0"))
    assert main(["solve", str(path), "--out", str(folder / "out")]) == 0
    return folder, path, folder / "out" / "pull.full.json"


@pytest.mark.parametrize("value, words", [
    (None, "it holds null"), ([], "it holds a list"), ({}, "an object without 'loops'"),
    ({"loops": 1}, "names no problem and records no source file; pass --problem FILE")])
def test_json_that_is_not_a_result_is_refused_by_what_it_is(tmp_path, capsys, value, words):
    path = tmp_path / "r.json"
    path.write_text(json.dumps(value))
    assert main(["check", str(path), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1 and "regular file" not in err


def test_another_problem_than_the_result_s_source_is_refused(solved, tmp_path, capsys):
    folder, path, result = solved
    other = tmp_path / "pull.toml"
    other.write_text(PULL.replace("LENGTH", "12.0"))
    assert main(["check", str(result), "--problem", str(other), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "is not the problem" in err and "loop length 12 against 10" in err
    assert err.count("\n") == 1


def test_the_source_itself_or_it_with_a_radius_is_accepted(solved, tmp_path, capsys):
    folder, path, result = solved
    assert main(["check", str(result), "--problem", str(path), "--out", str(tmp_path)]) in (0, 1)
    thick = tmp_path / "thick.toml"
    thick.write_text(path.read_text() + "[yarn]\nradius = 0.15\n")
    assert main(["check", str(result), "--problem", str(thick), "--out", str(tmp_path)]) in (0, 1)
    assert "(r = 0.15)" in capsys.readouterr().out


def _json_values():
    leaf = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(max_size=4))
    return st.recursive(leaf, lambda inner: st.one_of(
        st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=6), inner, max_size=4)),
        max_leaves=12)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.one_of(_json_values(),
                 st.fixed_dictionaries({"loops": _json_values()}),
                 st.fixed_dictionaries({"problem": st.just("pull"), "loops": _json_values()}),
                 st.fixed_dictionaries({"problem": st.just("pull"), "source": _json_values(),
                                        "loops": st.fixed_dictionaries(
                                            {"coefficients": _json_values(),
                                             "course_starts": _json_values()})})))
def test_check_of_any_json_exits_2_with_one_line(solved, capsys, value):
    folder, path, _ = solved
    bad = folder / "bad.json"
    bad.write_text(json.dumps(value))
    code = main(["check", str(bad), "--problem", str(path), "--out", str(folder / "c")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and err.startswith("knit-nlp: ")
