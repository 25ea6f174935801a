"""The typed blocks of a result (``solving.blocks``: contact, adaptive, warm start) write the
result JSON's blocks as they were written when they were dicts under ``WeftResult.extra``: the
same keys in the same order (pinned below from the dict-writing code, issue 38 item 4) and the
values the typed fields hold, through the file ``solve`` writes."""
from __future__ import annotations

import json

import pytest
from test_contact import squeezed

from knit_nlp.weft.api import solve
from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.model.parametrisation import Adaptive, Full
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.output.summary import solve_summary

# the keys the result JSON had with ``extra`` (docs/weft_files.md "Result JSON", docs/contact.md)
CONTACT_KEYS = ["radius", "route", "pairs_in_reach", "active", "smallest_gap",
                "smallest_gap_over_2r", "thick_pairs", "thick_smallest_gap_over_required",
                "interlock_pairs", "largest_force", "force_unit", "new_crossings",
                "lost_designed_crossings", "contacts", "solves", "contact_nlp"]
ONE_CONTACT_KEYS = ["loops", "s", "point", "force", "gap", "required"]
ADAPTIVE_KEYS = ["steps", "estimate"]
STEP_KEYS = ["representative_courses", "representative_wales", "n_parameters", "energy",
             "iterations", "solve_s", "success", "estimate"]
WARM_KEYS = ["from", "reduced_success", "reduced_iterations", "reduced_solve_s"]


def _written(res, tmp_path) -> dict:
    """The result JSON as ``knit-nlp solve`` writes it."""
    res.save(tmp_path)
    return json.loads((tmp_path / f"{res.problem.name}.{res.model}.json").read_text())


def test_a_contact_solve_writes_its_typed_block_key_for_key(tmp_path):
    r = 0.15
    res = solve(squeezed(0.5, r))           # the loop's neck closes on one contact
    js = _written(res, tmp_path)
    assert list(js)[-1] == "contact" and "adaptive" not in js and "warm_start" not in js
    block = js["contact"]
    assert list(block) == CONTACT_KEYS
    assert block["active"] == res.contact.active == len(res.contact.contacts) >= 1
    assert block["radius"] == r and block["route"] == res.contact.route
    assert block["smallest_gap"] == pytest.approx(2 * r, rel=1e-4)
    for written, typed in zip(block["contacts"], res.contact.contacts):
        assert list(written) == ONE_CONTACT_KEYS
        assert written["loops"] == [list(typed.loops[0]), list(typed.loops[1])]
        assert written["point"] == list(typed.point) and written["force"] == typed.force
    # the listed contacts touch: their gap is their required gap 2r (docs/contact.md)
    assert all(c["gap"] == pytest.approx(c["required"], abs=1e-3 * 2 * r) == 2 * r
               for c in block["contacts"])
    assert block["contact_nlp"] == res.contact.contact_nlp
    line = next(ln for ln in solve_summary(res, []).splitlines() if "yarn contact" in ln)
    assert f"{block['active']} active" in line and f"{block['new_crossings']} new" in line


def test_adaptive_and_warm_started_solves_write_their_typed_blocks(tmp_path):
    pr = parse_problem(diagonal_pull(4), "d4")
    ada = solve(pr, Adaptive(tolerance=0.05, max_parameters=300))
    js = _written(ada, tmp_path)
    assert list(js)[-1] == "adaptive" and "contact" not in js
    assert list(js["adaptive"]) == ADAPTIVE_KEYS
    assert all(list(st) == STEP_KEYS for st in js["adaptive"]["steps"])
    assert js["adaptive"]["estimate"] == js["adaptive"]["steps"][-1]["estimate"]
    assert js["adaptive"]["steps"][-1]["n_parameters"] == js["n_parameters"]
    warm = solve(pr, Full(), warm_from_reduced=True)
    js = _written(warm, tmp_path)
    assert list(js)[-1] == "warm_start" and list(js["warm_start"]) == WARM_KEYS
    assert js["warm_start"]["from"] == "reduced" and js["warm_start"]["reduced_success"]
    assert js["warm_start"]["reduced_iterations"] == warm.warm_start.reduced_iterations > 0
    assert "warm_start" not in _written(solve(pr, Full()), tmp_path / "cold")


SQUEEZE = """name = "squeeze"
[fabric]
courses = 1
wales = 1
[[rigid_clamp]]
points = [{loop = [1, 1], point = "start"}]
[[rigid_clamp]]
points = [{loop = [1, 1], point = "end"}]
translation = [-0.5, 0.0]
[[clamp]]
loop = [1, 1]
point = "start"
fix = []
angle = 0.0
[[clamp]]
loop = [1, 1]
point = "end"
fix = []
angle = 0.0
[yarn]
radius = 0.15
"""


def test_a_check_report_takes_the_contract_and_saves_the_commands_file(write_problem, tmp_path):
    """``knit-nlp check``'s file is ``CheckReport.save``'s: the same bytes, named after the
    result; ``success``/``status``/``message`` follow the check (clean with contact, violations
    for the paper's model judged at the radius: its squeezed loop's legs come within 0.4 x 2r)."""
    from knit_nlp.cli import main
    from knit_nlp.weft.output.check import check
    problem_file = write_problem(SQUEEZE, "squeeze.toml")
    with_r = squeezed(0.5, 0.15)
    for res, ok in ((solve(squeezed(0.5, None)), False), (solve(with_r), True)):
        path = res.save(tmp_path / ("contact" if ok else "paper"))[0]
        report = check(json.loads(path.read_text()), with_r)
        assert report.success is report.ok is ok
        assert report.status == ("Clean" if ok else "Violations_Found")
        assert report.message == report.verdict() and ("clean" in report.message) is ok
        mine = report.save(path.parent, path)
        assert mine == [path.parent / f"{path.stem}.check.json"]
        # the command's file, with the same problem (a file now): the same bytes
        code = main(["check", str(path), "--problem", str(problem_file),
                     "--out", str(tmp_path / "cmd")])
        assert code == (0 if ok else 1)
        written, = (tmp_path / "cmd").rglob(f"{path.stem}.check.json")
        assert written.read_bytes() == mine[0].read_bytes()
        written.unlink()


def test_a_comparison_takes_the_contract_and_names_the_model_that_failed(tmp_path):
    import dataclasses
    from knit_nlp.weft.api import compare
    from knit_nlp.weft.output.comparison import Comparison
    pr = parse_problem(diagonal_pull(4), "d4")
    cmp = compare(pr)
    assert cmp.success and cmp.status == "Solve_Succeeded" == cmp.full.status
    assert cmp.message == "converged: full and reduced models"
    js = json.loads(cmp.save(tmp_path)[0].read_text())
    assert js == json.loads(json.dumps(cmp.to_json())) and "status" not in js
    # the reduced model stopped by its iteration limit (its report so marked): it is named
    stopped = dataclasses.replace(cmp.reduced, report=dataclasses.replace(
        cmp.reduced.report, success=False, status="Maximum_Iterations_Exceeded"))
    bad = Comparison(cmp.full, stopped)
    assert not bad.success and bad.status == "Maximum_Iterations_Exceeded"
    assert bad.message == ("the reduced model: the iteration limit ([solver] max_iter) was "
                           "reached")
