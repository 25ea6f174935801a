"""The explicit midpoint scheme (paper eqs. 9-11) is second-order accurate in time.

As rockit's integrator tests do: integrate the same initial value problem to the same final
time with steps dt, dt/2, dt/4, dt/8, measure the error against a reference run with a much
smaller step, and fit the slope of log(error) against log(dt). The network is a small
thick/thin design whose springs are all taut (pretension) and far from the λ_max limit, and the
perturbation is small enough that no order pair crosses, so the smooth ODE m a = F(x, v) is
what is integrated (the constraints of 3.4 are not part of ``midpoint_step``).
"""
from __future__ import annotations

import numpy as np
import pytest

from knit_nlp.jacquard import build_network, parse_problem
from knit_nlp.jacquard.explicit import acceleration, midpoint_step
from knit_nlp.jacquard.springs import spring_geometry


def _network(damping: float):
    doc = {"model": "jacquard",
           "fabric": {"wales": 4, "courses": 4, "dz": 10.0, "dh": 8.0, "damping": damping,
                      "lambda_max": 2.0},
           "fall_plate": {"design": "#+#+\n+#+#\n#+#+\n+#+#"},
           "inlay": {"design": "+#+#\n#+#+\n+#+#\n#+#+"}}
    p = parse_problem(doc, "order.toml")
    return p, build_network(p)


def _run(x0: np.ndarray, v0: np.ndarray, accel, t_end: float, steps: int) -> np.ndarray:
    x, v, dt = x0.copy(), v0.copy(), t_end / steps
    for _ in range(steps):
        x, v = midpoint_step(x, v, dt, accel)
    return np.concatenate([x.ravel(), v.ravel()])


@pytest.mark.parametrize("damping", [0.0, 0.5])
def test_midpoint_scheme_is_second_order(damping):
    p, net = _network(damping)
    rng = np.random.default_rng(11)
    x0 = net.natural + 0.03 * p.w * rng.standard_normal(net.natural.shape) * (~net.fixed)[:, None]
    v0 = np.zeros_like(x0)
    _, length = spring_geometry(x0, net.springs)
    assert np.all(length > net.springs.l0)                   # every spring taut: smooth forces
    accel = acceleration(net, p.mass, damping)
    # a time span of several of the fastest periods, so the error is in its asymptotic regime
    omega = np.sqrt(np.max(net.springs.k) * 4 / p.mass)
    t_end = 6.0 / omega
    ref = _run(x0, v0, accel, t_end, 4096)
    assert np.max(np.abs(ref[: x0.size] - x0.ravel())) > 1e-3 * p.w   # the particles do move
    steps = np.array([32, 64, 128, 256])
    errors = np.array([np.max(np.abs(_run(x0, v0, accel, t_end, n) - ref)) for n in steps])
    order = np.polyfit(np.log(t_end / steps), np.log(errors), 1)[0]
    assert 1.8 < order < 2.2, (errors, order)
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 3.5) & (ratios < 4.5)), ratios

