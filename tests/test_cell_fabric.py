"""The clamped specimen of periodic cells (``model.spatial.cell_fabric``; docs/real_fabric.md,
"The clamped specimen of cells"): its lattice rule in closed form, its limit with every node
held (the held uniaxial cell), and its force as the energy's derivative along the travel."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from knit_nlp.tomlio import load_toml
from knit_nlp.weft.model.compression import SoftShell
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.model.spatial.cell_fabric import (build_cell_fabric, cell_lattice, displaced,
                                                     lattice_vectors, solve_cell_fabric,
                                                     specimen_mesh)
from knit_nlp.weft.model.spatial.periodic import build_cell, natural_state, relaxed, solve_cell

from conftest import PROBLEMS

SAMPLES, REACH, K, R_F = 16, 1.3, 0.00465, 0.045


def _lattice(F: np.ndarray, direction: str, w0: float = 3.0, c0: float = 2.0) -> np.ndarray:
    A1, A2 = lattice_vectors(direction, w0, c0)
    return np.array([float(v) for v in cell_lattice(ca.DM(F), A1, A2)])


def test_the_lattice_follows_the_deformation_gradient() -> None:
    """(E2, E3) in closed form: unmoved, the reference lattice; a stretch along the pull
    stretches the wale spacing (wales) or the course spacing (courses); a simple shear of
    the wale specimen shifts the course above by γ·c₀; a rigid rotation changes nothing."""
    assert np.allclose(_lattice(np.eye(2), "wales"), [3.0, 2.0, 0.0])
    assert np.allclose(_lattice(np.eye(2), "courses"), [3.0, 2.0, 0.0])
    stretch = np.diag([0.9, 1.2])                         # narrowed across, pulled along
    assert np.allclose(_lattice(stretch, "wales"), [3.0 * 0.9, 2.0 * 1.2, 0.0])
    assert np.allclose(_lattice(stretch, "courses"), [3.0 * 1.2, 2.0 * 0.9, 0.0])
    assert np.allclose(_lattice(np.array([[1.0, 0.1], [0.0, 1.0]]), "wales"), [3.0, 2.0, 0.2])
    a = 0.7
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    F = np.array([[1.1, 0.2], [-0.05, 0.95]])
    for direction in ("wales", "courses"):
        assert np.allclose(_lattice(R @ F, direction), _lattice(F, direction), atol=1e-13)


def test_the_mesh_covers_its_rectangle_counter_clockwise() -> None:
    m = specimen_mesh(10.0, 4.0, 4, 3)
    assert len(m.triangles) == 24 and np.all(m.areas() > 0)
    assert np.isclose(m.areas().sum(), 40.0)
    mirrored = np.sort(np.round(np.column_stack([10.0 - m.nodes[m.triangles][..., 0].mean(1),
                                                 m.nodes[m.triangles][..., 1].mean(1)]), 9),
                       axis=0)
    centroids = np.sort(np.round(m.nodes[m.triangles].mean(1), 9), axis=0)
    assert np.allclose(mirrored, centroids)              # left-right symmetric
    assert m.bottom.tolist() == [0, 1, 2, 3, 4] and m.top[0] == 15
    graded = specimen_mesh(10.0, 7.0, 2, 4, grading=2.0)      # rows 1, 2, 2, 1 (× 7/6)
    assert np.allclose(np.unique(graded.nodes[:, 1]), np.array([0, 1, 3, 5, 6]) * 7 / 6)
    assert np.isclose(graded.areas().sum(), 70.0) and np.all(graded.areas() > 0)


@pytest.fixture(scope="module")
def yarn():
    spec = load_toml(PROBLEMS / "real_fabric" / "acrylic_3d_source.toml")
    doc = {k: spec[k] for k in ("loop", "material", "yarn", "units")}
    doc["fabric"] = {"courses": 2, "wales": 2}
    pr = parse_problem(doc, "acrylic_3d_source.toml")
    law = pr.yarn.shell()
    law = SoftShell(law.radius, law.core_radius, K, law.exponent)
    shape = pr.yarn.natural3d
    cell = build_cell(shape, law, "wales", SAMPLES, straight=True, reach=REACH)
    rest = solve_cell(cell, cell.spacing0, R_F, natural_state(shape), free=True)
    assert rest.success
    return shape, law, rest


@pytest.mark.parametrize("direction", ["wales", "courses"])
def test_a_specimen_held_at_every_node_is_the_held_uniaxial_cell(yarn, direction: str) -> None:
    """One square, every node on a clamp: each cell's lattice is the clamps' (plane strain),
    so each cell's loop at the specimen's answer is an equilibrium of the held uniaxial cell
    (solved from it, the held cell stays), the specimen's energy is its area in cells times
    the held cell's, and its force the held cell's force through one cell times the width
    over the cell's width across. (From the same start the two may reach different minima:
    the cell's equilibria are not unique, ``periodic``.)"""
    shape, law, rest = yarn
    w0, c0 = (float(v) for v in rest.x[-2:])
    W, H, strain = 7.0, 5.0, 0.04
    fab = build_cell_fabric(shape, law, direction, specimen_mesh(W, H, 1, 1), (w0, c0),
                            SAMPLES, straight=True, reach=REACH)
    sol = solve_cell_fabric(fab, strain * H, R_F, K, fab.start(rest.x[:-2]))
    cell = build_cell(shape, law, direction, SAMPLES, straight=True, reach=REACH)
    relaxed(cell, rest.x)
    lattice = [w0, c0 * (1 + strain)] if direction == "wales" else [w0 * (1 + strain), c0]
    for y in fab.cells(sol.z):
        held = solve_cell(cell, (1 + strain) * cell.spacing0, R_F, np.concatenate([y, lattice]),
                          held=True)
        assert sol.success and held.success
        assert np.allclose(held.x[:-2], y, atol=1e-6)
    assert sol.U == pytest.approx(W * H / (w0 * c0) * held.U, rel=1e-7)
    assert sol.F == pytest.approx(held.F * W / cell.across0, rel=1e-5)
    assert held.F > 0.01


def test_the_force_is_the_energy_s_derivative_along_the_travel(yarn) -> None:
    """The envelope theorem on a specimen with free nodes (2 × 2 squares): F = dU/dδ, the
    travel row's multiplier against central differences of the minimum energy; the specimen
    narrows between its free sides."""
    shape, law, rest = yarn
    w0, c0 = (float(v) for v in rest.x[-2:])
    H, h = 6.0, 2e-3
    fab = build_cell_fabric(shape, law, "wales", specimen_mesh(8.0, H, 2, 2), (w0, c0),
                            SAMPLES, straight=True, reach=REACH)
    z = fab.start(rest.x[:-2])
    for travel in (0.02 * H, 0.04 * H):
        mid = solve_cell_fabric(fab, travel, R_F, K, z)
        z = mid.z
    up = solve_cell_fabric(fab, 0.04 * H + h, R_F, K, z)
    down = solve_cell_fabric(fab, 0.04 * H - h, R_F, K, z)
    assert mid.success and up.success and down.success
    assert mid.F == pytest.approx((up.U - down.U) / (2 * h), rel=1e-4)
    assert mid.F > 0
    left, right = displaced(fab, mid.z, np.array([[0.0, H / 2], [8.0, H / 2]]))
    assert right[0] - left[0] < 8.0 - 1e-3
