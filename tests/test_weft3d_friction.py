"""Lagged Coulomb friction at the 3-D model's designed crossings (docs/weft3d.md, "Friction",
F1-F4; ``model/spatial/friction.py``): its closed form on two straight yarns, the frictionless
limit, the load path's energy balance and monotonicity, the derivatives, and the refusals."""
from __future__ import annotations

import copy

import casadi as ca
import numpy as np
import pytest

from knit_nlp.errors import ProblemError
from knit_nlp.weft.inverse.forward import equilibrium_for
from knit_nlp.weft.model.basis import n_coeffs
from knit_nlp.weft.model.compression import ACRYLIC
from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.model.spatial.crossing_contact import crossing_terms
from knit_nlp.weft.model.spatial.curve3d import segment
from knit_nlp.weft.model.spatial.friction import LAGGED_ROWS, friction_potential
from knit_nlp.weft.output.results import WeftResult
from knit_nlp.weft.output.summary import solve_summary
from knit_nlp.weft.solving.variants import equilibrium
from knit_nlp.weft.transcription.spatial import Spatial, build_spatial

L, T, Q = 10.0, 1, 2
ALPHA = np.pi / 3
EPS = 1e-3 * L
Z = 1.25                       # the upper yarn held at this height: pressed (2r = 1.48)


def _yarn(angle: float) -> tuple[np.ndarray, np.ndarray]:
    a = np.zeros(n_coeffs(T))
    a[-1] = angle
    return a, np.zeros(n_coeffs(Q))


def _slide(mu: float, held: float | None = None, pull: float = 0.0) -> dict:
    """Two straight yarns crossing at α (tests/test_weft3d_contact.py's toy), the upper one
    held at height Z and moved along its own axis by u: held at u = ``held`` (the row's
    multiplier is the reaction) or pulled by a force ``pull`` (work pull·u). Friction
    μ N̄ f0(|Δ|) (F1-F3) lagged from the unslid state: N̄ the law's force at h = Z, σ̄ = L/2."""
    seg, terms = segment(L, T, Q, 8), crossing_terms(ACRYLIC)
    z, su, sl, u = (ca.SX.sym(n) for n in ("z", "su", "sl", "u"))
    (au, bu), (al, bl) = _yarn(0.0), _yarn(ALPHA)
    du, tu = seg(au, bu, 0.0, su)
    dl, tl = seg(al, bl, 0.0, sl)
    start_l = ca.DM([-L / 2 * np.cos(ALPHA), -L / 2 * np.sin(ALPHA), 0.0])
    energy, rows, _, _ = terms(ca.vertcat(-L / 2 + u, 0.0, z) + du, tu, start_l + dl, tl, 1.0, 1.0)
    normal = float(ACRYLIC.crossing_force(Z, np.sin(ALPHA)))
    lagged = ca.DM([normal, L / 2, L / 2, np.cos(ALPHA)])
    f = energy + friction_potential(mu, EPS)(ca.vertcat(su, sl), lagged) - pull * u
    g = ca.vertcat(rows, z - Z, *([u - held] if held is not None else []))
    solver = ca.nlpsol("s", "ipopt", {"x": ca.vertcat(z, su, sl, u), "f": f, "g": g},
                       {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-12}})
    sol = solver(x0=[Z, L / 2, L / 2, held or 0.0], lbg=0, ubg=0)
    assert solver.stats()["success"]
    x = np.asarray(sol["x"]).ravel()
    return {"su": x[1], "sl": x[2], "u": x[3], "lam": np.asarray(sol["lam_g"]).ravel(),
            "normal": normal}


@pytest.mark.parametrize("delta", [0.8, EPS / 2])
def test_the_force_to_slide_a_yarn_through_a_crossing_is_mu_n(delta: float) -> None:
    """Held slid by δ along its axis through a pressed crossing, the holding row's reaction is
    μN̄ f0′(δ) (F2-F3): the Coulomb force μN̄ once δ > ε (exactly: the crossing energy does not
    change along the yarn), 3/4 of it at δ = ε/2 (the mollifier: −δ²/ε² + 2δ/ε)."""
    mu = 0.3
    got = _slide(mu, held=delta)
    assert got["su"] - L / 2 == pytest.approx(-delta, abs=1e-9)
    assert got["sl"] == pytest.approx(L / 2, abs=1e-9)
    closed = mu * got["normal"] * (1.0 if delta > EPS else -(delta / EPS) ** 2 + 2 * delta / EPS)
    assert got["normal"] > 1e-4
    assert -got["lam"][-1] == pytest.approx(closed, rel=1e-8)


def test_below_mu_n_the_yarn_sticks() -> None:
    """Pulled by 0.6 μN̄ (below the Coulomb force) the yarn moves less than ε (it sticks: the
    mollifier's static regime), by δ with f0′(δ) = 0.6, δ/ε = 1 − √0.4; without friction the
    same pull has no equilibrium short of the yarn's end (the crossing holds nothing along it)."""
    mu = 0.3
    normal = float(ACRYLIC.crossing_force(Z, np.sin(ALPHA)))
    got = _slide(mu, pull=0.6 * mu * normal)
    assert 0 < got["u"] < EPS
    assert got["u"] == pytest.approx(EPS * (1 - np.sqrt(0.4)), rel=1e-6)


PULL = {"fabric": {"courses": 2, "wales": 2},
        "loop": {"length": 11.28, "harmonics": 3}, "material": {"R_f": 0.045},
        "yarn": {"radius": 0.74, "geometry": "3d", "elevation_modes": 4},
        "solver": {"continuation": 4},
        "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                  {"loop": [2, 2], "point": "H", "displacement": [1.2, 0.6]}]}


def _problem(mu: float | None, steps: int = 4, name: str = "pull.toml"):
    doc = copy.deepcopy(PULL)
    doc["solver"]["continuation"] = steps
    if mu is not None:
        doc["yarn"]["friction"] = mu
    return parse_problem(doc, name)


def _solve(mu: float | None, steps: int = 4) -> WeftResult:
    eq = equilibrium(_problem(mu, steps), Full())
    eq.rounds_max = 0                     # one load path (a round would solve its last step again)
    sol = eq.solve()
    assert sol.success, sol.status
    return WeftResult.of(sol)


def test_friction_zero_is_the_frictionless_model_bit_for_bit() -> None:
    """``friction = 0`` builds today's NLP (no lagged parameters, no friction term) and gives
    the same answer, bit for bit, as a file without the key."""
    none, zero = _solve(None), _solve(0.0)
    assert zero.nlp.friction is None
    assert zero.nlp.nlp["p"].numel() == zero.params.vector().size
    assert np.array_equal(none.x, zero.x)
    assert "friction" not in zero.to_json()["spatial"]


def _work_and_energy(res: WeftResult) -> tuple[float, float, list[float]]:
    """The clamp's work along the path (trapezoid over the steps' reactions and targets),
    the stored energy at its end and each step's dissipation (F4) recomputed from the path:
    each step lagged from the one before (the first from the natural state)."""
    nlp, steps = res.nlp, [r for _, r in res.loading_path()]
    natural = WeftParams.natural(res.problem).targets
    work, dis, before = 0.0, [], nlp.x0
    reactions, targets = [np.zeros_like(natural)], [natural]
    for r in steps:
        reactions.append(np.array([c.reaction for c in r.clamps]))
        targets.append(np.array([c.target for c in r.clamps]))
        if nlp.friction is not None:
            dis.append(nlp.step_dissipation(r.x, nlp.lagged_at(before)))
        before = r.x
    for k in range(len(steps)):
        work += 0.5 * float(np.sum((reactions[k] + reactions[k + 1])
                                   * (targets[k + 1] - targets[k])))
    return work, res.energy.total, dis


WALE_PULL = [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
             {"loop": [1, 2], "point": "start", "displacement": [0.0, 0.0]},
             {"loop": [2, 1], "point": "H", "displacement": [0.0, 0.6]},
             {"loop": [2, 2], "point": "H", "displacement": [0.0, 0.6]}]


def test_a_pull_with_friction_needs_more_force_and_balances_its_energy(monkeypatch) -> None:
    """A wale pull (2 x 2, the lower course's starts held, the upper loops' heads moved up by
    0.6 mm in 6 steps: the wraps pressed, the yarn sliding through them) needs a larger clamp
    force with friction, more with more friction; and along the path the clamp's work is the
    stored energy plus the dissipation (F4): W = ΔU + Σ D to the steps' accuracy. The work is
    the trapezoid over the steps' reactions and N̄ lags a step behind (0 in the first): both
    first order in the step, so the tolerance is 20 % of Σ D (measured: 11 % at μ = 0.3, 15 %
    at 0.6; without friction |W − ΔU| is 0.3 % of W). The result reports the path's steps and
    dissipation, which the path's states give again."""
    monkeypatch.setitem(PULL, "clamp", WALE_PULL)
    runs = {mu: _solve(mu, 6) for mu in (0.0, 0.3, 0.6)}
    force = {mu: sum(c.reaction[1] for c in r.clamps[2:]) for mu, r in runs.items()}
    assert force[0.0] > 0
    assert force[0.0] < force[0.3] < force[0.6]
    w0, u0, _ = _work_and_energy(runs[0.0])
    assert abs(w0 - u0) < 0.005 * w0
    for mu in (0.3, 0.6):
        w, u, dis = _work_and_energy(runs[mu])
        spatial = runs[mu].to_json()["spatial"]
        block = spatial["friction"]
        assert block["load_steps"] == 6 and block["mu"] == mu
        assert block["dissipation"] == pytest.approx(sum(dis), rel=1e-12)
        lag = runs[mu].nlp.lagged_at(runs[mu].loading_path()[-2][1].x)
        assert [c["friction_force"] for c in spatial["crossings"]] == pytest.approx(
            mu * lag.normal, rel=1e-12)
        assert max(c["slide"] for c in spatial["crossings"]) > 0
        assert sum(dis) > 0.02 * w
        assert abs(w - u - sum(dis)) < 0.2 * sum(dis)
        told = solve_summary(runs[mu], [])
        assert (f"  friction: mu = {mu:g} at the designed crossings, lagged over 6 load steps; "
                f"dissipated {sum(dis):.4g} [{runs[mu].problem.units.energy}]"
                ) in told.splitlines(), told
    assert "friction" not in solve_summary(runs[0.0], [])


def test_friction_derivatives_equal_ad_and_finite_differences() -> None:
    """With friction the element-assembled Hessian (the friction element's by AD of one
    crossing, ``elements.py``) equals CasADi's AD of the whole NLP to rounding, at random
    states with slides on both sides of ε and none (a step's start, where |Δ| has no
    derivative: η); and AD's Hessian of f on the σ block equals central
    differences of its gradient."""
    pr = _problem(0.4)
    el, ad = build_spatial(pr), build_spatial(pr, Spatial(derivatives="casadi"))
    K = el.friction.count
    x_, p_, f_, g_ = (ad.nlp[k] for k in ("x", "p", "f", "g"))
    lf, lg = ca.MX.sym("lf"), ca.MX.sym("lg", g_.numel())
    hess = ca.Function("h", [x_, p_, lf, lg], [ca.triu(ca.hessian(lf * f_ + ca.dot(lg, g_), x_)[0])])
    grad = ca.Function("g", [x_, p_], [ca.gradient(f_, x_)])
    rng = np.random.default_rng(5)
    sig = el.x.slice("sigma")
    for _ in range(2):
        x = ad.x0 + 0.02 * rng.normal(size=ad.x.size)
        s = el.x.get(x, "sigma")
        off = rng.choice([0.0, 0.2, 2.0], size=(2, K)) * EPS * rng.choice([-1, 1], size=(2, K))
        off[:, 0] = 0.0                   # a step's start: no slide yet (F1-F2 at Δ = 0)
        lag = np.vstack([rng.uniform(0.01, 0.1, K), s[0] + off[0], s[1] + off[1],
                         rng.uniform(-0.6, 0.6, K)]).ravel(order="F")
        p = np.concatenate([ad.params.vector(), lag])
        assert p.size == ad.nlp["p"].numel() == ad.params.vector().size + LAGGED_ROWS * K
        lam = rng.normal(size=ad.g.size)
        H1, H2 = hess(x, p, 1.3, lam), el.nlpsol_options["hess_lag"](x, p, 1.3, lam)
        assert float(ca.mmax(ca.fabs(ca.densify(H1 - H2)))) < 1e-12 * float(ca.mmax(ca.fabs(H1)))
        H = np.asarray(ca.densify(hess(x, p, 1.0, np.zeros(ad.g.size))))
        H = np.triu(H) + np.triu(H, 1).T
        idx = np.arange(ad.x.size)[sig][:6]
        h = 1e-6 * EPS
        for i in idx:
            e = np.zeros(ad.x.size)
            e[i] = h
            fd = (np.asarray(grad(x + e, p)).ravel() - np.asarray(grad(x - e, p)).ravel()) / (2 * h)
            assert np.allclose(fd[idx], H[idx, i], rtol=1e-5, atol=1e-6 * np.abs(H[idx][:, idx]).max())


def test_friction_is_refused_where_it_cannot_be_carried_or_has_no_meaning() -> None:
    """One-line refusals naming [yarn] friction: negative or non-finite, on planar geometry,
    and in control, fit and calibrate (their solves are not one forward load path)."""
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ProblemError, match=r"\[yarn\] friction"):
            _problem(bad)
    planar = copy.deepcopy(PULL)
    planar["yarn"] = {"radius": 0.2, "friction": 0.3}
    with pytest.raises(ProblemError, match=r"\[yarn\] friction.*geometry = \"3d\""):
        parse_problem(planar, "planar.toml")
    with pytest.raises(ProblemError, match=r"\[yarn\] friction: control and fit"):
        equilibrium_for(_problem(0.3))


def test_a_round_of_other_contacts_keeps_the_lagged_values_of_the_step_it_solves_again(
        monkeypatch) -> None:
    """The wale pull's answer gains a round of other contacts (pairs added, the NLP rebuilt,
    its last load step solved again from the answer): that solve keeps the last step's lagged
    values (the friction forces μN̄ are those of the path without the round) and the path's
    steps; its dissipation is the earlier steps' plus its own last step's."""
    monkeypatch.setitem(PULL, "clamp", WALE_PULL)
    plain = _solve(0.3, 6)
    eq = equilibrium(_problem(0.3, 6), Full())
    sol = eq.solve()
    assert sol.success, sol.status
    rounds = WeftResult.of(sol).to_json()["spatial"]
    assert [r["started_over"] for r in rounds["other_contacts"]["rounds"]] == [False]
    assert rounds["friction"]["load_steps"] == 6
    assert [c["friction_force"] for c in rounds["crossings"]] == pytest.approx(
        [c["friction_force"] for c in plain.to_json()["spatial"]["crossings"]], rel=1e-12)
    assert max(c["friction_force"] for c in rounds["crossings"]) > 0
    last = sol.nlp.step_dissipation(sol.x, sol.friction.lagged)
    assert rounds["friction"]["dissipation"] == pytest.approx(sol.friction.earlier + last,
                                                              rel=1e-12)
    assert rounds["friction"]["dissipation"] == pytest.approx(
        plain.to_json()["spatial"]["friction"]["dissipation"], rel=0.05)


def test_a_halved_step_keeps_the_last_accepted_lagged_values(monkeypatch) -> None:
    """The continuation's lagged block: the first step's from the natural state, each next
    one's from the last accepted answer, and a failed step retried at half the size keeps
    them (never taken from the failed iterate); the parameters are interpolated, the lagged
    block is not."""
    monkeypatch.setitem(PULL, "clamp", WALE_PULL)
    eq = equilibrium(_problem(0.3, 2), Full())
    eq.rounds_max = 0
    solver, nlp, calls = eq.solver, eq.nlp, []
    real = solver.once

    def once(p, x0, **kw):
        calls.append((solver.path.lagged, p))
        rep = real(p, x0, **kw)
        if len(calls) == 2:                  # the second step fails once (its iterate kept)
            rep.success, rep.x = False, rep.x + 0.01
        return rep
    monkeypatch.setattr(solver, "once", once)
    sol = eq.solve()
    assert sol.success
    answers = [x for _, x, _ in sol.path]
    assert len(calls) == 4 and len(answers) == 3          # 1/2, (1 failed), 3/4, 1
    expect = [nlp.lagged_at(nlp.x0), nlp.lagged_at(answers[0]), nlp.lagged_at(answers[0]),
              nlp.lagged_at(answers[1])]
    for (got, _), want in zip(calls, expect):
        assert np.array_equal(got.block(), want.block())
    assert np.all(calls[0][0].normal == 0) and np.any(calls[1][0].normal > 0)
    p_nat, p_end = WeftParams.natural(nlp.problem).vector(), nlp.params.vector()
    assert np.allclose(calls[2][1], p_nat + 0.75 * (p_end - p_nat))
