"""The 3-D model's independent check over all pairs of yarn pieces (model/spatial/proximity.py,
docs/weft3d.md "Check"): exact segment distances, a natural fabric called clean, loops moved
into each other and a course mirrored through the fabric found."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.model.spatial.proximity import check_3d, segment_distance
from knit_nlp.weft.model.spatial.state import spatial_natural

# a thin yarn (docs/weft3d.md: r = 0.15, L = 10) whose natural 3-D fabric keeps every pair of
# pieces that are not one piece at least 2r apart
THIN = {"name": "thin3d", "fabric": {"courses": 3, "wales": 3},
        "loop": {"length": 10.0, "harmonics": 3}, "material": {"R_f": 1.0},
        "yarn": {"radius": 0.15, "geometry": "3d", "elevation_modes": 4},
        "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]}]}
S = 121


@pytest.fixture(scope="module")
def thin():
    pr = parse_problem(THIN, "thin3d.toml")
    natural = spatial_natural(pr, S)                    # 2 x 3 loops
    three = np.concatenate([natural, natural[1:] + [0.0, pr.natural.course_spacing, 0.0]])
    return pr, three


def _check(pr, lines):
    return check_3d(lines, spatial_natural(pr, S), pr.L, pr.yarn.radius, pr.yarn.core_radius)


coord = st.floats(-2.0, 2.0, allow_nan=False)
point = st.tuples(coord, coord, coord).map(np.array)


@settings(max_examples=200, deadline=None)
@given(point, point, point, point, st.booleans())
def test_segment_distance_is_the_exact_minimum(p0, p1, q0, q1, parallel) -> None:
    """Against brute force on 401 x 401 points of the two segments: never above it, and below
    it by at most the grid's reach (half a spacing on each segment); parallel and degenerate
    segments included."""
    if parallel:
        q1 = q0 + 0.7 * (p1 - p0)
    d, a, b = segment_distance(p0[None], (p1 - p0)[None], q0[None], (q1 - q0)[None])
    t = np.linspace(0.0, 1.0, 401)
    P, Q = p0 + t[:, None] * (p1 - p0), q0 + t[:, None] * (q1 - q0)
    brute = np.sqrt(((P[:, None] - Q[None]) ** 2).sum(-1)).min()
    slack = (np.linalg.norm(p1 - p0) + np.linalg.norm(q1 - q0)) / 800
    assert brute - slack - 1e-12 <= d[0] <= brute + 1e-12
    # the parameters are a pair of points at that distance
    gap = p0 + a[0] * (p1 - p0) - q0 - b[0] * (q1 - q0)
    assert np.linalg.norm(gap) == pytest.approx(d[0], abs=1e-12)
    assert 0.0 <= a[0] <= 1.0 and 0.0 <= b[0] <= 1.0


def test_a_natural_fabric_is_clean(thin) -> None:
    """Every designed crossing found in its plain-knit order, touching (2r, to the polyline's
    sag), no pair inside the core, and pieces of one yarn not judged against each other."""
    pr, lines = thin
    rep = _check(pr, lines)
    assert rep.ok and rep.n_inside_core == 0 and not rep.flipped and rep.lost == 0
    assert rep.n_designed == 4 * 2 * 3
    assert rep.smallest == pytest.approx(2 * pr.yarn.radius, rel=2e-3)
    assert rep.smallest_where["designed"]


def test_loops_moved_into_each_other_are_found(thin) -> None:
    """Loop (3, 2) moved down by one course spacing lies on loop (2, 2): inside the core."""
    pr, lines = thin
    moved = lines.copy()
    moved[2, 1] -= [0.0, pr.natural.course_spacing, 0.0]
    rep = _check(pr, moved)
    assert not rep.ok and rep.smallest < 1e-9
    assert [[2, 2], [3, 2]] in [e["loops"] for e in rep.inside_core]
    assert "NOT CLEAN" in rep.verdict()


def test_a_mirrored_fabric_flips_every_crossing_and_a_mirrored_course_its_own(thin) -> None:
    """The whole fabric's z mirrored (face and back swapped): every designed crossing's order
    is the reverse of plain knit's, read from the geometry. Course 2 alone mirrored (its yarn
    passed through the others): crossings flip, each one of course 2's."""
    pr, lines = thin
    rep = _check(pr, lines * [1.0, 1.0, -1.0])
    assert len(rep.flipped) == rep.n_designed == 24 and not rep.ok
    mirrored = lines.copy()
    mirrored[1, :, :, 2] *= -1.0
    rep = _check(pr, mirrored)
    assert rep.flipped and not rep.ok
    assert all(2 in (f["upper"][0], f["lower"][0]) for f in rep.flipped)
