"""Physics of the double-jacquard mass-spring model (docs/jacquard.md)."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from knit_nlp.jacquard import (build_network, load_problem, parse_problem, solve_explicit,
                               solve_static)
from knit_nlp.jacquard.springs import KINDS, spring_geometry

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"


def _doc(fp: str, inlay: str, **fabric) -> dict:
    rows = fp.strip().splitlines()
    fab = {"wales": len(rows[0]), "courses": len(rows), "dz": 10.0, "dh": 8.0}
    fab.update(fabric)
    return {"model": "jacquard", "fabric": fab, "fall_plate": {"design": fp},
            "inlay": {"design": inlay}}


def _problem(fp: str, inlay: str, **fabric):
    return parse_problem(_doc(fp, inlay, **fabric), "test.toml")


def _random_design(rng, m: int, n: int, symbols: str) -> str:
    return "\n".join("".join(rng.choice(list(symbols), m)) for _ in range(n))


def _mirror(design: str) -> str:
    return "\n".join(line[::-1] for line in design.splitlines())


def _hessian(x: np.ndarray, net) -> np.ndarray:
    """Dense Hessian of sum 1/2 k (l - l0)^2 over taut springs (numpy, independent of casadi)."""
    s, n = net.springs, x.shape[0]
    d, length = spring_geometry(x, s)
    hess = np.zeros((2 * n, 2 * n))
    for a, b, dv, ell, k, l0 in zip(s.a, s.b, d, length, s.k, s.l0):
        if ell <= l0:
            continue
        u = dv / ell
        block = k * np.outer(u, u) + k * (1 - l0 / ell) * (np.eye(2) - np.outer(u, u))
        for p_, q_, sign in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
            hess[2 * p_:2 * p_ + 2, 2 * q_:2 * q_ + 2] += sign * block
    return hess


def test_net_cells_add_no_lateral_spring_and_all_net_stays_straight():
    p = _problem("\n".join(["......"] * 6), "\n".join(["......"] * 6))
    net = build_network(p)
    lateral = [KINDS.index(k) for k in KINDS if k.endswith(("thick", "thin"))]
    assert not np.isin(net.springs.kind, lateral).any()
    for result in (solve_static(p), solve_explicit(p, max_steps=2000)):
        assert result.success
        assert np.max(np.abs(result.displacement()[:, 0])) < 1e-9 * p.w
    # one thick cell is enough to move wales sideways (the test above can fail)
    q = _problem("\n".join(["#....."] + ["......"] * 5), "\n".join(["......"] * 6))
    assert np.max(np.abs(solve_static(q).displacement()[:, 0])) > 1e-3 * q.w


@pytest.mark.parametrize("fp, inlay, expected", [
    ("\n".join(["......"] * 4), "\n".join(["......"] * 4), 10),      # 6 free wales, 1 pinned
    ("\n".join(["#....."] * 4), "\n".join(["......"] * 4), 8),       # wales 0,3 joined; 1,2,4,5 free
    ("\n".join(["#+#+#+"] * 4), "\n".join(["+#+#+#"] * 4), 0),
])
def test_detected_zero_modes_match_hessian_null_space(fp, inlay, expected):
    p = _problem(fp, inlay)
    net = build_network(p)
    assert net.zero_modes == expected
    hess = _hessian(net.natural, net)
    keep = np.repeat(~net.fixed, 2)
    eig = np.linalg.eigvalsh(hess[np.ix_(keep, keep)])
    assert int(np.sum(eig < 1e-9 * eig.max())) == expected


def test_zero_mode_treatment_keeps_floating_centroids():
    p = _problem("\n".join(["##...."] * 6), "\n".join(["......"] * 6))
    static = solve_static(p)
    assert static.success and len(static.network.floating) == 3     # wales {1,4}, {2}, {5}
    assert np.max(np.abs(static.displacement())) > 0.1 * p.w          # the fabric does move
    for idx in static.network.floating:
        assert np.allclose(static.positions[idx].mean(axis=0),
                           static.network.natural[idx].mean(axis=0), atol=1e-8)


@pytest.mark.parametrize("boundary", ["fixed", "periodic"])
def test_mirrored_design_with_flipped_zigzag_gives_mirrored_result(boundary):
    rng = np.random.default_rng(7)
    fp, inlay = _random_design(rng, 8, 8, "#+"), _random_design(rng, 8, 8, "#+.")
    p = _problem(fp, inlay, boundary=boundary)
    q = _problem(_mirror(fp), _mirror(inlay), boundary=boundary, zigzag="left")
    x, y = solve_static(p).positions, solve_static(q).positions
    m, n = p.wales, p.courses
    ym = y.reshape(n, m, 2)[:, ::-1].reshape(-1, 2) * np.array([-1.0, 1.0])
    ym[:, 0] += (m - 1) * p.w
    diff = x - ym
    if boundary == "periodic":           # the pinned particle differs: compare up to translation
        diff = diff - diff.mean(axis=0)
    assert np.max(np.abs(diff)) < 1e-6 * p.w
    # without flipping the zigzag the mirror image is not the result
    r = solve_static(_problem(_mirror(fp), _mirror(inlay), boundary=boundary)).positions
    rm = r.reshape(n, m, 2)[:, ::-1].reshape(-1, 2) * np.array([-1.0, 1.0])
    rm[:, 0] += (m - 1) * p.w
    diff = (x - rm) - ((x - rm).mean(axis=0) if boundary == "periodic" else 0.0)
    assert np.max(np.abs(diff)) > 1e-2 * p.w


def test_static_and_explicit_agree_on_diamond():
    p = load_problem(PROBLEMS / "jacquard_diamond.toml")
    static, explicit = solve_static(p), solve_explicit(p)
    assert static.success and explicit.success
    assert np.max(np.abs(static.displacement())) > 0.1 * p.w        # a real deformation
    assert np.max(np.abs(static.positions - explicit.positions)) < 1e-3 * p.w
    assert static.residual_force < 1e-5 and explicit.residual_force < 1e-5


def test_static_and_explicit_agree_on_random_thick_thin():
    rng = np.random.default_rng(3)
    p = _problem(_random_design(rng, 8, 8, "#+"), _random_design(rng, 8, 8, "#+."))
    static, explicit = solve_static(p), solve_explicit(p)
    assert static.success and explicit.success
    assert np.max(np.abs(static.positions - explicit.positions)) < 1e-3 * p.w


def test_undamped_midpoint_gains_energy_damped_loses_it():
    p = _problem("\n".join(["##++"] * 4), "\n".join(["+#+."] * 4), lambda_max=2.0, dt=0.2)
    undamped = solve_explicit(dataclasses.replace(p, damping=0.0), max_steps=400,
                              record_energy=True).energy_history
    damped = solve_explicit(p, max_steps=400, record_energy=True).energy_history
    assert undamped[-1] > 1.01 * undamped[0]
    assert damped[-1] < 0.5 * damped[0]


def test_every_spring_ends_within_lambda_max():
    p = dataclasses.replace(load_problem(PROBLEMS / "jacquard_diamond.toml"), lambda_max=1.02)
    free = dataclasses.replace(p, lambda_max=2.0)
    assert solve_static(free).max_stretch() > 1.04            # the limit really binds
    static = solve_static(p)
    explicit = solve_explicit(p, max_steps=20000)
    assert static.success
    assert static.max_stretch() <= 1.02 * (1 + 1e-7)
    assert explicit.max_stretch() <= 1.02 * (1 + 1e-6)
    assert static.min_order_gap() >= -1e-9 and explicit.min_order_gap() >= -1e-9


def test_loop_width_extension_is_in_force_balance_and_removes_zero_modes():
    fp, inlay = "\n".join(["##...."] * 6), "\n".join(["......"] * 6)
    doc = _doc(fp, inlay, lambda_max=2.0)                 # no length limit reaction
    doc["fall_plate"]["pretension"] = {"thick": 0.5}      # underlaps pull hard
    bare = solve_static(parse_problem(doc, "t.toml"))
    doc["fabric"]["loop_width_stiffness"] = 0.5
    padded = solve_static(parse_problem(doc, "t.toml"))
    assert bare.network.zero_modes > 0 and padded.network.zero_modes == 0
    assert padded.success and padded.residual_force < 1e-5   # forces include the pushing springs
    s = padded.network.springs
    _, length = spring_geometry(padded.positions, s)
    w = bare.problem.w
    assert np.min(length[s.compress]) > 0.95 * w                # neighbours kept about w apart
    _, bare_length = spring_geometry(bare.positions, s)         # same pairs in the bare fabric
    assert np.min(bare_length[s.compress]) < 0.8 * w            # ... where without them they close


@pytest.mark.parametrize("boundary", ["fixed", "periodic"])
def test_wale_skew_of_known_displacements(boundary):
    """``wale_skew`` on prescribed positions with closed-form answers: a shear x += γ·y leans
    every pillar loop right by atan(γ) (positive), a translation of wale i by d_i moves its mean
    by d_i and leans nothing; for a periodic repeat the top loop closes on the next repeat's
    bottom particle (N·h higher), so a per-wale translation still gives zero inclination."""
    from knit_nlp.jacquard.result import JacquardResult
    p = _problem("#+#+#\n+#+#+\n#+#+#\n+#+#+", "+#+#+\n#+#+#\n+#+#+\n#+#+#", boundary=boundary)
    net = build_network(p)
    nat = net.natural
    shift = np.array([0.3, -0.1, 0.05, 0.2, -0.4]) * p.w             # per wale, i = index % M
    moved = nat + np.column_stack([shift[np.arange(p.n_particles) % p.wales], np.zeros(p.n_particles)])
    skew = JacquardResult(p, net, "static", moved, True, "given").wale_skew()
    np.testing.assert_allclose(skew["mean_dx_mm"], shift, atol=1e-12)
    np.testing.assert_allclose(skew["mean_angle_deg"], 0.0, atol=1e-9)
    np.testing.assert_allclose(skew["max_abs_angle_deg"], 0.0, atol=1e-9)
    if boundary == "fixed":
        gamma = 0.2
        sheared = nat + np.column_stack([gamma * nat[:, 1], np.zeros(p.n_particles)])
        skew = JacquardResult(p, net, "static", sheared, True, "given").wale_skew()
        np.testing.assert_allclose(skew["mean_angle_deg"], np.degrees(np.arctan(gamma)), rtol=1e-12)
        np.testing.assert_allclose(skew["mean_dx_mm"], gamma * p.h * (p.courses - 1) / 2, rtol=1e-12)
    else:   # alternate courses pushed right by d: loops lean ±atan(d/h), the wrap included
        d = 0.25 * p.w
        j = np.arange(p.n_particles) // p.wales
        zig = nat + np.column_stack([np.where(j % 2 == 0, d, 0.0), np.zeros(p.n_particles)])
        skew = JacquardResult(p, net, "static", zig, True, "given").wale_skew()
        np.testing.assert_allclose(skew["mean_angle_deg"], 0.0, atol=1e-9)
        np.testing.assert_allclose(skew["max_abs_angle_deg"], np.degrees(np.arctan(d / p.h)), rtol=1e-12)
        np.testing.assert_allclose(skew["mean_dx_mm"], d / 2, rtol=1e-12)


def test_natural_grid_is_i_w_by_j_h():
    """P(i, j) starts at (i·w, j·h), row j·M + i, with w = 10/dh and h = 10/dz (spec); w and
    h both differ from 1 here, so a swapped or inverted spacing shows."""
    p = _problem("#+#+\n+#+#\n#+#+\n+#+#", "+#+#\n#+#+\n+#+#\n#+#+", dz=4.0, dh=8.0)
    assert p.w == pytest.approx(1.25) and p.h == pytest.approx(2.5)
    nat = build_network(p).natural
    for j in range(p.courses):
        for i in range(p.wales):
            np.testing.assert_allclose(nat[j * p.wales + i], [i * 1.25, j * 2.5], rtol=1e-15)
    # pillar (ground) springs join P(i, j) to P(i, j+1), across the periodic seam to the next
    # repeat's P(i, 0) = N·h higher: every one is h long in the natural grid
    s = build_network(p).springs
    ground = s.kind == KINDS.index("ground")
    assert ground.sum() == p.wales * p.courses
    np.testing.assert_allclose(s.l_init[ground], 2.5, rtol=1e-15)
    seam = ground & (s.shift[:, 1] != 0)
    np.testing.assert_allclose(s.shift[seam], [[0.0, 4 * 2.5]] * p.wales, rtol=1e-15)
