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


def _stop(push: float, shift: float) -> float:
    """Two listed sample points, one held at the origin, the other pushed towards it along z
    by ``push``: the distance where it stops."""
    z = ca.SX.sym("z")
    pts = ca.horzcat(ca.DM.zeros(3), ca.vertcat(0.0, 0.0, z))
    pair = Neighbours(np.array([0]), np.array([0]), np.array([0]), np.array([1]),
                      np.array([shift]), 2)
    e = ca.Function("e", [z], [repulsion_energy(ACRYLIC, W, pts, pair)])
    assert float(e(2 * ACRYLIC.radius - shift)) == 0.0            # touching: no energy
    solver = ca.nlpsol("s", "ipopt", {"x": z, "f": e(z) + push * z},
                       {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes",
                                                        "tol": 1e-14}})
    sol = solver(x0=2 * ACRYLIC.radius - shift)
    assert solver.stats()["success"]
    return float(sol["x"])


@pytest.mark.parametrize("shift", [0.0, 0.3])
def test_a_pushed_pair_stops_where_the_law_says(shift: float) -> None:
    """w² f(d + c) = F (R1 with the soft-shell force f = −v′): d = f⁻¹(F / w²) − c, inside the
    shell, outside the core shifted by c."""
    push = 2e-4
    d = _stop(push, shift)
    assert d == pytest.approx(float(ACRYLIC.distance_at(push / W ** 2)) - shift, rel=1e-9)
    assert 2 * ACRYLIC.core_radius - shift < d < 2 * ACRYLIC.radius - shift


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
    nb = natural_neighbours(sh, pr.courses, n)
    s = sample_s(pr.L, nb.samples)
    starts = sh.starts(pr.courses, n).reshape(-1, 3)
    x = sh.xyz(s)
    xa, xb = starts[nb.ka] + x[nb.qa], starts[nb.kb] + x[nb.qb]
    d0 = np.linalg.norm(xa - xb, axis=1)
    assert np.all(d0 + nb.shift >= 2 * r - 1e-12)
    assert np.any(d0 < 2 * r)                                 # some naturally closer: shifted
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
    assert len(eq.missing(sol.x)) == 0
    natural = natural_neighbours(pr.yarn.natural3d, 2, 2)
    assert len(eq.nlp.neighbours) == len(natural) + sum(r["added"] for r in rounds)
    result = WeftResult.of(sol)
    block = result.to_json()["spatial"]["other_contacts"]
    assert block["rounds"] == rounds and block["listed_pairs"] == len(eq.nlp.neighbours)
    line = solve_summary(result, [])
    word = "round" if len(rounds) == 1 else "rounds"
    assert f"{len(rounds)} {word} added {sum(r['added'] for r in rounds)} pairs" in line
