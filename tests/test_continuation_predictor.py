"""The load steps' secant predictor (``WeftSolver.continuation(predict=True)``, ``secant``):
exact on a straight loading path, each predicted step started on the chord of the last two
states, and the same minimum as steps started from the last state (the planar pull's minimum
is unique) in no more IPOPT iterations."""
import sys
from pathlib import Path

import numpy as np
import pytest

from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.solving.solve import WeftSolver, secant
from knit_nlp.weft.transcription.factory import transcribe

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from bench_weft3d import document  # noqa: E402


def test_secant_is_exact_on_a_straight_path() -> None:
    rng = np.random.default_rng(3)
    a, b = rng.normal(size=7), rng.normal(size=7)
    path = lambda tau: a + b * tau                         # noqa: E731
    for t0, t1, t in ((0.25, 0.5, 0.75), (0.5, 0.75, 0.875), (0.1, 0.4, 1.0)):
        np.testing.assert_allclose(secant((t0, path(t0)), (t1, path(t1)), t), path(t),
                                   rtol=0, atol=1e-14)


def _recorded(solver: WeftSolver) -> list[tuple[np.ndarray, np.ndarray]]:
    """(start, solution) of every IPOPT solve the solver makes from now on."""
    calls, once = [], solver.once

    def recording(p, x0, **kw):
        rep = once(p, x0, **kw)
        calls.append((np.array(x0), rep.x))
        return rep
    solver.once = recording
    return calls


@pytest.fixture(scope="module")
def pull():
    pr = parse_problem(document(4, False, 0.5), "pull.toml")
    return transcribe(pr, Full())


def test_predicted_steps_start_on_the_chord_and_reach_the_same_minimum(pull) -> None:
    p, steps = WeftParams.of(pull.problem).vector(), 4
    plain_solver, predicted_solver = WeftSolver(pull, verbose=None), WeftSolver(pull, verbose=None)
    plain_calls, calls = _recorded(plain_solver), _recorded(predicted_solver)
    plain = plain_solver.continuation(p, pull.x0, steps)
    predicted = predicted_solver.continuation(p, pull.x0, steps, predict=True)
    assert plain.success and predicted.success and predicted.continuation_steps == steps
    for k, (start, _) in enumerate(plain_calls):                # unpredicted: the last state
        np.testing.assert_array_equal(start, pull.x0 if k == 0 else plain_calls[k - 1][1])
    np.testing.assert_array_equal(calls[0][0], pull.x0)         # nothing to extrapolate yet
    states = [(0.0, pull.x0)] + [((k + 1) / steps, sol) for k, (_, sol) in enumerate(calls)]
    for k in range(1, steps):
        np.testing.assert_allclose(calls[k][0], secant(states[k - 1], states[k], (k + 1) / steps),
                                   rtol=0, atol=1e-12)
        assert np.abs(calls[k][0] - states[k][1]).max() > 1e-3   # it did move the start
    assert predicted.objective == pytest.approx(plain.objective, rel=1e-9)
    np.testing.assert_allclose(predicted.x, plain.x, atol=1e-6)
    assert predicted.iterations <= plain.iterations
