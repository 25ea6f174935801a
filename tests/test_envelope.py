"""Envelope-theorem checks: reported reactions and displacements are derivatives of the minimum.

Let V(p) = min_x U(x) − W(x, p) subject to g(x, p) = 0, the NLP's optimal value (stored energy
minus load work) at parameters p. CasADi's multipliers make ∇ₓ(U − W) + ∇ₓgᵀλ = 0, and the
envelope theorem gives dV/dp = ∂(U − W)/∂p + λᵀ ∂g/∂p at the minimum.

- Point clamp, rows g = P − target: ∂g/∂target = −I, so dV/dtarget = −λ, which is the clamp's
  reported ``reaction`` (the force the clamp applies to the fabric = −multiplier; docs/weft_files.md).
  Physically: moving the clamp by δ, the clamp does work reaction·δ on the fabric.
- Angle clamp, row g = θ(s) − angle: dV/dangle = −λ = ``reaction_moment``.
- Point load, W = F·(P − P0) + M·(θ(s) − θ0(s)) with g independent of F, M:
  dV/dF = −(P − P0) and dV/dM = −(θ(s) − θ0(s)) at the minimum.
- Rigid clamp, rows g_i = P_i − (c + R(φ)(P0_i − c) + t): dV/dt = Σ_i f_i = ``force`` with
  f_i = −λ_i the point reactions, and dV/dφ = Σ_i f_i·(R'(φ)(P0_i − c)) = Σ_i f_i·J(P_i − c − t)
  with J the quarter turn, i.e. Σ_i (a_x f_y − a_y f_x), a_i = P_i − (c + t): ``moment``, the
  moment of the reactions about the moved centre.

Each derivative is a central finite difference of V over re-solves warm-started from the
minimum at a tight IPOPT tolerance, compared at relative 1e-6.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from knit_nlp.weft.model.basis import phi
from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.transcription.factory import transcribe
from knit_nlp.weft.model.problem import load_problem
from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.output.results import WeftResult
from knit_nlp.weft.solving.solve import WeftSolver

TOL = 1e-12
STEP = 1e-4

LOADED = """
[fabric]
courses = 3
wales = 3
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
angle = 0.15
[[clamp]]
loop = [3, 3]
point = "H"
displacement = [1.0, 0.6]
[[clamp]]
loop = [1, 3]
point = "end"
displacement = [0.4, 0.0]
fix = ["x"]
[[clamp]]
loop = [2, 1]
point = "start"
fix = []
angle = -0.1
[[load]]
loop = [2, 2]
point = "end"
force = [0.05, -0.03]
[[load]]
loop = [3, 1]
point = "B"
force = [-0.02, 0.04]
moment = 0.01
"""

RIGID = """
[fabric]
courses = 3
wales = 3
[[rigid_clamp]]
points = [{loop = [1, 1], point = "start"}, {loop = [2, 1], point = "start"},
          {loop = [3, 1], point = "start"}]
translation = [-0.3, 0.2]
rotation = 0.05
[[rigid_clamp]]
points = [{loop = [1, 3], point = "end"}, {loop = [3, 3], point = "end"}]
translation = [1.2, 0.4]
rotation = -0.08
centre = [7.0, 1.0]
[[load]]
loop = [2, 2]
point = "E"
force = [0.0, 0.04]
"""


class Envelope:
    """A problem's NLP, its minimum at the file's parameters, and V at nearby parameters."""

    def __init__(self, path) -> None:
        self.wnlp = transcribe(load_problem(path), Full())
        self.solver = WeftSolver(self.wnlp, tol=TOL)
        self.params = WeftParams.of(self.wnlp.problem)
        p = self.params.vector()
        rep = self.solver.once(p, self.wnlp.x0)
        assert rep.success, rep.status
        self.rep = rep
        self.result = WeftResult(self.wnlp, rep, self.params, 0.0,
                                 self.solver.violation(rep.x, p)).to_json()

    def value(self, params: WeftParams) -> float:
        """V = stored energy − load work at the minimum, warm-started from the base one."""
        p = params.vector()
        rep = self.solver.once(p, self.rep.x)
        assert rep.success, rep.status
        spring, bending, work = (float(v) for v in self.wnlp.energy(rep.x, p))
        assert rep.objective == pytest.approx(spring + bending - work, rel=1e-12, abs=1e-14)
        return spring + bending - work

    def derivative(self, name: str, index: tuple[int, ...], h: float = STEP) -> float:
        """Central difference of V in one entry of a parameter array of ``WeftParams``
        (targets and forces (count, 2), angles and moments (count,), rigid (count, 3))."""
        vals = []
        for sign in (1.0, -1.0):
            arr = getattr(self.params, name).copy()
            arr[index] += sign * h
            vals.append(self.value(replace(self.params, **{name: arr})))
        return (vals[0] - vals[1]) / (2 * h)


@pytest.fixture(scope="module")
def loaded(tmp_path_factory):
    path = tmp_path_factory.mktemp("env") / "loaded.toml"
    path.write_text(LOADED)
    return Envelope(path)


@pytest.fixture(scope="module")
def rigid(tmp_path_factory):
    path = tmp_path_factory.mktemp("env") / "rigid.toml"
    path.write_text(RIGID)
    return Envelope(path)


def _close(fd: float, reported: float) -> None:
    assert abs(reported) > 1e-4                          # a real force, not a vacuous zero
    assert fd == pytest.approx(reported, rel=1e-6)


@pytest.mark.parametrize("clamp, dim", [(0, 0), (0, 1), (1, 0), (1, 1), (2, 0)])
def test_clamp_reaction_is_dV_by_dtarget(loaded, clamp, dim):
    _close(loaded.derivative("targets", (clamp, dim)), loaded.result["clamps"][clamp]["reaction"][dim])


def test_clamps_hold_their_targets_and_angle(loaded):
    """The reported position and angle are the clamped loop's own (0.15 rad at loop (1, 1)'s
    start and −0.1 at loop (2, 1)'s, where every other loop's angle differs)."""
    pr, res = loaded.wnlp.problem, loaded.result
    coeffs = np.asarray(res["loops"]["coefficients"])
    angles = coeffs @ phi(0.0, pr.L, pr.t)[0]
    assert np.sum(np.abs(angles - 0.15) < 1e-3) == 1 and np.sum(np.abs(angles + 0.1) < 1e-3) == 1
    assert res["clamps"][0]["angle"] == pytest.approx(0.15, abs=1e-9)
    assert res["clamps"][3]["angle"] == pytest.approx(-0.1, abs=1e-9)      # loop (2, 1)
    for c, out in zip(pr.clamps, res["clamps"]):
        fixed = list(c.fix)
        np.testing.assert_allclose(np.asarray(out["position"])[fixed], c.target[fixed], atol=1e-9)


def test_clamps_loads_and_rigid_clamps_are_numbered_from_1(loaded, rigid):
    """The typed result numbers them as problem files and ``WeftParams.with_`` do."""
    res = WeftResult(loaded.wnlp, loaded.rep, loaded.params, 0.0, 0.0)
    assert [c.number for c in res.clamps] == [1, 2, 3, 4]
    assert [ld.number for ld in res.loads] == [1, 2]
    res = WeftResult(rigid.wnlp, rigid.rep, rigid.params, 0.0, 0.0)
    assert [r.number for r in res.rigid_clamps] == [1, 2]


@pytest.mark.parametrize("clamp", [0, 3])
def test_clamp_reaction_moment_is_dV_by_dangle(loaded, clamp):
    _close(loaded.derivative("angles", (clamp,)), loaded.result["clamps"][clamp]["reaction_moment"])


@pytest.mark.parametrize("load, dim", [(0, 0), (0, 1), (1, 0), (1, 1)])
def test_dV_by_dforce_is_minus_the_load_displacement(loaded, load, dim):
    pr = loaded.wnlp.problem
    ld, res = pr.loads[load], loaded.result["loads"][load]
    moved = res["position"][dim] - pr.natural_position(ld.loop, ld.s)[dim]
    _close(loaded.derivative("forces", (load, dim)), -moved)


def test_dV_by_dmoment_is_minus_the_load_rotation(loaded):
    pr = loaded.wnlp.problem
    ld = pr.loads[1]
    a = np.asarray(loaded.result["loops"]["coefficients"])[ld.loop[0] - 1, ld.loop[1] - 1]
    turn = float(phi(ld.s, pr.L, pr.t)[0] @ (a - pr.natural.coeffs))
    _close(loaded.derivative("moments", (1,)), -turn)


def test_load_work_is_force_times_displacement(loaded):
    """W = Σ F·(P − P0) + M·(θ − θ0) from the result's own positions and coefficients."""
    pr, res = loaded.wnlp.problem, loaded.result
    coeffs = np.asarray(res["loops"]["coefficients"])
    work = 0.0
    for ld, out in zip(pr.loads, res["loads"]):
        work += np.dot(ld.force, np.asarray(out["position"]) - pr.natural_position(ld.loop, ld.s))
        a = coeffs[ld.loop[0] - 1, ld.loop[1] - 1]
        work += ld.moment * float(phi(ld.s, pr.L, pr.t)[0] @ (a - pr.natural.coeffs))
    assert abs(work) > 1e-4
    assert res["energy"]["load_work"] == pytest.approx(work, rel=1e-10)


@pytest.mark.parametrize("q, k", [(0, 0), (0, 1), (1, 0), (1, 1)])
def test_rigid_clamp_force_is_dV_by_dtranslation(rigid, q, k):
    _close(rigid.derivative("rigid", (q, k)), rigid.result["rigid_clamps"][q]["force"][k])


def test_rigid_clamp_reports_its_motion(rigid):
    pr = rigid.wnlp.problem
    for rc, out in zip(pr.rigid_clamps, rigid.result["rigid_clamps"]):
        assert out["translation"] == pytest.approx(rc.translation.tolist(), abs=0)
        assert out["rotation"] == rc.rotation and out["centre"] == rc.centre.tolist()
        c = rc.centre + rc.translation
        rot = np.array([[np.cos(rc.rotation), -np.sin(rc.rotation)],
                        [np.sin(rc.rotation), np.cos(rc.rotation)]])
        for (loop, _, s), pt in zip(rc.points, out["points"]):
            moved = c + rot @ (pr.natural_position(loop, s) - rc.centre)
            np.testing.assert_allclose(pt["position"], moved, atol=1e-9)


@pytest.mark.parametrize("q", [0, 1])
def test_rigid_clamp_moment_is_dV_by_drotation(rigid, q):
    _close(rigid.derivative("rigid", (q, 2)), rigid.result["rigid_clamps"][q]["moment"])
