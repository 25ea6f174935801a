"""The 3-D model's periodic cell (``scripts/periodic_cell.py``; docs/real_fabric.md, "A periodic
cell"): the natural cell carries no force, the force through a cell is the energy's derivative
along the pull (the envelope theorem, against differences of the energy), a pull contracts the
cell across it and leaves the yarns apart, and a straight bending reference relaxes to a
prestressed cell at zero force."""
import sys
from pathlib import Path

import numpy as np
import pytest

from knit_nlp.tomlio import load_toml
from knit_nlp.weft.model.problem import parse_problem

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import periodic_cell as pc  # noqa: E402


@pytest.fixture(scope="module")
def yarn():
    spec = load_toml(ROOT / "problems" / "real_fabric" / "acrylic_3d_source.toml")
    doc = {k: spec[k] for k in ("loop", "material", "yarn", "units")}
    doc["fabric"] = {"courses": 2, "wales": 2}
    pr = parse_problem(doc, "acrylic_3d_source.toml")
    return pr.yarn.natural3d, pr.yarn.shell(), pr.R_f


@pytest.fixture(scope="module")
def course_cell(yarn):
    return pc.build(*yarn, "courses", samples=48)


def test_the_natural_cell_carries_no_force(course_cell) -> None:
    rest = pc.solve(course_cell, course_cell.spacing0, pc.natural_x(course_cell.shape))
    assert rest["success"]
    pulled = pc.solve(course_cell, 1.1 * course_cell.spacing0, rest["x"])
    assert abs(rest["F"]) < 2e-3 * pulled["F"]          # measured 9.9e-6 against 9.9e-3 N
    assert abs(rest["U"]) < 1e-6                         # N mm; 2.4e-8
    np.testing.assert_allclose(rest["x"][-2:], course_cell.x0_lattice, atol=1e-4)   # 8e-6 mm


def test_the_force_through_a_cell_is_the_energy_s_derivative(course_cell) -> None:
    x = pc.solve(course_cell, 1.1 * course_cell.spacing0, pc.natural_x(course_cell.shape))["x"]
    h = 0.002
    at = {e: pc.solve(course_cell, (1 + e) * course_cell.spacing0, x) for e in (0.1 - h, 0.1,
                                                                                  0.1 + h)}
    assert all(r["success"] for r in at.values())
    dU = (at[0.1 + h]["U"] - at[0.1 - h]["U"]) / (2 * h * course_cell.spacing0)
    assert at[0.1]["F"] == pytest.approx(dU, rel=1e-3)
    assert at[0.1]["F"] > 0                               # a pull pulls


def test_a_pull_contracts_the_cell_across_it_and_keeps_the_yarns_apart(course_cell) -> None:
    nodes = pc.pull(course_cell, np.array([0.05, 0.1]), pc.natural_x(course_cell.shape),
                    say=lambda line: None)
    assert [n["strain"] for n in nodes] == [0.05, 0.1]
    assert nodes[0]["lateral"] < 0 and nodes[1]["lateral"] < nodes[0]["lateral"]
    assert all(n["clean"] for n in nodes)
    assert nodes[1]["F"] > nodes[0]["F"] > 0


def test_a_straight_bending_reference_relaxes_to_a_prestressed_cell(yarn) -> None:
    cell = pc.build(*yarn, "courses", samples=48, straight=True)
    rest = pc.solve(cell, cell.spacing0, pc.natural_x(cell.shape), free=True)
    assert rest["success"]
    assert rest["U"] > 0.1                                # N mm: bent loops store energy
    assert not np.allclose(rest["x"][-2:], cell.x0_lattice, atol=0.05)   # it moved
    held = pc.solve(cell, rest["x"][-2], rest["x"])      # the pulled spacing held there
    pulled = pc.solve(cell, 1.1 * rest["x"][-2], rest["x"])
    assert held["success"] and pulled["success"]
    assert abs(held["F"]) < 1e-3 * pulled["F"]            # relaxed: no force at its own spacing


def test_the_cell_s_side_of_the_metric_reads_its_curve_where_it_first_reaches_each_force() -> None:
    e = np.array([0.0, 0.1, 0.2, 0.3])
    F = np.array([0.0, 2.0, 1.5, 6.0])            # not monotone: the first crossing counts
    got = pc.at_forces(e, F, e, (1.0, 2.0, 4.0, 7.0))
    np.testing.assert_allclose(got[:3], [0.05, 0.1, 0.2 + 0.1 * 2.5 / 4.5], rtol=1e-12)
    assert np.isnan(got[3])                       # never reached: no strain, no RMS
