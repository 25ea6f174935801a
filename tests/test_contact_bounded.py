"""Bounded memory in the crossing count and the pair search (issue 41, item 4): the course
samples by one matrix product follow the cell rule; neighbour searches come in slices of a
bounded number of rows and lose or repeat no pair; check refuses, in one line, a gap search it
could not finish."""
from __future__ import annotations

import numpy as np
import pytest

from knit_nlp.errors import ProblemError
from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.model.contact import near
from knit_nlp.weft.model.contact.curves import Curves
from knit_nlp.weft.model.contact.pairs import Grid, course_samples
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.output import check as checker


def _perturbed(m: int, n: int, seed: int = 3) -> tuple[Curves, float]:
    """Jersey loops with random coefficients of every harmonic (sd 0.3), each course's loops
    following each other (check.loops_of: each loop starts where the last one ends)."""
    pr = parse_problem(diagonal_pull(n, m), "pull")
    rng = np.random.default_rng(seed)
    coeffs = pr.natural.coeffs + 0.3 * rng.standard_normal((m, n, pr.natural.coeffs.size))
    result = {"loops": {"coefficients": coeffs.tolist(),
                        "course_starts": pr.natural_starts()[:, 0].tolist()}}
    return Curves.of(*checker.loops_of(result, pr), pr.L), pr.L


@pytest.mark.parametrize("per_loop", [16, 67, 200])
def test_course_samples_by_one_matrix_product_follow_the_cell_rule(per_loop):
    """Every sample against Curves.points (the contact rows' cell rule, 1.6e-8 from adaptive
    quadrature) at the same course arc."""
    curves, L = _perturbed(3, 4)
    grid = Grid(3, 4, L, per_loop)
    S = grid.S
    c = np.repeat(np.arange(3), S.size).reshape(3, S.size)
    k, s = grid.loop_of(c, np.broadcast_to(S, c.shape))
    np.testing.assert_allclose(course_samples(curves, grid), curves.points(k, s), rtol=0,
                               atol=1e-9 * L)


def _cloud(seed: int = 1) -> np.ndarray:
    """Points spread over a square with a dense cluster (a pile of crossed yarns)."""
    rng = np.random.default_rng(seed)
    return np.concatenate([rng.uniform(0, 10, (3000, 2)), rng.normal(5, 0.05, (400, 2))])


def test_neighbour_slices_hold_every_pair_once_and_a_bounded_number_at_a_time():
    pts = _cloud()
    tree = near.tree_of(pts)
    whole = tree.sparse_distance_matrix(tree, 0.3, output_type="ndarray")
    expected = set(zip(whole["i"].tolist(), whole["j"].tolist()))
    rows, got, sizes = 2000, [], []
    for i, j in near.neighbours(tree, 0.3, rows, 10 ** 6):
        sizes.append(len(i))
        got += list(zip(i.tolist(), j.tolist()))
    assert len(got) == len(set(got)) and set(got) == expected
    assert len(expected) > 20 * rows and len(sizes) > 10
    assert max(sizes) < 3 * rows                 # an estimate: within a small factor


@pytest.mark.parametrize("at_once", [0, near.AT_ONCE])
def test_close_pairs_by_slices_or_at_once_are_the_tree_s_pairs(monkeypatch, at_once):
    pts = _cloud(2)
    monkeypatch.setattr(near, "AT_ONCE", at_once)
    got = np.concatenate(list(near.close_pairs(pts, 0.2, 1000)))
    assert np.all(got[:, 0] < got[:, 1])
    expected = near.tree_of(pts).query_pairs(0.2)
    assert len(got) == len(expected) and set(map(tuple, got.tolist())) == expected


def test_check_refuses_in_one_line_a_gap_search_it_could_not_finish(monkeypatch):
    pr = parse_problem({**diagonal_pull(3), "yarn": {"radius": 0.15}}, "pull.toml")
    result = {"loops": {"coefficients": np.broadcast_to(pr.natural.coeffs, (3, 3, 8)).tolist(),
                        "course_starts": pr.natural_starts()[:, 0].tolist()}}
    assert checker.check(result, pr).ok
    monkeypatch.setattr(checker, "CHECK_ROWS", 1e3)
    with pytest.raises(ProblemError, match=r"\[yarn\] radius: r = 0.15 .* needs an estimated"
                       ) as err:
        checker.check(result, pr, where="r.json")
    assert "\n" not in str(err.value) and str(err.value).startswith("r.json")


def test_the_solver_s_coarse_grid_and_check_count_the_same_crossings():
    """A designed crossing is one thing to the solver and to check: the count is made on 200
    segments per loop whatever the grid (the solver's is about one sample per radius, 16 per
    loop at r = 0.656, where a crossed 6 x 6 stretch was judged clean). On uneven loops the
    count from a 16-sample grid is the 200-sample count and the converged one (2000)."""
    from knit_nlp.weft.model.contact.crossings import find_crossings
    curves, L = _perturbed(4, 4, 3)
    coarse, fine = (find_crossings(curves, Grid(4, 4, L, p)) for p in (16, 2000))
    assert coarse.counts() == find_crossings(curves, Grid(4, 4, L, 200)).counts()
    assert coarse.counts() == fine.counts() and len(fine) == 32
