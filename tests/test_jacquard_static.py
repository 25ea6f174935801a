"""The static NLP's hand-assembled pieces against independent computations."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from knit_nlp.jacquard import build_network, load_problem, parse_problem, solve_static
from knit_nlp.jacquard.static import (WorkingSet, build_nlp, incidence, merge_parallel,
                                      pairwise_sum)

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"


def _diamond(**changes):
    return dataclasses.replace(load_problem(PROBLEMS / "jacquard_diamond.toml"), **changes)


def _loop_width_problem():
    doc = {"model": "jacquard",
           "fabric": {"wales": 6, "courses": 4, "dz": 10.0, "dh": 8.0,
                      "loop_width_stiffness": 0.5},
           "fall_plate": {"design": "\n".join(["##...."] * 4)},
           "inlay": {"design": "\n".join(["+.+.+."] * 4)}}
    return parse_problem(doc, "t.toml")


@pytest.mark.parametrize("make", [_diamond, _loop_width_problem])
def test_structural_hessian_equals_casadi_hessian_of_the_lagrangian(make):
    """hess_lag = B^T blockdiag(H_s) B assembled by hand must equal CasADi's own AD Hessian of
    lam_f f + lam_g^T g, springs, regularisation, length limits and order rows included."""
    p = make()
    net = build_network(p)
    s = merge_parallel(net.springs)
    work = WorkingSet(np.arange(0, s.n, 3), np.arange(0, net.order_left.size, 2))
    nlp, custom, _ = build_nlp(p, net, s, incidence(s, net.natural.shape[0]), work)
    x, g = nlp["x"], nlp["g"]
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", g.numel())
    reference = ca.Function("ref", [x, lam_f, lam_g],
                            [ca.hessian(lam_f * nlp["f"] + ca.dot(lam_g, g), x)[0]])
    rng = np.random.default_rng(1)
    # random points: some springs slack, some taut, loop-width springs both ways
    for scale in (0.05, 0.3):
        x0 = net.natural.ravel() + scale * p.w * rng.standard_normal(x.numel())
        lf, lg = rng.uniform(0.1, 2.0), rng.standard_normal(g.numel())
        want = np.triu(np.array(reference(x0, lf, lg)))
        got = np.array(custom["hess_lag"](x0, [], lf, lg))
        assert np.max(np.abs(got - want)) < 1e-12 * np.max(np.abs(want))


def test_pairwise_sum_is_exact_on_integers_and_accurate_on_many_terms():
    for n in (1, 2, 3, 7, 1000, 1025):
        v = ca.MX.sym("v", 1, n)
        f = ca.Function("f", [v], [pairwise_sum(v)])
        data = np.arange(1, n + 1, dtype=float)
        assert float(f(data)) == n * (n + 1) / 2
    n = 2 ** 18
    data = np.full(n, 0.1)
    v = ca.MX.sym("v", 1, n)
    assert abs(float(ca.Function("f", [v], [pairwise_sum(v)])(data)) - 0.1 * n) < 1e-10


def test_constraint_generation_reaches_the_fully_constrained_minimiser():
    """Convexity: the relaxation whose minimiser satisfies every constraint has the same
    minimiser as the NLP holding every length limit and order constraint from the start."""
    p = _diamond(lambda_max=1.02)
    generated = solve_static(p)
    assert generated.success and generated.constraints["rounds"] >= 2   # the limits did bind
    assert 0 < generated.constraints["length_limits"] < generated.network.springs.n
    net = generated.network
    s = merge_parallel(net.springs)
    every = WorkingSet(np.arange(s.n), np.arange(net.order_left.size))
    nlp, custom, bounds = build_nlp(p, net, s, incidence(s, net.natural.shape[0]), every)
    solver = ca.nlpsol("all", "ipopt", nlp, {**custom, "print_time": False,
                                            "ipopt": {"print_level": 0, "sb": "yes",
                                                      "tol": 1e-10}})
    x = np.array(solver(x0=net.natural.ravel(), **bounds)["x"]).reshape(-1, 2)
    assert solver.stats()["success"]
    assert np.max(np.abs(x - generated.positions)) < 1e-6 * p.w
