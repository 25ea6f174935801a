"""The static solver's Newton round (newton.py, linalg.py): derivatives against finite
differences and CasADi, the answer against IPOPT's, the dispatch, the merge, and the JSON
writer's bulk arrays."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from knit_nlp.jacquard import build_network, load_problem, parse_problem, solve_static
from knit_nlp.jacquard import linalg
from knit_nlp.jacquard.newton import SpringEnergy
from knit_nlp.jacquard.springs import SpringSet, spring_hessians
from knit_nlp.jacquard.static import _spring_law, merge_parallel
from knit_nlp.jsonio import _plain, array_text, json_text

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"
RNG = np.random.default_rng(7)


def _design(rng, m: int, n: int, symbols: str) -> str:
    return "\n".join("".join(rng.choice(list(symbols), m)) for _ in range(n))


def _random_problem(m: int, n: int, seed: int, pull: list | None = None, **fabric):
    rng = np.random.default_rng(seed)
    fab = {"wales": m, "courses": n, "dz": 10.0, "dh": 8.0, **fabric}
    doc = {"model": "jacquard", "fabric": fab,
           "fall_plate": {"design": _design(rng, m, n, "#+")},
           "inlay": {"design": _design(rng, m, n, "#+.")}}
    if pull:
        doc["pull"] = [{"edge": "top", "displacement": pull}]
    return parse_problem(doc, "t.toml")


def _pulled_patch():
    """A fixed patch held at the bottom and top, its top moved (0.03, 0.1) mm."""
    return _random_problem(8, 6, 3, pull=[0.03, 0.1], boundary="fixed",
                           fixed_edges=["bottom", "top"])


def _energy(p) -> tuple[SpringEnergy, np.ndarray]:
    net = build_network(p)
    s = merge_parallel(net.springs)
    energy = SpringEnergy(s, ~net.fixed, net.held, net.natural, 1e-3 * float(s.k.max()))
    z = net.held[~net.fixed].ravel() + 0.08 * p.w * RNG.standard_normal(2 * (~net.fixed).sum())
    return energy, z


PROBLEM_MAKERS = [lambda: _random_problem(6, 4, 1), _pulled_patch]


def test_spring_hessians_equal_casadi_second_derivatives():
    """Rope and loop-width springs, taut and slack: the closed-form 2 x 2 blocks against
    CasADi's AD Hessian of the same spring law (static.py's IPOPT formulation)."""
    n = 40
    d = RNG.uniform(-2.0, 2.0, (n, 2))
    length = np.hypot(d[:, 0], d[:, 1])
    l0 = length * RNG.uniform(0.6, 1.4, n)                 # about half in force
    compress = np.arange(n) % 3 == 0
    s = SpringSet(np.zeros(n, dtype=int), np.ones(n, dtype=int), d, RNG.uniform(0.5, 2.0, n),
                  length, l0, np.full(n, np.inf), compress, np.zeros(n, dtype=int))
    got = np.column_stack(spring_hessians(np.zeros((2, 2)), s))
    law = _spring_law()
    want = np.array([np.array(law(d[i], s.k[i], l0[i], -1.0 if compress[i] else 1.0)[1]).ravel()
                     for i in range(n)])
    assert np.abs(got).max() > 0.5 and (np.abs(got).sum(axis=1) == 0).any()
    assert np.allclose(got, want, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("make", PROBLEM_MAKERS)
def test_gradient_is_the_derivative_of_the_energy(make):
    energy, z = _energy(make())
    v = RNG.standard_normal(z.size)
    h = 1e-6
    fd = (energy.value(z + h * v) - energy.value(z - h * v)) / (2 * h)
    assert fd == pytest.approx(energy.gradient(z) @ v, rel=1e-7)


@pytest.mark.parametrize("make", PROBLEM_MAKERS)
def test_assembled_hessian_is_the_derivative_of_the_gradient(make):
    """The BSR matrix (blocks scattered by BlockHessian, held particles dropped) times v
    against central differences of the gradient."""
    energy, z = _energy(make())
    H = energy.hessian(z)
    assert H.shape == (z.size, z.size) and H.blocksize == (2, 2)
    for _ in range(3):
        v = RNG.standard_normal(z.size)
        h = 1e-6
        fd = (energy.gradient(z + h * v) - energy.gradient(z - h * v)) / (2 * h)
        assert np.allclose(H @ v, fd, rtol=1e-6, atol=1e-7 * np.abs(fd).max())


@pytest.mark.parametrize("make", PROBLEM_MAKERS)
def test_energy_change_equals_the_difference_of_energies(make):
    """The cancellation-free change (springs crossing slack/taut included) against
    E(z + step) - E(z), for steps large enough that the plain difference is accurate."""
    energy, z = _energy(make())
    for scale in (0.01, 0.1, 0.3):
        step = scale * RNG.standard_normal(z.size)
        want = energy.value(z + step) - energy.value(z)
        assert energy.change(z, step) == pytest.approx(want, rel=1e-9, abs=1e-12)


def _problems_for_agreement():
    diamond = load_problem(PROBLEMS / "jacquard_diamond.toml")
    return {"diamond": diamond,
            "letter_k_pulled": load_problem(PROBLEMS / "jacquard_letter_k.toml"),
            "random_periodic": _random_problem(10, 8, 5),
            "pulled_patch": _pulled_patch(),
            # 46 x 46: more unknowns than DIRECT_MAX, so the multigrid CG path
            "multigrid": _random_problem(46, 46, 11)}


@pytest.mark.parametrize("name", list(_problems_for_agreement()))
def test_newton_reaches_ipopts_equilibrium(name):
    p = _problems_for_agreement()[name]
    newton, ipopt = solve_static(p, method="newton"), solve_static(p, method="ipopt")
    assert newton.success and ipopt.success
    assert "Newton" in newton.message and ipopt.status == "Solve_Succeeded"
    if name == "multigrid":
        assert "multigrid" in newton.message and 2 * p.n_particles > linalg.DIRECT_MAX
    assert np.max(np.abs(newton.positions - ipopt.positions)) < 1e-7 * p.w
    assert newton.energy.total == pytest.approx(ipopt.energy.total, rel=1e-10)
    assert newton.residual_force == pytest.approx(ipopt.residual_force, rel=1e-3, abs=1e-9)
    assert np.max(np.abs(newton.displacement())) > 0.05 * p.w         # a real deformation


def test_multigrid_and_direct_solves_give_the_same_equilibrium(monkeypatch):
    p = _random_problem(46, 46, 11)
    amg = solve_static(p, method="newton")
    monkeypatch.setattr(linalg, "DIRECT_MAX", 10 ** 9)
    direct = solve_static(p, method="newton")
    assert "multigrid" in amg.message and "sparse LU" in direct.message
    assert np.max(np.abs(amg.positions - direct.positions)) < 1e-9 * p.w


def test_default_dispatch_newton_where_it_applies_ipopt_elsewhere():
    assert "Newton" in solve_static(_pulled_patch()).message
    stripe = load_problem(PROBLEMS / "jacquard_stripe.toml")     # floating components
    assert build_network(stripe).floating and solve_static(stripe).status == "Solve_Succeeded"
    loop_width = dataclasses.replace(_random_problem(6, 4, 1), loop_width_stiffness=0.5)
    assert solve_static(loop_width).status == "Solve_Succeeded"   # not convex: IPOPT
    with pytest.raises(ValueError, match="Newton"):
        solve_static(loop_width, method="newton")


def test_active_length_limits_continue_with_ipopt_rounds():
    """A binding length limit: the Newton relaxation violates it, constraint generation goes
    on with IPOPT from the Newton solution and ends where IPOPT alone ends."""
    p = dataclasses.replace(load_problem(PROBLEMS / "jacquard_diamond.toml"), lambda_max=1.02)
    auto, ipopt = solve_static(p), solve_static(p, method="ipopt")
    assert auto.success and auto.constraints["rounds"] >= 2
    assert auto.max_stretch() <= 1.02 * (1 + 1e-7)
    assert np.max(np.abs(auto.positions - ipopt.positions)) < 1e-6 * p.w


def test_newton_iteration_limit_is_reported_and_handed_to_ipopt():
    p = _random_problem(10, 8, 5)
    p = dataclasses.replace(p, solver=dataclasses.replace(p.solver, max_iter=1))
    r = solve_static(p)
    assert not r.success and r.message.startswith("Newton round not converged")


def _old_merge(s: SpringSet) -> SpringSet:
    """The previous implementation (np.unique over rows), the reference for the lexsort."""
    key = np.column_stack([s.a, s.b, s.shift, np.round(s.l0, 12), np.round(s.limit, 12),
                           s.compress])
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    k = np.bincount(inverse.ravel(), s.k, first.size)
    return SpringSet(s.a[first], s.b[first], s.shift[first], k, s.l_init[first], s.l0[first],
                     s.limit[first], s.compress[first], s.kind[first])


def test_merge_equals_the_row_unique_reference_with_unequal_pretensions():
    """Pillar and longitudinal springs on the same pair with different rest lengths must not
    merge; equal ones must."""
    doc = {"model": "jacquard", "fabric": {"wales": 6, "courses": 4, "dz": 10.0, "dh": 8.0,
                                           "loop_width_stiffness": 0.3},
           "ground": {"pretension": 0.8},
           "fall_plate": {"design": "\n".join(["#+.#+."] * 4)},
           "inlay": {"design": "\n".join([".+#.+#"] * 4), "pretension": {"longitudinal": 0.8}}}
    s = build_network(parse_problem(doc, "t.toml")).springs
    got, want = merge_parallel(s), _old_merge(s)
    assert got.n < s.n
    for f in ("a", "b", "shift", "k", "l_init", "l0", "limit", "compress", "kind"):
        assert np.array_equal(getattr(got, f), getattr(want, f)), f


# --- the JSON writer's bulk arrays ----------------------------------------------------------

floats = st.floats(allow_nan=True, allow_infinity=True, width=64)


@settings(max_examples=60, deadline=None)
@given(hnp.arrays(np.float64, hnp.array_shapes(min_dims=1, max_dims=3, max_side=9),
                  elements=floats))
def test_array_text_reads_back_as_json_dumps_of_tolist(a):
    want = json.loads(json.dumps(_plain(a)))
    assert json.loads(array_text(a)) == want


@settings(max_examples=30, deadline=None)
@given(hnp.arrays(np.int64, hnp.array_shapes(min_dims=1, max_dims=2, max_side=9),
                  elements=st.integers(-2 ** 62, 2 ** 62)))
def test_array_text_of_integers(a):
    assert json.loads(array_text(a)) == a.tolist()


def test_json_text_writes_large_arrays_in_bulk_and_keeps_the_rest():
    big = RNG.standard_normal((1500, 2))
    big[3, 1] = np.nan
    data = {"name": "\x00not a marker\x00", "particles": {"final": big, "small": np.ones(3)},
            "list": [big[:600]], "n": np.int64(4)}
    text = json_text(data)
    back = json.loads(text)
    assert back == json.loads(json.dumps(_plain(data), indent=1))
    assert back["particles"]["final"][3][1] is None
    assert text.count("\n") < 2 * 1500 + 50          # one [x, y] per line, not one number


def test_line_search_keeps_every_step_downhill_from_a_far_start():
    """From a start 0.6 w away from the natural grid (springs crossing slack/taut, full Newton
    steps that overshoot), every accepted step lowers the energy and the iteration still ends
    at IPOPT's equilibrium."""
    from knit_nlp.jacquard import newton
    p = _random_problem(10, 8, 5)
    net = build_network(p)
    s = merge_parallel(net.springs)
    energy = SpringEnergy(s, ~net.fixed, net.held, net.natural,
                          p.solver.regularization * float(s.k.max()))
    z0 = net.held[~net.fixed].ravel() + 0.6 * p.w * np.random.default_rng(2).standard_normal(
        2 * (~net.fixed).sum())
    values = []
    original = energy.gradient

    def recording(z):
        values.append(energy.value(z))
        return original(z)

    energy.gradient = recording
    out = newton.minimise(energy, z0, 1e-10, 100, float("inf"))
    assert out.converged
    assert all(b <= a + 1e-9 * abs(a) for a, b in zip(values, values[1:]))
    assert np.max(np.abs(energy.positions(out.z) - solve_static(p, method="ipopt").positions)) \
        < 1e-7 * p.w
