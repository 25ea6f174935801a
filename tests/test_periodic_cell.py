"""The 3-D model's periodic cell (``knit_nlp.weft.model.spatial.periodic``, and
``scripts/periodic_cell.py``'s side of the metric; docs/real_fabric.md, "A periodic cell"): the natural cell carries no force, the force through a cell is the energy's derivative
along the pull (the envelope theorem, against differences of the energy), a pull contracts the
cell across it and leaves the yarns apart, and a straight bending reference relaxes to a
prestressed cell at zero force."""
import sys
from pathlib import Path

import numpy as np
import pytest

from knit_nlp.tomlio import load_toml
from knit_nlp.weft.model.spatial import periodic as pc
from knit_nlp.weft.model.problem import parse_problem

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import periodic_cell as script  # noqa: E402


@pytest.fixture(scope="module")
def yarn():
    spec = load_toml(ROOT / "problems" / "real_fabric" / "acrylic_3d_source.toml")
    doc = {k: spec[k] for k in ("loop", "material", "yarn", "units")}
    doc["fabric"] = {"courses": 2, "wales": 2}
    pr = parse_problem(doc, "acrylic_3d_source.toml")
    return pr.yarn.natural3d, pr.yarn.shell()


R_F = 0.045                                  # N mm² (acrylic_3d_source)


@pytest.fixture(scope="module")
def course_cell(yarn):
    return pc.build_cell(*yarn, "courses", samples=48)


def _lattice(cell) -> np.ndarray:
    return np.array([cell.shape.wale_spacing, cell.shape.course_spacing])


def test_the_natural_cell_carries_no_force(course_cell) -> None:
    rest = pc.solve_cell(course_cell, course_cell.spacing0, R_F,
                         pc.natural_state(course_cell.shape))
    assert rest.success
    pulled = pc.solve_cell(course_cell, 1.1 * course_cell.spacing0, R_F, rest.x)
    # measured 9.9e-6 against 9.9e-3 N on one machine, 5.7e-5 on another (IPOPT's path from
    # the natural state differs in rounding; the cell's equilibria are not unique)
    assert abs(rest.F) < 1e-2 * pulled.F
    assert abs(rest.U) < 1e-6                            # N mm; 2.4e-8
    # 8e-6 mm on one machine, 5e-4 mm on another (the same drift as the force above)
    np.testing.assert_allclose(rest.x[-2:], _lattice(course_cell), atol=3e-3)


def test_the_force_through_a_cell_is_the_energy_s_derivative(course_cell) -> None:
    s0 = course_cell.spacing0
    x = pc.solve_cell(course_cell, 1.1 * s0, R_F, pc.natural_state(course_cell.shape)).x
    h = 0.002
    at = {e: pc.solve_cell(course_cell, (1 + e) * s0, R_F, x) for e in (0.1 - h, 0.1, 0.1 + h)}
    assert all(r.success for r in at.values())
    dU = (at[0.1 + h].U - at[0.1 - h].U) / (2 * h * s0)
    assert at[0.1].F == pytest.approx(dU, rel=1e-3)
    assert at[0.1].F > 0                                  # a pull pulls


def test_the_energy_is_linear_in_R_f_and_in_k_and_k_is_the_built_law_s(yarn, course_cell) -> None:
    """U = R_f·B + (k/k₀)·C (S4, S7, R1: the contact laws are linear in k): at a fixed state,
    equal steps in R_f, and in k, change U by equal amounts; at k = k₀, the built law's, the
    parameter changes nothing; bending and contacts both store energy in a pull."""
    x = pc.solve_cell(course_cell, 1.1 * course_cell.spacing0, R_F,
                      pc.natural_state(course_cell.shape)).x
    k0 = yarn[1].rigidity
    assert course_cell.rigidity == k0

    def U(R_f, k):
        return float(course_cell.energy(x, [0.0, R_f, k]))
    assert U(2 * R_F, k0) - U(R_F, k0) == pytest.approx(U(R_F, k0) - U(0.0, k0), rel=1e-12)
    assert U(R_F, 2 * k0) - U(R_F, k0) == pytest.approx(U(R_F, k0) - U(R_F, 0.0), rel=1e-12)
    assert U(R_F, k0) - U(0.0, k0) > 0 and U(R_F, k0) - U(R_F, 0.0) > 0


def test_a_pull_contracts_the_cell_across_it_and_keeps_the_yarns_apart(course_cell) -> None:
    nodes = script.pull(course_cell, R_F, np.array([0.05, 0.1]),
                        pc.natural_state(course_cell.shape), say=lambda line: None)
    assert [n["strain"] for n in nodes] == [0.05, 0.1]
    assert nodes[0]["lateral"] < 0 and nodes[1]["lateral"] < nodes[0]["lateral"]
    assert all(n["clean"] for n in nodes)
    assert nodes[1]["F"] > nodes[0]["F"] > 0


def test_holding_the_width_keeps_it_and_stores_more_energy_than_leaving_it_free(course_cell
                                                                               ) -> None:
    """``held`` (plane strain) fixes the spacing across the pull at its natural value; the
    free cell (uniaxial stress) minimises the same energy over more states, so at each strain
    it stores no more and, contracting, carries less force."""
    s0, x = course_cell.spacing0, pc.natural_state(course_cell.shape)
    for e in (0.05, 0.1):
        held = pc.solve_cell(course_cell, (1 + e) * s0, R_F, x, held=True)
        free = pc.solve_cell(course_cell, (1 + e) * s0, R_F, x)
        assert held.success and free.success
        assert course_cell.across(held.x) == course_cell.across0
        assert course_cell.across(free.x) < course_cell.across0
        assert held.U > free.U and held.F > free.F > 0
        x = held.x


def test_a_contact_s_normal_force_is_its_energy_s_derivative_along_the_separation(
        course_cell) -> None:
    """``contact_state`` (and through ``crossing_contact.normal_force`` the 3-D model's
    crossings): N = a·F(h′) = −dE/dh with E = E(h′(h), α) (C1-C3), against central differences
    of the energy; no force at the natural loop, where the wraps just touch; linear in k."""
    from knit_nlp.weft.model.spatial.crossing_contact import separation
    cell, law = course_cell, course_cell.law
    nat = pc.contact_state(cell, pc.natural_state(cell.shape))
    np.testing.assert_allclose(nat.sigma_upper, cell.shape.s_upper)
    x = pc.solve_cell(cell, 1.2 * cell.spacing0, R_F, pc.natural_state(cell.shape)).x
    state = pc.contact_state(cell, x)
    assert np.all(state.normal > 0)                       # pulled 20 %: the wraps press
    assert np.all(nat.normal < 1e-3 * state.normal.min())  # measured 1.2e-6 against N
    cp = np.asarray(cell.closest(x))
    h, sin_a = separation(cp[0:3].T, cp[3:6].T, cp[6:9].T, cp[9:12].T,
                          cell.shape.crossing_signs())
    a, d = law.thinning(cell.shape.h0), 1e-6

    def E(hh):
        return law.crossing_energy(law.seen(hh, a), sin_a)
    np.testing.assert_allclose(state.normal, -(E(h + d) - E(h - d)) / (2 * d), rtol=1e-5)
    np.testing.assert_allclose(pc.contact_state(cell, x, 2 * law.rigidity).normal,
                               2 * state.normal, rtol=1e-12)


def test_the_cell_s_energy_is_its_bending_its_wraps_and_its_other_pairs_read_back(
        course_cell) -> None:
    """What the friction estimate reads (``contact_state``, ``pair_state``) is the cell's own
    energy (S4, S7, R1): at a pulled state, the bending (U at k = 0) plus the wraps' energy
    (C1 at their separations) plus the other pairs' sum to U; each pair's push is minus its
    energy's derivative along the distance (central differences)."""
    from knit_nlp.weft.model.spatial.crossing_contact import separation
    cell, law = course_cell, course_cell.law
    x = pc.solve_cell(cell, 1.2 * cell.spacing0, R_F, pc.natural_state(cell.shape)).x
    r, E, N = pc.pair_state(cell, x)
    cp = np.asarray(cell.closest(x))
    h, sin_a = separation(cp[0:3].T, cp[3:6].T, cp[6:9].T, cp[9:12].T,
                          cell.shape.crossing_signs())
    wraps = float(np.sum(law.crossing_energy(law.seen(h, law.thinning(cell.shape.h0)), sin_a)))
    bending = float(cell.energy(x, [0.0, R_F, 0.0]))
    assert np.sum(E) > 0.1 * wraps > 0 and np.sum(N > 0) > 10          # the pull presses both
    assert bending + wraps + np.sum(E) == pytest.approx(
        float(cell.energy(x, [0.0, R_F, law.rigidity])), rel=1e-10)
    E2 = pc.pair_state(cell, x, 2 * law.rigidity)[1]                  # at twice the rigidity
    assert bending + 2 * wraps + np.sum(E2) == pytest.approx(
        float(cell.energy(x, [0.0, R_F, 2 * law.rigidity])), rel=1e-10)
    d, step = np.linalg.norm(r, axis=0), 1e-7
    weight = (cell.shape.length / cell.samples) ** 2

    def energy(dd):
        with np.errstate(all="ignore"):
            return weight * law.energy(law.seen(dd, cell.pair_scales))
    on = N > 0
    # atol: the differences' truncation error at a pair just touching (a push of 2e-10 N
    # differed by 1.2e-5 of itself, 2.4e-15 N, on one machine)
    np.testing.assert_allclose(N[on], -(energy(d + step) - energy(d - step))[on] / (2 * step),
                               rtol=1e-5, atol=1e-9 * N.max())


def test_a_straight_bending_reference_relaxes_to_a_prestressed_cell(yarn) -> None:
    cell = pc.build_cell(*yarn, "courses", samples=48, straight=True)
    rest = pc.solve_cell(cell, cell.spacing0, R_F, pc.natural_state(cell.shape), free=True)
    assert rest.success
    assert rest.U > 0.1                                   # N mm: bent loops store energy
    assert not np.allclose(rest.x[-2:], _lattice(cell), atol=0.01)   # it moved (c: 0.027 mm)
    held = pc.solve_cell(cell, rest.x[-2], R_F, rest.x)   # the pulled spacing held there
    pulled = pc.solve_cell(cell, 1.1 * rest.x[-2], R_F, rest.x)
    assert held.success and pulled.success
    assert abs(held.F) < 1e-3 * pulled.F                  # relaxed: no force at its own spacing


def test_the_cell_s_side_of_the_metric_reads_its_curve_where_it_first_reaches_each_force() -> None:
    e = np.array([0.0, 0.1, 0.2, 0.3])
    F = np.array([0.0, 2.0, 1.5, 6.0])            # not monotone: the first crossing counts
    got = script.at_forces(e, F, e, (1.0, 2.0, 4.0, 7.0))
    np.testing.assert_allclose(got[:3], [0.05, 0.1, 0.2 + 0.1 * 2.5 / 4.5], rtol=1e-12)
    assert np.isnan(got[3])                       # never reached: no strain, no RMS
