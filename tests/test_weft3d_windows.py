"""A designed contact's own window follows its crossing (model/spatial/repulsion.py ``missing``,
solving/rounds3d.py; docs/weft3d.md "Other contacts", "Rounds"): under a large pull the yarn
slides through its crossings (σ moves, up to 1.6 mm on the 12 × 12 course pull to +50 %,
against a wrap's window of ±0.25·2r = ±0.37 mm). A pair pressed into the core where the
crossing *was* is an other contact the rounds must add; a pair where the crossing *is* is the
wrap's own (its law S7 acts there) and is not added."""
from __future__ import annotations

import numpy as np
import pytest

from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.model.spatial.proximity import Near, ProximityReport
from knit_nlp.weft.model.spatial.repulsion import (WRAP_WINDOW, missing, natural_distance,
                                                   natural_neighbours, none, sample_s)
from knit_nlp.weft.solving.variants import equilibrium

DOC = {"name": "slid3d", "fabric": {"courses": 2, "wales": 2},
       "units": {"length": "mm", "force": "N"},
       "loop": {"length": 11.28, "harmonics": 3}, "material": {"R_f": 0.045},
       "yarn": {"radius": 0.74, "geometry": "3d", "elevation_modes": 4},
       "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]}]}
SLIDE = (1.1, -0.9)              # the crossing's slide along the upper, lower yarn (mm), > 0.37


@pytest.fixture(scope="module")
def fabric():
    """The 2 × 2 acrylic (wraps), its natural list, and the crossings' σ with crossing 0
    (upper loop (2, 1), A/D+C/F) slid by SLIDE, the others natural."""
    pr = parse_problem(DOC, "slid3d.toml")
    sh = pr.yarn.natural3d
    listed = natural_neighbours(sh, pr.yarn.shell(), pr.courses, pr.wales)
    K = (pr.courses - 1) * pr.wales * sh.s_upper.size
    sigma = np.vstack([np.tile(sh.s_upper, K // sh.s_upper.size),
                       np.tile(sh.s_lower, K // sh.s_lower.size)])
    sigma[:, 0] += SLIDE
    return pr, sh, listed, sigma


def _pressed(u_upper: float, u_lower: float, d: float = 0.60) -> Near:
    """The check's finding: courses 2 (upper) and 1 of wale 1 at these material coordinates,
    ``d`` apart (inside the core 2R_c = 0.65 mm)."""
    return Near(np.array([1]), np.array([u_upper]), np.array([0]), np.array([u_lower]),
                np.array([d]))


def _nearest(pr, S: int, u_upper: float, u_lower: float) -> tuple[int, int, int, int]:
    """Loop and sample of both points (loop (2, 1) is k = n, loop (1, 1) is k = 0)."""
    s = sample_s(pr.L, S)
    return (pr.wales, int(np.argmin(np.abs(s - u_upper))), 0,
            int(np.argmin(np.abs(s - u_lower))))


def _holds(pairs, pair: tuple[int, int, int, int]) -> bool:
    ku, qu, kl, ql = pair
    return bool(np.any(((pairs.ka == ku) & (pairs.qa == qu) & (pairs.kb == kl) & (pairs.qb == ql))
                       | ((pairs.kb == ku) & (pairs.qb == qu) & (pairs.ka == kl) & (pairs.qa == ql))))


def test_a_pair_pressed_where_the_crossing_was_is_added(fabric) -> None:
    """The pair at the natural crossing point, the crossing slid away: neither the natural list
    (which leaves the natural window out) nor the tracked window holds it, so ``missing``
    lists its nearest samples; the natural window alone would have dropped it for ever."""
    pr, sh, listed, sigma = fabric
    at = (sh.s_upper[0], sh.s_lower[0])
    pair = _nearest(pr, listed.samples, *at)
    assert not _holds(listed, pair)                       # the natural window left it out
    assert _holds(missing(_pressed(*at), listed, pr.L, pr.wales, sh, sigma), pair)
    assert not _holds(missing(_pressed(*at), listed, pr.L, pr.wales, sh), pair)


def test_a_pair_where_the_crossing_is_now_is_the_wraps_own(fabric) -> None:
    """The pair at the slid crossing's points is the wrap's own contact (its law S7 acts
    there): not added with the tracked windows, though the natural ones would add it (an
    empty list, so that only the windows decide)."""
    pr, sh, listed, sigma = fabric
    at = (sigma[0, 0], sigma[1, 0])
    pair = _nearest(pr, listed.samples, *at)
    assert min(abs(sample_s(pr.L, listed.samples)[pair[1]] - at[0]),
               abs(sample_s(pr.L, listed.samples)[pair[3]] - at[1])) < WRAP_WINDOW * 2 * sh.radius
    empty = none(listed.samples)
    assert not _holds(missing(_pressed(*at), empty, pr.L, pr.wales, sh, sigma), pair)
    assert _holds(missing(_pressed(*at), empty, pr.L, pr.wales, sh), pair)


def test_natural_distance_gives_the_lists_thinning(fabric) -> None:
    """d⁰ of any pair from the natural loops on their lattice reproduces the natural list's
    own thinning a = Δ/(d⁰ − 2R_c) (C3), which it computes from lattice shifts."""
    pr, sh, listed, _ = fabric
    a = pr.yarn.shell().thinning(natural_distance(listed, sh, pr.courses, pr.wales))
    np.testing.assert_allclose(a, listed.scale, rtol=1e-12)
    assert np.any(a > 1.0)


def test_the_rounds_judge_by_the_crossings_current_sigma(fabric, monkeypatch) -> None:
    """The solve's rounds (``SpatialEquilibrium.missing``) read σ from the answer: with
    crossing 0 slid and the check finding a pair in the core at its natural point, the round
    adds that pair, thinned by its natural distance (C3: no force at rest), and starts over
    (the pair is inside the core)."""
    pr, sh, _, sigma = fabric
    eq = equilibrium(pr)
    nlp = eq.nlp
    x = nlp.lift3d(np.broadcast_to(sh.coeffs, (pr.courses, pr.wales, sh.coeffs.size)),
                   np.broadcast_to(sh.elevation, (pr.courses, pr.wales, sh.elevation.size)),
                   sh.starts(pr.courses, pr.wales), sigma)
    assert np.allclose(nlp.x.get(x, "sigma"), sigma)
    at = (sh.s_upper[0], sh.s_lower[0])
    rep = ProximityReport(pr.yarn.radius, 2 * pr.yarn.core_radius, 61)
    rep.touching = _pressed(*at)
    rep.touching.designed = np.array([True])
    monkeypatch.setattr(eq, "report", lambda _x: rep)
    new, through = eq.missing(x)
    pair = _nearest(pr, nlp.neighbours.samples, *at)
    assert through and _holds(new, pair)
    d0 = natural_distance(new, sh, pr.courses, pr.wales)
    np.testing.assert_allclose(new.scale, pr.yarn.shell().thinning(d0))
    assert np.all(new.shift == 0.0) and np.all(new.scale > 1.0)


def test_a_refuted_answer_is_solved_again_on_finer_samples(fabric, monkeypatch) -> None:
    """When the check still finds pairs of loops in the core after the rounds, the solve
    rebuilds its list on samples twice as fine and starts over (load steps from the natural
    state), once, says so in its rounds' record, and the check still has the last word (a
    check that keeps saying "inside the core" refutes the answer)."""
    from knit_nlp.weft.solving.contact.rounds import REFUTED
    pr, sh, listed, _ = fabric
    eq = equilibrium(pr)
    rep = ProximityReport(pr.yarn.radius, 2 * pr.yarn.core_radius, 61, n_inside_core=1)
    monkeypatch.setattr(eq, "report", lambda _x: rep)
    sol = eq.solve()
    S = 2 * listed.samples
    assert eq.nlp.rounds == [{"added": 0, "status": "Solve_Succeeded", "started_over": True,
                              "samples": S}]
    assert eq.nlp.neighbours.samples == S
    assert len(eq.nlp.neighbours) == len(natural_neighbours(sh, pr.yarn.shell(), pr.courses,
                                                             pr.wales, S))
    assert not sol.success and sol.status == REFUTED
