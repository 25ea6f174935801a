"""Designed zones that follow slid crossings (model/contact/zones.py): hand-made zones, a
jersey whose middle course is shifted along the courses (its interlocks slid out of their
natural boxes), and the 4 x 4 diagonal pull whose last step met such pieces as "deep pairs"."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from knit_nlp.weft.model.cases import diagonal_pull, unclamped
from knit_nlp.weft.model.contact.crossings import designed_zones, find_crossings, judge
from knit_nlp.weft.model.contact.curves import Curves
from knit_nlp.weft.model.contact.natural import NaturalFabric
from knit_nlp.weft.model.contact.pairs import Grid, find_pairs
from knit_nlp.weft.model.contact.zones import Zones
from knit_nlp.weft.model.problem import Yarn, parse_problem
from knit_nlp.weft.output.check import check
from knit_nlp.weft.study import WeftStudy

L = 10.0
R = 0.15


def test_a_zone_holds_the_pieces_within_its_half_width_along_both_yarns():
    """One crossing of courses 0 and 1 at arcs (5, 7), z = 1: the box [4, 6] x [6, 8] on
    those two courses, edges included, nothing else (another course, one yarn too far)."""
    zones = Zones(np.array([0]), np.array([5.0]), np.array([1]), np.array([7.0]),
                  np.array([1.0]))
    ca = np.array([0, 0, 0, 0, 0, 0, 2])
    Sa = np.array([5.0, 4.0, 6.0, 6.01, 5.0, 3.0, 5.0])
    cb = np.array([1, 1, 1, 1, 1, 1, 1])
    Sb = np.array([7.0, 6.0, 8.0, 7.0, 8.01, 7.0, 7.0])
    assert zones.exempt(ca, Sa, cb, Sb).tolist() == [True, True, True, False, False, False,
                                                      False]


def test_zones_agree_with_a_brute_force_search():
    """Random zones on 4 courses (centres anywhere along them, half-widths 0.5-5) and 5,000
    random piece pairs: exempt() gives what testing every zone gives."""
    rng = np.random.default_rng(7)
    nz, nq = 60, 5000
    zones = Zones(rng.integers(0, 4, nz), rng.uniform(0, 40, nz), rng.integers(0, 4, nz),
                  rng.uniform(0, 40, nz), rng.uniform(0.5, 5.0, nz))
    ca, cb = rng.integers(0, 4, nq), rng.integers(0, 4, nq)
    Sa, Sb = rng.uniform(-1, 41, nq), rng.uniform(-1, 41, nq)
    brute = ((zones.ca[None] == ca[:, None]) & (zones.cb[None] == cb[:, None])
             & (np.abs(Sa[:, None] - zones.Sa[None]) <= zones.z[None])
             & (np.abs(Sb[:, None] - zones.Sb[None]) <= zones.z[None])).any(axis=1)
    assert 100 < brute.sum() < nq - 100
    assert np.array_equal(zones.exempt(ca, Sa, cb, Sb), brute)
    assert zones.exempt(ca.reshape(50, 100), Sa.reshape(50, 100), cb.reshape(50, 100),
                        Sb.reshape(50, 100)).shape == (50, 100)


def _rods_crossing(angle: float) -> Curves:
    """Course 1 a straight loop along x from the origin; course 2 a straight loop at ``angle``
    crossing it at (5, 0)."""
    coeffs = np.zeros((2, 1, 8))
    coeffs[1, 0, 7] = angle
    starts = np.array([[[0.0, 0.0]], [[5.0 - 5.0 * np.cos(angle), -5.0 * np.sin(angle)]]])
    return Curves.of(coeffs, starts, L)


@pytest.mark.parametrize("angle, z", [(np.pi / 2, 0.1 * L), (0.2, 2 * R / np.sin(0.2)),
                                      (0.005, 0.5 * L)])
def test_a_zone_is_as_wide_as_the_natural_boxes_rule_but_never_wider_than_half_a_loop(angle, z):
    """z = max(2r / sin α, 0.1 L) at the crossing's current angle, capped at L / 2 (at 0.005
    rad the rule would give 60, six loops)."""
    fab = NaturalFabric.of(parse_problem(unclamped(2, 2), "rods"), R)
    curves, grid = _rods_crossing(angle), Grid(2, 1, L, 200)
    found = find_crossings(curves, grid)
    zones = designed_zones(fab, curves, grid, found, {})
    assert len(found) == 1
    assert zones.z == pytest.approx([z, z], rel=1e-9)
    assert zones.Sa[0] == pytest.approx(5.0, abs=1e-9) and zones.Sb[0] == pytest.approx(5.0)


def _zones(fab: NaturalFabric, curves: Curves, grid: Grid) -> Zones:
    """The designed zones of a state, as the contact solver builds them (ContactSolver.look)."""
    found = find_crossings(curves, grid)
    return designed_zones(fab, curves, grid, found, judge(fab, found, grid.courses,
                                                          grid.wales).new)


def _shifted(d: float):
    """A 3 x 3 natural jersey with its middle course moved by d along x, its fabric and grid."""
    pr = parse_problem(unclamped(3, 3), "shifted")
    starts = np.array(pr.natural_starts(), dtype=float)
    starts[1, :, 0] += d
    curves = Curves.of(np.broadcast_to(pr.natural.coeffs, (3, 3, 8)), starts, L)
    return NaturalFabric.of(pr, R), curves, Grid(3, 3, L, 67)


def test_pieces_at_interlocks_slid_out_of_their_natural_boxes_are_exempt():
    """Middle course moved 2.5 along the courses: its interlocks with the courses below and
    above slid out of their natural boxes (no new crossing, 8 lost at the fabric's sides).
    With the natural boxes alone 148 pieces near the slid crossings must keep 2r and cannot
    (the distance is zero at a crossing); with the zones none is short, as in the natural
    fabric (the same 66 pairs)."""
    fab, curves, grid = _shifted(2.5)
    found = find_crossings(curves, grid)
    assert judge(fab, found, 3, 3).clean
    zones = _zones(fab, curves, grid)
    boxes_only = find_pairs(fab, curves, grid, 0.02 * L)
    assert np.sum(boxes_only.gap < boxes_only.required * (1 - 1e-3)) > 100
    with_zones = find_pairs(fab, curves, grid, 0.02 * L, zones)
    assert np.all(with_zones.gap >= with_zones.required * (1 - 1e-3))
    fab0, natural, _ = _shifted(0.0)
    assert len(with_zones) == len(find_pairs(fab0, natural, grid, 0.02 * L))


def test_new_crossings_get_no_zone():
    """Middle course moved 4: 8 crossings the natural fabric does not have; the pieces around
    them stay short with the zones as without."""
    fab, curves, grid = _shifted(4.0)
    assert judge(fab, find_crossings(curves, grid), 3, 3).n_new == 8
    zones = _zones(fab, curves, grid)
    short = [np.sum(p.gap < p.required * (1 - 1e-3)) for p in
             (find_pairs(fab, curves, grid, 0.02 * L),
              find_pairs(fab, curves, grid, 0.02 * L, zones))]
    assert short[0] == short[1] > 0


@pytest.mark.parametrize("n", [4])
def test_a_pull_whose_interlocks_slide_needs_no_restart(n):
    """The 4 x 4 diagonal pull: its last step's first solve met pieces at slid designed
    crossings, which the natural boxes alone took for pairs nearly crossed (a restart from the
    step's start, 4 pairs); with the zones no step restarts and the pull ends clean, for the
    solver and for the independent checker."""
    pr = parse_problem(diagonal_pull(n), f"pull {n}")
    pr = dataclasses.replace(pr, solver=dataclasses.replace(pr.solver, max_time=120.0),
                             yarn=Yarn(R))
    st = WeftStudy(pr, verbose=None)
    said: list[str] = []
    st.contact.log = lambda m: said.append(m if isinstance(m, str) else "")
    res = st.run()
    block = res.contact
    assert res.success and block.new_crossings == 0
    assert block.smallest_gap_over_2r >= 1 - 1e-4
    assert not any("restart" in m or "deep inside" in m for m in said)
    checked = check(res.to_json(), pr)          # the checker applies the same zones
    assert not checked.new_crossings and not checked.short_gaps


def test_expand_lists_every_index_of_every_range_with_its_owner():
    """ranges.expand against a plain loop, empty ranges included (the pair search, the zones
    and the rounds' matching all use it)."""
    from knit_nlp.weft.model.contact.ranges import expand
    rng = np.random.default_rng(3)
    lo = rng.integers(0, 40, 200)
    hi = lo + rng.integers(0, 5, 200)
    owner, rows = expand(lo, hi)
    want = [(i, r) for i in range(200) for r in range(lo[i], hi[i])]
    assert list(zip(owner.tolist(), rows.tolist())) == want
    assert expand(np.zeros(0, int), np.zeros(0, int))[0].size == 0


def _natural_result(pr) -> dict:
    """A result JSON's loops: the natural fabric of ``pr``."""
    m, n = pr.courses, pr.wales
    return {"loops": {"coefficients": np.broadcast_to(pr.natural.coeffs, (m, n, 8)).tolist(),
                      "course_starts": pr.natural_starts()[:, 0].tolist()}}


@pytest.mark.parametrize("moved", [3, 4])
def test_check_names_the_pairs_of_loops_that_lost_designed_crossings_and_where(moved):
    """A 5 x 5 jersey: natural, nothing lost. Its course ``moved`` (the middle one, or the
    one under the last course, whose losses with course 5 are at the edge: red when the last
    course is not an edge, which the middle course alone never showed) moved 100 L away: every
    interlock of that course with its neighbours is lost, listed per pair of loops (natural
    count, count now, lost), the pairs with a loop in wale 1 or 5 or course 1 or 5 marked at
    the edge and the others inside the fabric, the line saying how many pairs are inside; the
    listed losses add up to the count."""
    pr = parse_problem(unclamped(5, 5), "five")
    result = _natural_result(pr)
    natural = check(result, pr)
    assert natural.lost_crossings == 0 and natural.lost == [] and "(between" not in natural.line()
    result["loops"]["course_starts"][moved - 1][0] += 100 * L
    report = check(result, pr)
    assert report.ok                           # nothing crossed anew: losses are not violations
    assert sum(p["lost"] for p in report.lost) == report.lost_crossings > 0
    courses = {tuple(sorted((p["loops"][0][0], p["loops"][1][0]))) for p in report.lost}
    c = moved
    assert courses <= {(c - 1, c), (c, c + 1), (c - 2, c), (c, c + 2)}
    assert (c - 1, c) in courses and (c, c + 1) in courses
    for p in report.lost:
        wales = {p["loops"][0][1], p["loops"][1][1]}
        courses_of = {p["loops"][0][0], p["loops"][1][0]}
        assert p["edge"] == bool(wales & {1, 5} or courses_of & {1, 5})
        assert p["count"] == 0 and p["lost"] == p["natural"] > 0
    inside = sum(not p["edge"] for p in report.lost)
    assert inside > 0 and f"{inside} of them inside the fabric" in report.line()
