"""A model's or caller's IPOPT options override WeftSolver's own defaults (MUMPS scaling off,
the wall-time budget) instead of being passed twice; the solve still reaches the minimum."""
import numpy as np
import pytest

from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.solving.solve import WeftSolver
from knit_nlp.weft.transcription.factory import transcribe

PULL = {"name": "pull", "fabric": {"courses": 3, "wales": 3},
        "loop": {"length": 11.28, "harmonics": 3}, "material": {"R_f": 0.045},
        "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                  {"loop": [1, 3], "point": "H", "displacement": [0.5, 0.5]}]}


def test_options_override_the_solvers_defaults() -> None:
    nlp = transcribe(parse_problem(PULL, "pull.toml"), Full())
    p = WeftParams.of(nlp.problem).vector()
    plain = WeftSolver(nlp, verbose=None).once(p, nlp.x0)
    scaled = WeftSolver(nlp, verbose=None, ipopt={"mumps_scaling": 77, "mumps_permuting_scaling": 7,
                                                  "max_wall_time": 60.0}).once(p, nlp.x0)
    assert plain.success and scaled.success
    assert scaled.objective == pytest.approx(plain.objective, rel=1e-9)
    np.testing.assert_allclose(scaled.x, plain.x, atol=1e-7)


def test_the_iteration_limit_tolerance_and_print_level_may_be_overridden_too() -> None:
    """``max_iter``, ``tol`` and ``print_level`` among a caller's options (``bench_weft3d.py
    --ipopt max_iter=3``) override the solver's own instead of raising "got multiple values
    for argument 'max_iter'" (measured before the fix)."""
    nlp = transcribe(parse_problem(PULL, "pull.toml"), Full())
    p = WeftParams.of(nlp.problem).vector()
    cut = WeftSolver(nlp, verbose=None, ipopt={"max_iter": 1, "tol": 1e-6,
                                               "print_level": 0}).once(p, nlp.x0)
    assert not cut.success and cut.status == "Maximum_Iterations_Exceeded"
