"""``knit-nlp solve NAME --size CxW``: a shipped pull rebuilt at another size from its load case
(knit_nlp.weft.model.cases, the functions the benchmarks build their pulls with), its pull
scaled as eq. 28 scales it; the resized file written as the result's source."""
from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest

from knit_nlp.cli import main
from knit_nlp.tomlio import load_toml
from knit_nlp.weft.model.cases import eq28_map
from knit_nlp.weft.model.problem import load_problem, parse_problem
from knit_nlp.tomlio import toml_text
from knit_nlp.weft.model.resize import SCALED, resized

from conftest import PROBLEMS


@pytest.mark.parametrize("name", sorted(SCALED))
def test_at_its_own_size_a_resized_file_is_the_file(name):
    """The case at the file's own size gives the file's clamps (the files round the targets):
    the scaling rule is the one the file was made with."""
    path = PROBLEMS / f"{name}.toml"
    own = load_problem(path)
    again = parse_problem(resized(load_toml(path), str(path), own.courses, own.wales), path)
    assert len(again.clamps) == len(own.clamps)
    key = lambda c: (c.loop, c.s)                                       # noqa: E731
    for a, b in zip(sorted(own.clamps, key=key), sorted(again.clamps, key=key)):
        assert (a.loop, a.s, a.fix) == (b.loop, b.s, b.fix)
        np.testing.assert_allclose(a.target, b.target, atol=0.05)


@pytest.mark.parametrize("size", [(5, 5), (12, 7), (3, 30)])
def test_the_diagonal_pull_keeps_eq28s_stretch_and_turn_at_any_size(size):
    """H of loop (1, n)'s target is its natural position (from the resized problem's own
    natural fabric) stretched 1.883 times and turned 25.26 degrees about the pinned corner."""
    doc = resized(load_toml(PROBLEMS / "diagonal_pull.toml"), "diagonal_pull", *size)
    pr = parse_problem(doc, "resized.toml")
    assert (pr.courses, pr.wales) == size
    pinned, pulled = pr.clamps
    assert pulled.loop == (1, size[1]) and np.allclose(pinned.target, 0.0)
    h0 = pr.natural_position(pulled.loop, pulled.s) - pr.natural_position(pinned.loop, pinned.s)
    stretch, turn = eq28_map()
    assert np.linalg.norm(pulled.target) / np.linalg.norm(h0) == pytest.approx(stretch, rel=1e-9)
    angle = np.arctan2(pulled.target[1], pulled.target[0]) - np.arctan2(h0[1], h0[0])
    assert angle == pytest.approx(turn, abs=1e-9)


@pytest.mark.parametrize("name", sorted(SCALED))
def test_the_written_file_reads_back_as_the_document(name):
    doc = resized(load_toml(PROBLEMS / f"{name}.toml"), name, 4, 9)
    assert tomllib.loads(toml_text(doc)) == doc


def test_solve_size_writes_and_solves_the_resized_problem(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["solve", "diagonal_pull", "--size", "3x4", "--out", str(out)]) == 0
    written = out / "diagonal_pull_3x4.toml"
    result = json.loads((out / "diagonal_pull_3x4.full.json").read_text())
    assert np.array(result["loops"]["coefficients"]).shape[:2] == (3, 4)
    assert result["source"]["file"].endswith("diagonal_pull_3x4.toml") and written.is_file()
    assert str(written) in capsys.readouterr().out
    assert main(["solve", "diagonal_pull", "--size", "3x4", "--out", str(out)]) == 0  # again


@pytest.mark.parametrize("argv, needle", [
    (["diagonal_pull", "--size", "3xx"], "expected COURSESxWALES"),
    (["diagonal_pull", "--size", "0x5"], "courses must be in"),
    (["place_stitch", "--size", "12"], "resizes only the shipped pulls"),
    (["jacquard_diamond", "--size", "12"], "applies to weft problems only")])
def test_a_size_that_cannot_be_made_is_one_line(tmp_path, capsys, argv, needle):
    assert main(["solve", *argv, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err and "--size" in err, err
    assert not (tmp_path / "out").exists()
