"""No solve runs silently for long: without --verbose the progress line appears once a solve
outlasts QUIET_FOR seconds, refreshed at most once a second, and a warning says when half the
[solver] max_time budget is spent."""
from __future__ import annotations

import io
import re

import casadi as ca
import numpy as np
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
    """A sweep has its own progress line: the line of the solver its workers build never
    writes (its callback only keeps the deadline), even a million seconds into a solve."""
    built = prepare_point(load_toml(PROBLEMS / "wada_fig7.toml"))
    line = built.solver.progress
    line.stream = io.StringIO()
    line.clock.t0 -= 1e6
    line.clock.shown -= 1e6
    assert line.eval([ca.DM([1.0]), ca.DM(2.0), ca.DM([0.5])]) == [0]
    assert line.stream.getvalue() == ""


def test_study_workers_keep_their_contact_solves_quiet(monkeypatch, capsys):
    """A worker's contact solves (the contact NLP's own IPOPT instances) keep quiet too: in a
    sweep of the diagonal pull with r = 0.15 their lines ran into the sweep's line."""
    from knit_nlp.weft.model.cases import diagonal_pull
    monkeypatch.setattr("knit_nlp.weft.solving.solve.QUIET_FOR", 0.0)
    built = prepare_point({**diagonal_pull(4), "yarn": {"radius": 0.15}})
    result = built.run()
    assert result.contact.solves > 0 and capsys.readouterr().err == ""


def test_a_long_control_reports_each_outer_iteration(monkeypatch, capsys, tmp_path):
    """A control that outlasts QUIET_FOR (here 0) prints one line per outer iteration."""
    monkeypatch.setattr("knit_nlp.weft.inverse.control.QUIET_FOR", 0.0)
    assert main(["control", "place_stitch", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "control: outer iteration 1, goal misfit" in err and "trust radius" in err


def test_a_control_ends_its_last_solve_line_before_its_summary(monkeypatch, capsys, tmp_path):
    """Every IPOPT iterate shown (QUIET_FOR 0): the control's last solve left its line open,
    and the summary on stdout was glued onto it in a terminal."""
    monkeypatch.setattr("knit_nlp.weft.solving.solve.QUIET_FOR", 0.0)
    assert main(["control", "place_stitch", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "IPOPT iterate" in err and err.endswith("\n")


def test_a_long_jacquard_newton_solve_shows_progress(monkeypatch, capsys, tmp_path):
    """The jacquard static solver's Newton iterations (made to speak at once) on stderr."""
    monkeypatch.setattr("knit_nlp.jacquard.newton.QUIET_FOR", 0.0)
    assert main(["solve", "jacquard_bench_100", "--out", str(tmp_path)]) == 0
    assert "Newton iteration 1: max |dE/dx|" in capsys.readouterr().err


@pytest.mark.parametrize("verbose", [None, False])
def test_a_solve_ends_at_the_shared_deadline_not_a_whole_budget_later(verbose):
    """Solves that share one [solver] max_time (contact rounds, continuation, fits) each had
    IPOPT's own max_wall_time of the whole budget: a 30 x 30 contact pull with a 1 200 s budget
    ran 2 165 s (its fifth IPOPT solve started at about 970 s). The deadline now ends the solve
    in progress: a 20 x 20 pull (13 iterations, about 1 s) given 0.1 s left stops after at most
    a few iterations, reported as out of time; with time enough the same solver converges."""
    import time

    from knit_nlp.outcome import OUT_OF_TIME
    from knit_nlp.weft.model.cases import diagonal_pull
    from knit_nlp.weft.model.params import WeftParams
    from knit_nlp.weft.model.problem import parse_problem
    from knit_nlp.weft.solving.solve import WeftSolver
    from knit_nlp.weft.transcription.full import build_nlp

    pr = parse_problem(diagonal_pull(20), "pull 20")
    nlp = build_nlp(pr)
    solver = WeftSolver(nlp, verbose=verbose)
    p = WeftParams.of(pr).vector()
    solver.deadline = time.perf_counter() + 0.1
    t0 = time.perf_counter()
    late = solver.once(p, nlp.x0)
    took = time.perf_counter() - t0
    solver.deadline = time.perf_counter() + 600.0
    full = solver.once(p, nlp.x0)
    assert full.success
    # stopped at the deadline, short of convergence (the iterations that fit in 0.1 s depend on
    # the machine: 4 of 13 on a quiet one), within a second of it, not a budget later
    assert late.status == OUT_OF_TIME and not late.success and late.iterations < full.iterations
    assert took < 1.1


def test_the_line_shows_how_far_the_rows_are_outside_their_bounds(monkeypatch):
    """Yarn contact's gap rows are inequalities (gap >= 2r): their values are not violations.
    The line printed max |g| (a contact solve showed 0.44, the largest gap, at its solution);
    it now shows how far any row is outside its bounds."""
    clock = Clock()
    monkeypatch.setattr(progress.time, "perf_counter", clock)
    line = IterationLine(1, 2, io.StringIO(), quiet_for=0.0)
    line.bounds = (np.array([0.0, 0.3]), np.array([0.0, np.inf]))

    def shown(g: list[float]) -> str:
        before = line.stream.getvalue()
        line.eval([ca.DM([1.0]), ca.DM(2.0), ca.DM(g)])
        return line.stream.getvalue()[len(before):]

    assert "max violation 1.00e-03" in shown([1e-3, 0.5])       # an equation off by 1e-3
    assert "max violation 1.00e-01" in shown([0.0, 0.2])        # a gap 0.1 short of 0.3
    assert "max violation 0.00e+00" in shown([0.0, 7.0])        # far apart: no violation


def test_solves_sharing_a_stream_overwrite_one_line_and_end_it_once():
    """Contact rounds are several IPOPT solves, each with its own line object: a shorter line
    blanks what a longer one left, and the line ends once (the last contact solve's line was
    never ended, and the result's first line was glued onto it)."""
    stream = io.StringIO()
    long, short = (IterationLine(1, 1, stream, quiet_for=0.0) for _ in range(2))
    long.stage = "yarn contact, load 0.625, round 12 (123,456 pairs): "
    long.eval([ca.DM([1.0]), ca.DM(2.0), ca.DM([0.0])])
    width = len(stream.getvalue().rsplit("\r", 1)[1])
    short.eval([ca.DM([1.0]), ca.DM(2.0), ca.DM([0.0])])
    assert len(stream.getvalue().rsplit("\r", 1)[1]) >= width    # blanks over the long line
    short.done()
    long.done()
    assert stream.getvalue().count("\n") == 1 and stream.getvalue().endswith("\n")


def test_a_contact_solve_names_each_step_on_its_progress_line(monkeypatch, capsys):
    """The 4 x 4 diagonal pull with r = 0.15 takes several contact solves (load steps, rounds);
    each progress line says which, with its pairs, and the last one is ended."""
    from knit_nlp.weft.api import solve
    from knit_nlp.weft.model.cases import diagonal_pull
    from knit_nlp.weft.model.parametrisation import Full
    from knit_nlp.weft.model.problem import parse_problem
    monkeypatch.setattr("knit_nlp.weft.solving.solve.QUIET_FOR", 0.0)
    pr = parse_problem({**diagonal_pull(4), "yarn": {"radius": 0.15}}, "pull 4")
    assert solve(pr, Full()).success
    err = capsys.readouterr().err
    stages = set(re.findall(r"yarn contact, (load [0-9.]+(?:, round \d+)?) \(\d[\d,]* pairs\)",
                            err))
    assert "load 1" in stages and len(stages) >= 3
    assert err.endswith("\n")


def test_the_line_tells_the_solves_elapsed_time_and_the_time_left_on_a_path(monkeypatch):
    """Elapsed time counts from the solve's start (its max_time budget's), also on a line made
    later (a contact solve's own IPOPT); on a loading path the share reached and the time left
    at the pace so far: 25 % in 30 s leaves about 90 s. (Once only each solve's own seconds
    were shown, and a 30 x 30 contact pull sat at "load 0.625" for minutes.)"""
    clock = Clock()
    monkeypatch.setattr(progress.time, "perf_counter", clock)
    first = IterationLine(1, 1, io.StringIO(), quiet_for=0.0, budget=600.0)
    first.deadline = 600.0                                  # the budget started at 0
    clock.now = 50.0
    later = IterationLine(1, 1, io.StringIO(), quiet_for=0.0, budget=600.0)
    later.deadline = first.deadline
    assert "elapsed 1 min 00 s" in _iterate(later, clock, 60.0)
    clock.now = 70.0
    later.at(0.0)
    assert "load path starting" in _iterate(later, clock, 75.0)
    clock.now = 80.0
    later.at(0.25)
    shown = _iterate(later, clock, 100.0)
    assert "elapsed 1 min 40 s; 25% of the load reached, about 1 min 30 s left" in shown, shown
    later.done()
    assert "load" not in _iterate(first, clock, 101.0)      # the path has ended


def test_a_continuation_tells_its_share_of_the_load(monkeypatch, capsys, tmp_path):
    monkeypatch.setattr("knit_nlp.weft.solving.solve.QUIET_FOR", 0.0)
    assert main(["solve", "wada_fig7", "--continuation", "4", "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "elapsed" in err and "75% of the load reached, about" in err


def test_a_calibration_curve_step_is_not_told_as_a_share_of_the_last_path():
    """A 3-D calibration curve step is one IPOPT solve from the last node: its progress line
    must not go on telling the unloaded solve's load steps ("67% of the load reached, about 1
    min left" for every step of a 4-minute calibration)."""
    from types import SimpleNamespace
    from knit_nlp.weft.inverse.calibration.curve import SpecimenModel
    told = []
    solver = SimpleNamespace(start_clock=lambda: None, begin_path=lambda x0: None,
                             once=lambda p, x0: told.append(progress.path_told()) or "report")
    fake = SimpleNamespace(eq=SimpleNamespace(solver=solver, solution=lambda rep, p: rep))
    progress.loading(0.0)
    progress.loading(2 / 3)
    assert "67% of the load reached" in progress.path_told()
    assert SpecimenModel._step3d(fake, np.zeros(1), np.zeros(1)) == "report"
    assert told == [""]


def test_calibrate_s_own_lines_start_on_a_line_of_their_own(monkeypatch):
    """``knit-nlp calibrate --breaks`` printed 'calibrate: breaks: ...' at the end of the last
    solve's open IPOPT line ('... elapsed 4 s  calibrate: breaks: core radius × 0.455')."""
    from knit_nlp.weft.inverse.calibration import command

    clock, stream = Clock(), io.StringIO()
    monkeypatch.setattr(progress.time, "perf_counter", clock)
    monkeypatch.setattr(command.sys, "stderr", stream)
    line = IterationLine(1, 1, stream, quiet_for=0.0)
    _iterate(line, clock, 0.0)
    command._progress("breaks: R_f × 0.5 (6 of 29), 194 s")
    assert re.search(r"IPOPT iterate +1 [^\n]*\ncalibrate: breaks: R_f × 0\.5", stream.getvalue())
