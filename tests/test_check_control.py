"""`knit-nlp check` reads a control result (its equilibrium): the paper's place_stitch answer
has yarns passed through each other (the picture issue 19 starts from)."""
from __future__ import annotations

from knit_nlp.cli import main

from conftest import PROBLEMS


def test_check_counts_the_crossings_of_the_papers_place_stitch_control(tmp_path, capsys):
    assert main(["control", "place_stitch", "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    code = main(["check", str(tmp_path / "place_stitch.control.json"), "--problem",
                 str(PROBLEMS / "place_stitch.toml")])
    out = capsys.readouterr().out
    assert code == 1 and "VIOLATIONS" in out and "new crossings" in out
