"""Lagged friction in calibrate (issue 39's friction in issue 40's calibration): a calibration
curve is a forward load path, each node one step lagged from the last accepted state
(``curve.SpecimenModel._step3d``), so calibrate takes a spec with ``[yarn] friction`` where
control and fit refuse it. 2 x 2 acrylic course pulls: seconds each (the natural 3-D loop is
built once per process)."""
from __future__ import annotations

import numpy as np
import pytest

from knit_nlp.errors import ProblemError
from knit_nlp.weft.inverse.calibration.curve import SpecimenModel
from knit_nlp.weft.inverse.calibration.specimen import build_specimen
from knit_nlp.weft.inverse.forward import equilibrium_for

MU = 0.3
STRAINS = np.array([0.02, 0.04, 0.06, 0.08])


def _doc(mu: float | None) -> dict:
    yarn = {"radius": 0.74, "geometry": "3d", **({} if mu is None else {"friction": mu})}
    return {"units": {"length": "mm", "force": "N"}, "loop": {"length": 11.28},
            "material": {"R_f": 0.045}, "yarn": yarn}


def _pull(mu: float | None) -> tuple[SpecimenModel, object]:
    doc = _doc(mu)
    sm = SpecimenModel(build_specimen(doc, "<friction>", "courses", 2, 2, "friction"))
    return sm, sm.pull_to(doc["material"], STRAINS)


@pytest.fixture(scope="module")
def pulls():
    return {mu: _pull(mu) for mu in (None, 0.0, MU)}


def test_a_curve_without_friction_is_the_frictionless_curve(pulls):
    _, none = pulls[None]
    _, zero = pulls[0.0]
    assert np.array_equal(none.force, zero.force)
    assert all(np.array_equal(a, b) for a, b in zip(none.xs, zero.xs))


def test_friction_stiffens_the_curve_from_its_second_step(pulls):
    """The unloaded state presses no crossing (its laws start where the natural fabric puts
    them), so the first step lags N = 0 and carries no friction; from the second step on the
    clamp pulls harder against the crossings' friction."""
    _, free = pulls[0.0]
    _, rough = pulls[MU]
    assert rough.complete and free.complete
    assert rough.force[1] == pytest.approx(free.force[1], rel=1e-6)
    assert np.all(rough.force[2:] > free.force[2:] * (1 + 1e-3))


def test_each_node_is_lagged_from_the_node_before(pulls):
    """Node k + 1 is the equilibrium whose friction lags from node k: solved again from node k
    with the lag set there explicitly, it is the curve's node k + 1."""
    sm, rough = pulls[MU]
    solver = sm.eq.solver
    for k in (1, 2):
        p = sm.params(_doc(MU)["material"], rough.u[k + 1])
        solver.start_clock()
        solver.begin_path(rough.xs[k])
        again = solver.once(p, rough.xs[k])
        assert again.success
        assert np.max(np.abs(again.x - rough.xs[k + 1])) < 1e-6


def test_control_and_fit_still_refuse_friction():
    from knit_nlp.weft.model.problem import parse_problem
    doc = {**_doc(MU), "name": "rough", "fabric": {"courses": 2, "wales": 2},
           "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                     {"loop": [1, 2], "point": "H", "displacement": [1.0, 0.0]}]}
    with pytest.raises(ProblemError, match="friction"):
        equilibrium_for(parse_problem(doc, "rough.toml"))
