"""What the answer's own check was made cheaper with (issue 41, docs/measurements.md, "The own
check's cost") still finds what the plain ways find: the crossing count's segments read from
the course samples without a copy against every segment pair intersected, the course samples
written loop block by loop block against one block, the per-pair counts against a plain count
(the natural interlocks' k-d tree candidates: tests/test_contact_natural_crossings.py)."""
from __future__ import annotations

import subprocess
import sys
from collections import Counter

import numpy as np
import pytest

from knit_nlp.weft.model.cases import unclamped
from knit_nlp.weft.model.contact import near, pairs
from knit_nlp.weft.model.contact.crossings import Crossings, find_crossings, segments_crossing
from knit_nlp.weft.model.contact.curves import Curves
from knit_nlp.weft.model.contact.pairs import Grid, course_samples
from knit_nlp.weft.model.problem import parse_problem

L = 10.0


def _shifted(d: float) -> tuple[Curves, Grid]:
    """A 3 x 3 natural jersey with its middle course moved by d along x (d = 4: crossings
    that the natural fabric has and new ones, tests/test_contact_zones.py)."""
    pr = parse_problem(unclamped(3, 3), "shifted")
    starts = np.array(pr.natural_starts(), dtype=float)
    starts[1, :, 0] += d
    return Curves.of(np.broadcast_to(pr.natural.coeffs, (3, 3, 8)), starts, L), Grid(3, 3, L, 200)


@pytest.mark.parametrize("shift", [0.0, 1.0, 4.0])
def test_the_crossing_count_finds_what_every_segment_pair_intersected_finds(shift):
    """find_crossings (segment starts read as rows u + u // (K − 1) of the course samples)
    against all 1.6 million pairs of the 1800 segments, starts copied out course by course,
    on the jersey as knitted (24 crossings), its middle course moved 1 (10, slid) and 4 (8,
    new): the same crossings, on the same loops at the same material points and places."""
    curves, grid = _shifted(shift)
    found = find_crossings(curves, grid)
    pts = course_samples(curves, grid)
    m, K = pts.shape[:2]
    p0 = pts[:, :-1].reshape(-1, 2)
    d = (pts[:, 1:] - pts[:, :-1]).reshape(-1, 2)
    u, v = np.triu_indices(len(d), 1)
    one = (v - u == 1) & (v % (K - 1) != 0)            # neighbours along a course
    u, v, tu, tv = segments_crossing(p0, d, u[~one], v[~one])
    cu, iu = np.divmod(u, K - 1)
    cv, iv = np.divmod(v, K - 1)
    kA, sA = grid.loop_of(cu, grid.S[iu] + tu * grid.h)
    kB, sB = grid.loop_of(cv, grid.S[iv] + tv * grid.h)
    swap = (kA > kB) | ((kA == kB) & (sA > sB))
    brute = sorted(zip(np.where(swap, kB, kA).tolist(), np.where(swap, sB, sA).tolist(),
                       np.where(swap, kA, kB).tolist(), np.where(swap, sA, sB).tolist()))
    got = sorted(zip(found.kA.tolist(), found.sA.tolist(), found.kB.tolist(),
                     found.sB.tolist()))
    assert len(brute) >= 8 and len({k for k, *_ in brute}) >= 2
    assert got == brute
    xy = p0[u] + tu[:, None] * d[u]
    assert sorted(map(tuple, found.xy.tolist())) == sorted(map(tuple, xy.tolist()))


@pytest.mark.parametrize("loops_per_block", [1, 2, 4, 5])
def test_the_course_samples_put_every_loop_block_in_its_course(monkeypatch, loops_per_block):
    """Blocks of 1, 2, 4 or 5 loops on 3 courses of 3 (blocks that end inside a course, at its
    end, or run into the next one) give the samples of one block of all 9 loops: each loop's
    first sample its start, each course's last sample its last loop's end."""
    curves, grid = _shifted(4.0)
    p, G = grid.per_loop, pairs.INTERVAL_NODES
    pairs._SAMPLED.clear()
    whole = course_samples(curves, grid).copy()
    monkeypatch.setattr(pairs, "ROWS", loops_per_block * p * G)
    pairs._SAMPLED.clear()
    blocks = course_samples(curves, grid)
    pairs._SAMPLED.clear()
    np.testing.assert_allclose(blocks, whole, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(blocks[:, :-1:p], curves.starts.reshape(3, 3, 2))
    ends = curves.points(np.array([2, 5, 8]), np.full(3, L))
    np.testing.assert_allclose(blocks[:, -1], ends, rtol=0, atol=1e-9)


def test_the_pair_counts_are_the_crossings_of_each_pair_of_loops():
    """Crossings.pair_counts (the judge's arrays) and counts (the report's dict) against a
    plain count of 500 random crossings on 40 loops."""
    rng = np.random.default_rng(11)
    ka, kb = rng.integers(0, 40, 500), rng.integers(0, 40, 500)
    ka, kb = np.minimum(ka, kb), np.maximum(ka, kb)
    z = np.zeros(500)
    found = Crossings(ka, z, kb, z, np.zeros((500, 2)))
    plain = Counter(zip(ka.tolist(), kb.tolist()))
    a, b, n = found.pair_counts()
    assert dict(zip(zip(a.tolist(), b.tolist()), n.tolist())) == plain == found.counts()
    assert list(zip(a.tolist(), b.tolist())) == sorted(plain)
    assert Crossings(z[:0].astype(int), z[:0], z[:0].astype(int), z[:0],
                     np.zeros((0, 2))).counts() == {}


def test_a_course_end_crossing_the_next_course_start_is_counted():
    """Course 1 straight along x from the origin; course 2 straight up from (9.99, −0.01), its
    first segment through course 1's last: one crossing, though the two segments are numbered
    one after the other (they are neighbours only within a course)."""
    coeffs = np.zeros((2, 1, 8))
    coeffs[1, 0, 7] = np.pi / 2
    curves = Curves.of(coeffs, np.array([[[0.0, 0.0]], [[9.99, -0.01]]]), L)
    found = find_crossings(curves, Grid(2, 1, L, 200))
    assert (found.kA.tolist(), found.kB.tolist()) == ([0], [1])
    assert found.sA[0] == pytest.approx(9.99) and found.sB[0] == pytest.approx(0.01)


def _cell_pairs(points: np.ndarray, radius: float, rows: int) -> np.ndarray:
    """All of near.cell_pairs' pairs, each chunk checked to hold at most ``rows`` pairs or
    the pairs of a single point."""
    chunks = list(near.cell_pairs(points, radius, rows))
    for c in chunks:
        assert len(c) <= rows or any(np.all(np.any(c == p, axis=1)) for p in c[0])
    return np.concatenate(chunks) if chunks else np.zeros((0, 2), dtype=np.int64)


def _points(kind: str) -> tuple[np.ndarray, float]:
    """Points and a radius: uniform, on a lattice of exactly the radius, pairs exactly the
    radius apart whose first point lies just below a cell's edge (two cells apart in cells
    any narrower), clumped (many points in one cell: chunks of one point's pairs), a column
    of points a radius apart over the rows whose cell numbers pass 2^31, a wide sparse cloud
    and one too fine for 64-bit cell numbers (the k-d tree instead)."""
    rng = np.random.default_rng(5)
    if kind == "uniform":
        return rng.random((3000, 2)) * 3.0, 0.05
    if kind == "lattice":
        i, j = np.mgrid[0:40, 0:40]
        return np.stack([i.ravel(), j.ravel()], axis=1) * 0.25 + 1.0, 0.25
    if kind == "edges":
        k = np.arange(1.0, 61.0)
        a = np.stack([k * 0.25 * (1 - 2e-6), 3.0 * k], axis=1)
        return np.concatenate([[[0.0, 0.0]], a, a + [0.25, 0.0]]), 0.25
    if kind == "rows":
        column = np.stack([np.full(2000, 0.5), np.arange(42000, 44000) + 0.5], axis=1)
        return np.concatenate([[[0.0, 0.0], [5e4, 0.0]], column]), 1.0
    if kind == "clumped":
        return np.concatenate([rng.random((400, 2)) * 0.01, rng.random((600, 2))]), 0.02
    if kind == "wide":
        far = rng.random((500, 2)) * 1e6
        return np.concatenate([far, far[:100] + rng.normal(0, 0.3, (100, 2))]), 1.0
    far = rng.random((300, 2)) * 1e12
    return np.concatenate([far, far[:50]]), 1e-9


@pytest.mark.parametrize("kind", ["uniform", "lattice", "edges", "clumped", "rows", "wide",
                                  "too_fine"])
def test_the_cell_list_holds_every_pair_of_the_tree_once(kind):
    """near.cell_pairs against the k-d tree's query_pairs (every pair within the radius), in
    chunks of at most 500 pairs (or one point's): on the points of :func:`_points` (a cloud
    10^6 radii wide, one 10^21 wide): every tree pair is there, each pair once with u < v,
    and none further than two cells' diagonal."""
    pts, radius = _points(kind)
    got = _cell_pairs(pts, radius, 500)
    n = len(pts)
    keys = got[:, 0] * n + got[:, 1]
    assert np.all(got[:, 0] < got[:, 1]) and len(np.unique(keys)) == len(keys)
    tree = near.tree_of(pts).query_pairs(radius, output_type="ndarray")
    assert len(tree) >= 40
    assert np.isin(tree[:, 0] * n + tree[:, 1], keys).all()
    gap = np.hypot(*(pts[got[:, 0]] - pts[got[:, 1]]).T)
    assert gap.max() <= 2 * np.sqrt(2) * radius * (1 + 2 * near.WIDER)


def _folded(seed: int) -> tuple[Curves, Grid]:
    """A 3 x 4 fabric of random loops (coefficients of sd 1.5 on the natural jersey's):
    folded, crossing itself everywhere."""
    pr = parse_problem(unclamped(3, 4), "folded")
    rng = np.random.default_rng(seed)
    coeffs = np.asarray(pr.natural.coeffs) + rng.normal(0.0, 1.5, (3, 4, 8))
    starts = np.array(pr.natural_starts(), dtype=float) + rng.normal(0.0, 2.0, (3, 4, 2))
    return Curves.of(coeffs, starts, L), Grid(3, 4, L, 200)


@pytest.mark.parametrize("state", ["jersey", "slid", "new", "folded 1", "folded 2"])
def test_the_cell_list_counts_the_crossings_the_tree_counts(state):
    """find_crossings by the cell list (ordered=False, the own check's) against the k-d tree's
    (ordered=True, knit-nlp check's): the jersey as knitted, its middle course moved 1 and 4
    (tests above), and two folded fabrics of random loops (hundreds of crossings, many of a
    course with itself): the same crossings, located at the same material points and places."""
    if state.startswith("folded"):
        curves, grid = _folded(int(state[-1]))
    else:
        curves, grid = _shifted({"jersey": 0.0, "slid": 1.0, "new": 4.0}[state])
    tree = find_crossings(curves, grid)
    cells = find_crossings(curves, grid, ordered=False)

    def rows(c):
        return sorted(zip(c.kA.tolist(), c.sA.tolist(), c.kB.tolist(), c.sB.tolist(),
                          map(tuple, c.xy.tolist())))

    assert len(tree) >= 8
    assert rows(cells) == rows(tree)
    assert cells.counts() == tree.counts()


def test_the_own_check_imports_no_scipy_without_slides():
    """The own check (check_state without places) of a 3 x 3 jersey whose middle course moved
    4 (new crossings, no slides to match) imports no SciPy: the crossings and the natural
    interlocks by cell lists, not k-d trees (SciPy's sparse graphs come for slides only)."""
    code = (
        "import sys, numpy as np\n"
        "from knit_nlp.weft.model.cases import unclamped\n"
        "from knit_nlp.weft.model.problem import parse_problem\n"
        "from knit_nlp.weft.output.check import check_state\n"
        "pr = parse_problem(unclamped(3, 3), 'shifted')\n"
        "starts = np.array(pr.natural_starts(), dtype=float)\n"
        "starts[1, :, 0] += 4.0\n"
        "rep = check_state(pr, np.broadcast_to(pr.natural.coeffs, (3, 3, 8)), starts,\n"
        "                  places=False)\n"
        "print(rep.n_new, any(m.startswith('scipy') for m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert int(out[0]) > 0
    assert out[1] == "False"
