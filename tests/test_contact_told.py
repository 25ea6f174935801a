"""Every weft result carries its own check (issue 41, item 1): the result JSON's ``check`` block,
the summary and the picture's title say what ``knit-nlp check`` would (new crossings against
the natural fabric; with a radius gaps below their requirement and thick pairs), and a
converged solve still exits 0."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from knit_nlp.cli import main
from knit_nlp.weft.output import check as checker
from knit_nlp.weft.output.check import check
from problem_texts import anchored

ROOT = Path(__file__).resolve().parent.parent
PAPER = "158 new crossings between 92 pairs of loops: the paper's model has no yarn contact " \
        "(add [yarn] radius)"

STILL = anchored(3, 3, "still")


def _solve(path: Path, out: Path, capsys) -> tuple[dict, str]:
    assert main(["solve", str(path), "--out", str(out)]) == 0        # converged: exit 0
    result = json.loads(next(out.glob("*.full.json")).read_text())
    return result, capsys.readouterr().out


def test_the_quickstart_pull_states_its_new_crossings_everywhere(tmp_path, capsys, titles):
    """The README's first command: the paper's model lets 158 yarn pieces pass through each
    other; the JSON, the summary and the title say so, as check on the written file does."""
    result, summary = _solve(ROOT / "problems" / "diagonal_pull.toml", tmp_path, capsys)
    block = result["check"]
    assert block["ok"] is False and block["new_crossings"] == 158
    assert block["new_crossing_pairs"] == 92 and block["verdict"] == PAPER
    assert f"  check: {PAPER}\n" in summary
    title, colour = titles[-1]
    assert title.endswith(f"converged\ncheck: {PAPER}") and colour == "tab:red"
    from knit_nlp.weft.model.problem import load_problem
    again = check(result, load_problem(ROOT / "problems" / "diagonal_pull.toml"))
    assert again.n_new == block["new_crossings"] and again.lost_crossings == \
        block["lost_designed_crossings"]


@pytest.mark.parametrize("yarn, words", [
    ("", "clean: no yarn passes through another"),
    ("[yarn]\nradius = 0.15\n", "clean: no new crossing, no gap below its requirement")])
def test_a_fabric_at_rest_says_clean(tmp_path, capsys, titles, yarn, words):
    path = tmp_path / "still.toml"
    path.write_text(STILL + yarn)
    result, summary = _solve(path, tmp_path / "out", capsys)
    assert result["check"]["ok"] is True and result["check"]["verdict"].startswith(words)
    assert f"  check: {words}" in summary
    if yarn:                                    # the block's gap is check's, over 2r
        from knit_nlp.weft.model.problem import load_problem
        again = check(result, load_problem(path))
        assert again.smallest_gap is not None
        assert result["check"]["smallest_gap_over_2r"] == pytest.approx(
            again.smallest_gap / 0.3, rel=1e-12)
    assert titles[-1][0].split("\ncheck: ")[1].startswith(words) and titles[-1][1] == "black"


def test_a_check_too_large_to_make_is_said_and_the_solve_still_exits_0(tmp_path, capsys,
                                                                        monkeypatch):
    monkeypatch.setattr(checker, "CHECK_ROWS", 1.0)
    path = tmp_path / "still.toml"
    path.write_text(STILL + "[yarn]\nradius = 0.15\n")
    result, summary = _solve(path, tmp_path / "out", capsys)
    assert result["check"]["ok"] is None
    assert result["check"]["verdict"].startswith("not checked: r = 0.15 at ")
    assert "  check: not checked: r = 0.15 at " in summary
