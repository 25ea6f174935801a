"""The 3-D model's own load steps (``solve.model_steps``): MODEL_CONTINUATION's three, more
where a held point would move further than 1.2 natural lattice spacings (the smaller) in a
step. The bug it catches: a large 3-D pull (the 30 x 30 bench pull, a corner moved (15, 15)
mm) taken in three steps of 7.1 mm, in which IPOPT ran for minutes towards objective 1e15 N mm
without converging."""
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.solving.solve import MODEL_CONTINUATION, model_steps
from knit_nlp.weft.solving.starts import largest_move

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
from bench_weft3d import document  # noqa: E402


def _pull(n: int, pull: float, rigid: bool = False):
    doc = document(n, False, pull)
    if rigid:          # the top course's every start turned by 0.1 and moved by (pull n, 0)
        doc["clamp"] = [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]}]
        doc["rigid_clamp"] = [{"course": n, "point": "start", "translation": [pull * n, 0.0],
                               "rotation": 0.1}]
    pr = parse_problem(doc, f"steps_{n}.toml")
    return pr, WeftParams.natural(pr).vector(), WeftParams.of(pr).vector()


def test_the_largest_move_is_the_pulled_point_s_distance() -> None:
    pr, p0, p1 = _pull(10, 0.5)
    assert largest_move(pr, p0, p1) == pytest.approx(np.hypot(5.0, 5.0), rel=1e-12)
    assert largest_move(pr, p0, p0) == 0.0
    assert largest_move(pr, p0, p0 + 0.5 * (p1 - p0)) == pytest.approx(np.hypot(2.5, 2.5))


def test_a_rigid_clamp_s_points_count() -> None:
    pr, p0, p1 = _pull(6, 0.5, rigid=True)
    assert pr.rigid_clamps
    starts = pr.natural_starts()[-1]                      # the top course's (n, 2)
    centre = starts.mean(axis=0)
    turn = np.array([[np.cos(0.1), -np.sin(0.1)], [np.sin(0.1), np.cos(0.1)]])
    moved = centre + (starts - centre) @ turn.T + [3.0, 0.0]
    assert largest_move(pr, p0, p1) == pytest.approx(np.max(np.hypot(*(moved - starts).T)),
                                                     rel=1e-12)


@pytest.mark.parametrize(("n", "expected"), [(6, 3), (10, 3), (12, 4), (30, 9)])
def test_three_steps_or_one_lattice_spacing_a_step(n: int, expected: int) -> None:
    pr, _, p1 = _pull(n, 0.5)
    spatial = SimpleNamespace(model="full3d", problem=pr,
                              shape=SimpleNamespace(wale_spacing=2.97, course_spacing=2.0))
    assert model_steps(spatial, p1) == expected     # ceil(0.5 n √2 / (1.2 · 2.0)), at least 3
    planar = SimpleNamespace(model="full", problem=pr)
    assert model_steps(planar, p1) == MODEL_CONTINUATION.get("full")


def test_a_coordinate_the_clamp_does_not_hold_does_not_count() -> None:
    doc = document(6, False, 0.5)
    doc["clamp"][1].update(displacement=[3.0, 4.0], fix=["x"])     # y free: only x moves
    pr = parse_problem(doc, "steps_fix.toml")
    p0, p1 = WeftParams.natural(pr).vector(), WeftParams.of(pr).vector()
    assert largest_move(pr, p0, p1) == pytest.approx(3.0, rel=1e-12)
