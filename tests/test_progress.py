"""No solve runs silently for long: without --verbose the progress line appears once a solve
outlasts QUIET_FOR seconds, refreshed at most once a second, and a warning says when half the
[solver] max_time budget is spent."""
from __future__ import annotations

import io

import casadi as ca
import pytest

import knit_nlp.progress as progress
from knit_nlp.cli import main
from knit_nlp.progress import IterationLine
from knit_nlp.tomlio import load_toml
from knit_nlp.weft.study import prepare_point

from conftest import PROBLEMS


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _iterate(line: IterationLine, clock: Clock, t: float) -> str:
    before = line.stream.getvalue()
    clock.now = t
    line.eval([ca.DM([1.0]), ca.DM(2.0), ca.DM([0.5])])
    return line.stream.getvalue()[len(before):]


def test_the_quiet_line_waits_then_throttles_then_warns_at_half_the_budget(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(progress.time, "perf_counter", clock)
    line = IterationLine(1, 1, io.StringIO(), quiet_for=3.0, budget=10.0)
    assert _iterate(line, clock, 1.0) == ""                      # a quick solve prints nothing
    shown = _iterate(line, clock, 4.0)
    assert "IPOPT iterate     2" in shown and "4 s" in shown and "warning" not in shown
    assert _iterate(line, clock, 4.5) == ""                      # at most once a second
    warned = _iterate(line, clock, 6.0)
    assert "warning: this solve has used 6 s, half its [solver] max_time of 10 s" in warned
    assert "warning" not in _iterate(line, clock, 8.0)           # said once
    line.done()
    assert line.stream.getvalue().endswith("\n")


def test_verbose_shows_every_iterate_from_the_first(monkeypatch):
    clock = Clock()
    monkeypatch.setattr(progress.time, "perf_counter", clock)
    line = IterationLine(1, 1, io.StringIO(), quiet_for=0.0)
    assert "IPOPT iterate     1" in _iterate(line, clock, 0.0)
    assert "IPOPT iterate     2" in _iterate(line, clock, 0.01)


def test_a_long_solve_shows_progress_without_verbose(monkeypatch, capsys, tmp_path):
    """The CLI's solve installs the quiet line (here made to speak at once) without --verbose."""
    monkeypatch.setattr("knit_nlp.weft.solving.solve.QUIET_FOR", 0.0)
    assert main(["solve", "wada_fig7", "--out", str(tmp_path)]) == 0
    assert "IPOPT iterate" in capsys.readouterr().err


def test_study_workers_keep_quiet():
    """A sweep has its own progress line: the solver its workers build installs none."""
    built = prepare_point(load_toml(PROBLEMS / "wada_fig7.toml"))
    assert built.solver.progress is None


def test_a_long_control_reports_each_outer_iteration(monkeypatch, capsys, tmp_path):
    """A control that outlasts QUIET_FOR (here 0) prints one line per outer iteration."""
    monkeypatch.setattr("knit_nlp.weft.inverse.control.QUIET_FOR", 0.0)
    assert main(["control", "place_stitch", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "control: outer iteration 1, goal misfit" in err and "trust radius" in err


def test_a_long_jacquard_newton_solve_shows_progress(monkeypatch, capsys, tmp_path):
    """The jacquard static solver's Newton iterations (made to speak at once) on stderr."""
    monkeypatch.setattr("knit_nlp.jacquard.newton.QUIET_FOR", 0.0)
    assert main(["solve", "jacquard_bench_100", "--out", str(tmp_path)]) == 0
    assert "Newton iteration 1: max |dE/dx|" in capsys.readouterr().err
