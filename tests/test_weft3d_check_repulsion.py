"""Other contacts of the 3-D model (model/spatial/repulsion.py, docs/weft3d.md "Other
contacts"): the repulsion stops a pair where the soft-shell law says, the natural neighbour list
carries no force, and a solve adds the pairs its check finds closer than touch."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from knit_nlp.weft.model.compression import ACRYLIC
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.model.spatial.repulsion import (Neighbours, natural_neighbours,
                                                   repulsion_energy, sample_s)

W = 0.7                         # the length each sample carries (mm)


def _stop(push: float, shift: float, scale: float = 1.0) -> float:
    """Two listed sample points, one held at the origin, the other pushed towards it along z
    by ``push``: the distance where it stops (the law starting at ``rest``)."""
    z = ca.SX.sym("z")
    pts = ca.horzcat(ca.DM.zeros(3), ca.vertcat(0.0, 0.0, z))
    pair = Neighbours(np.array([0]), np.array([0]), np.array([0]), np.array([1]),
                      np.array([shift]), np.array([scale]), 2)
    e = ca.Function("e", [z], [repulsion_energy(ACRYLIC, W, pts, pair)])
    rest = _rest(shift, scale)
    assert float(e(rest)) == 0.0                                  # touching: no energy
    solver = ca.nlpsol("s", "ipopt", {"x": z, "f": e(z) + push * z},
                       {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes",
                                                        "tol": 1e-14}})
    sol = solver(x0=rest, lbx=0.0)        # from above: no step over the core to the far side
    assert solver.stats()["success"]
    return float(sol["x"])


def _rest(shift: float, scale: float) -> float:
    """Where the pair's law starts: d′ = 2R_c + a (d + c − 2R_c) = 2R (C3), solved by hand."""
    return 2 * ACRYLIC.core_radius + ACRYLIC.shell / scale - shift


@pytest.mark.parametrize("shift", [0.0, 0.3])
def test_a_pushed_pair_stops_where_the_law_says(shift: float) -> None:
    """w² f(d + c) = F (R1 with the soft-shell force f = −v′): d = f⁻¹(F / w²) − c, inside the
    shell, outside the core shifted by c."""
    push = 2e-4
    d = _stop(push, shift)
    assert d == pytest.approx(float(ACRYLIC.distance_at(push / W ** 2)) - shift, rel=1e-9)
    assert 2 * ACRYLIC.core_radius - shift < d < 2 * ACRYLIC.radius - shift


@pytest.mark.parametrize("rest", [0.70, 0.90])
def test_a_pair_pressed_at_rest_keeps_the_hard_core(rest: float) -> None:
    """A pair at rest at d₀ < 2r (a tight fabric's natural pair) thinned by a = Δ/(d₀ − 2R_c)
    (C3): no force at d₀; pushed by F it stops where a w² f(d′) = F, d′ = 2R_c + a (d − 2R_c),
    solved by hand: d = 2R_c + (f⁻¹(F/(a w²)) − 2R_c)/a, between the core and d₀; and a push
    100 times harder still leaves it outside the core 2R_c."""
    core = 2 * ACRYLIC.core_radius
    a = ACRYLIC.shell / (rest - core)
    for push in (2e-4, 2e-2):
        d = _stop(push, 0.0, a)
        law = float(ACRYLIC.distance_at(push / (a * W ** 2)))
        assert d == pytest.approx(core + (law - core) / a, rel=1e-9)
        assert core < d < rest


DOC = {"name": "acrylic3d", "fabric": {"courses": 4, "wales": 4},
       "loop": {"length": 11.28, "harmonics": 3}, "material": {"R_f": 0.045},
       "yarn": {"radius": 0.74, "geometry": "3d", "elevation_modes": 4},
       "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]}]}


def test_the_natural_list_is_force_free_and_holds_the_other_contacts() -> None:
    """Every listed pair of natural sample points lies at or beyond touch once shifted (no
    force in the natural state), no pair is one piece of yarn, and the list holds the legs of
    neighbouring wales, the loop below and courses two apart."""
    pr = parse_problem(DOC, "acrylic3d.toml")
    sh, n, r = pr.yarn.natural3d, pr.wales, pr.yarn.radius
    nb = natural_neighbours(sh, pr.yarn.shell(), pr.courses, n)
    s = sample_s(pr.L, nb.samples)
    starts = sh.starts(pr.courses, n).reshape(-1, 3)
    x = sh.xyz(s)
    xa, xb = starts[nb.ka] + x[nb.qa], starts[nb.kb] + x[nb.qb]
    d0 = np.linalg.norm(xa - xb, axis=1)
    core = 2 * pr.yarn.core_radius
    seen = core + nb.scale * (d0 + nb.shift - core)           # (C3), written out
    assert np.all(seen >= 2 * r - 1e-12)
    assert np.any(d0 < 2 * r)                                 # some naturally closer: thinned
    assert np.all(nb.shift == 0.0)                            # ... with the core kept at 2R_c
    np.testing.assert_allclose(nb.scale[d0 < 2 * r], (2 * r - core) / (d0[d0 < 2 * r] - core))
    ua, ub = (nb.ka % n) * pr.L + s[nb.qa], (nb.kb % n) * pr.L + s[nb.qb]
    same = nb.ka // n == nb.kb // n
    assert np.all(np.abs(ua - ub)[same] >= np.pi * r)
    kinds = set(zip((nb.kb // n - nb.ka // n).tolist(), (nb.kb % n - nb.ka % n).tolist()))
    assert {(0, 1), (1, 0), (2, 0)} <= kinds


PULL = {"name": "pull3d", "fabric": {"courses": 2, "wales": 2}, "units": {"length": "mm", "force": "N"},
        "loop": {"length": 11.28, "harmonics": 3}, "material": {"R_f": 0.045},
        "yarn": {"radius": 0.74, "geometry": "3d", "elevation_modes": 4},
        "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                  {"loop": [1, 2], "point": "H", "displacement": [0.0, 0.8]}]}


def test_a_solve_adds_the_pairs_its_check_finds_and_says_so(tmp_path) -> None:
    """A 2 x 2 acrylic pull brings pairs of pieces the natural list does not hold closer than
    2r: the solve adds them, solves again from its answer, and at the end its check finds none
    missing; the result JSON and the summary say how many were added."""
    from knit_nlp.weft.output.results import WeftResult
    from knit_nlp.weft.output.summary import solve_summary
    from knit_nlp.weft.solving.variants import equilibrium

    pr = parse_problem(PULL, "pull3d.toml")
    eq = equilibrium(pr)
    sol = eq.solve()
    assert sol.success
    rounds = eq.nlp.rounds
    assert rounds and rounds[0]["added"] > 0 and rounds[-1]["status"] == "Solve_Succeeded"
    assert len(eq.missing(sol.x)[0]) == 0
    natural = natural_neighbours(pr.yarn.natural3d, pr.yarn.shell(), 2, 2)
    assert len(eq.nlp.neighbours) == len(natural) + sum(r["added"] for r in rounds)
    result = WeftResult.of(sol)
    block = result.to_json()["spatial"]["other_contacts"]
    assert block["rounds"] == rounds and block["listed_pairs"] == len(eq.nlp.neighbours)
    line = solve_summary(result, [])
    word = "round" if len(rounds) == 1 else "rounds"
    assert f"{len(rounds)} {word} added {sum(r['added'] for r in rounds)} pairs" in line
