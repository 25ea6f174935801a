"""Adaptive representatives: the error indicator and the refinement loop."""
import json

import numpy as np

from knit_nlp.cli import main
from knit_nlp.weft.adaptive import NewtonProbe, solve_adaptive
from knit_nlp.weft.condensed import build_condensed
from knit_nlp.weft.problem import load_problem
from knit_nlp.weft.api import solve as solve_model
from knit_nlp.weft.solve import WeftSolver, solve

# the diagonal pull of scripts/bench_weft.py on 12 x 12 (the corner H of loop (1, 12) stretched
# 1.883 x along the chord from the origin and turned 25.26 degrees)
PULL = """
[fabric]
courses = {m}
wales = {n}
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [1, {n}]
point = "H"
displacement = {d}
{extra}
"""


def _diagonal(write_problem, n, extra=""):
    from knit_nlp.weft.natural import natural_loop, preset_coeffs
    loop = natural_loop(preset_coeffs("jersey", 3), 10.0, 3)
    h = np.array([(n - 1) * loop.wale_spacing, 0.0]) + loop.xy([6.420998])[0]
    c, s = np.cos(np.radians(25.26)), np.sin(np.radians(25.26))
    d = 1.883 * np.array([[c, -s], [s, c]]) @ h - h
    return write_problem(PULL.format(m=n, n=n, d=[float(d[0]), float(d[1])], extra=extra))


def _rank(a):
    return np.argsort(np.argsort(a.ravel()))


def test_indicator_vanishes_at_the_full_solution_and_ranks_loops_like_the_true_error(write_problem):
    pr = load_problem(_diagonal(write_problem, 12))
    full = solve_model(pr)
    assert full.success
    probe = NewtonProbe(pr)
    at_full = probe.step(full.coefficients, full.starts, 21)
    corner = build_condensed(pr)
    rep = solve(corner, WeftSolver(corner))
    coeffs, starts = corner.coefficients(rep.x), corner.starts(rep.x)
    eta = probe.step(coeffs, starts, 21)
    from knit_nlp.weft.sampling import centrelines
    err = np.sqrt(np.mean(np.sum((centrelines(coeffs, starts, pr.L, pr.t, 21)[0]
                                  - full.centrelines(21)) ** 2, axis=-1), axis=-1))
    assert np.sqrt(np.mean(err ** 2)) > 1.0                      # the corner form is wrong here
    assert np.max(at_full) < 1e-6 * np.max(eta)
    assert np.corrcoef(_rank(eta), _rank(err))[0, 1] > 0.9       # measured 0.97
    # and the estimate is the error's size (measured 8.1 against 6.0)
    assert 0.5 < np.sqrt(np.mean(eta ** 2)) / np.sqrt(np.mean(err ** 2)) < 2.0


def test_refinement_is_monotone_and_reported(write_problem, tmp_path):
    path = _diagonal(write_problem, 8, "[reduction]\nadaptive = true\ntolerance = 0.05\n"
                                       "max_parameters = 300\n")
    pr = load_problem(path)
    run = solve_adaptive(pr, pr.reduction)
    energies = [st.energy for st in run.steps]
    estimates = [st.estimate for st in run.steps]
    assert len(run.steps) >= 3 and all(st.success for st in run.steps)
    assert all(b <= a + 1e-9 * abs(a) for a, b in zip(energies, energies[1:])), energies
    assert estimates[-1] < estimates[0], estimates
    grids = [(len(st.courses), len(st.wales)) for st in run.steps]
    assert all(b[0] >= a[0] and b[1] >= a[1] and b != a for a, b in zip(grids, grids[1:]))
    assert run.steps[-1].n_parameters <= 300
    # through the CLI: the reduced model is adaptive and the steps are in the result JSON
    assert main(["solve", str(path), "--reduced", "--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "p.reduced.json").read_text())
    assert [s["n_parameters"] for s in res["adaptive"]["steps"]] == [
        st.n_parameters for st in run.steps]
    assert res["n_parameters"] == run.steps[-1].n_parameters
    assert res["adaptive"]["estimate"] == estimates[-1]
