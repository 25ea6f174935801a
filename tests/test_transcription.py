"""The transcription seam: one factory, one protocol, bounds passed through to IPOPT."""
import numpy as np
import pytest

import knit_nlp
from knit_nlp.weft import Adaptive, Full, Reduced, WeftNLP, transcribe
from knit_nlp.weft.solving.solve import WeftSolver, solve_nlp
from knit_nlp.weft.transcription.condensed.nlp import CondensedNLP
from knit_nlp.weft.transcription.full import FullNLP


def test_the_factory_gives_each_parametrisation_its_transcription_and_refuses_adaptive():
    problem = knit_nlp.load_problem("wada_fig7")
    full, red = transcribe(problem, Full()), transcribe(problem, Reduced())
    assert isinstance(full, FullNLP) and isinstance(red, CondensedNLP)
    assert (full.model, red.model) == ("full", "reduced")
    assert "hess_lag" in full.nlpsol_options and "hess_lag" in red.nlpsol_options
    assert "hess_lag" not in transcribe(problem, Full(), derivatives="casadi").nlpsol_options
    for nlp in (full, red):                     # what the protocol declares, each provides
        for name in WeftNLP.__annotations__:
            assert hasattr(nlp, name), (type(nlp).__name__, name)
        assert nlp.lbg.shape == nlp.ubg.shape == (nlp.n_constraints,)
    with pytest.raises(ValueError, match="chooses representatives by solving"):
        transcribe(problem, Adaptive())
    with pytest.raises(ValueError, match="derivatives"):
        transcribe(problem, Reduced(), derivatives="casadi")


@pytest.mark.parametrize("param", [Full(), Reduced()], ids=["full", "reduced"])
def test_the_solver_passes_the_transcriptions_bounds(param):
    """Rows need not be equalities (contact gaps are g >= 0): with the pulled clamp's rows
    bounded by a box around the natural position instead of held at the target, the fabric
    stays natural (zero energy, zero reaction); with a box that excludes the natural position
    it stops at the box's edge, with the box's sign of reaction. violation() measures against
    the bounds."""
    problem = knit_nlp.load_problem("wada_fig7")
    nlp = transcribe(problem, param)
    rows = nlp.clamp_table.clamp_rows[1].position
    target = problem.clamps[1].target
    natural = problem.natural_position(problem.clamps[1].loop, problem.clamps[1].s)
    nlp.lbg, nlp.ubg = nlp.lbg.copy(), nlp.ubg.copy()
    nlp.lbg[rows], nlp.ubg[rows] = natural - target - 1.0, natural - target + 1.0
    free = solve_nlp(nlp, WeftSolver(nlp), start="natural")
    assert free.success and nlp.energy(free.x, nlp.p0)[0] + nlp.energy(free.x, nlp.p0)[1] < 1e-10
    assert np.max(np.abs(free.lam_g[rows])) < 1e-8
    # a box in x only, reaching 0.5 short of the natural x: the point is pulled to its edge
    nlp.lbg[rows], nlp.ubg[rows] = [natural[0] - target[0] + 0.5, -np.inf], [np.inf, np.inf]
    pulled = solve_nlp(nlp, WeftSolver(nlp), start="natural")
    x_end = nlp.special_positions(pulled.x)[0, nlp.clamp_table.clamp_points[1]]
    assert pulled.success and x_end == pytest.approx(natural[0] + 0.5, abs=1e-6)
    assert pulled.lam_g[rows][0] < 0 and abs(pulled.lam_g[rows][1]) < 1e-8
    solver = WeftSolver(nlp)
    assert solver.violation(pulled.x, nlp.p0) < 1e-7
    nlp.lbg[rows][0] += 1.0                       # now the solution lies 1.0 outside its bound
    assert solver.violation(pulled.x, nlp.p0) == pytest.approx(1.0, abs=1e-6)
