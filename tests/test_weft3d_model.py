"""The 3-D weft NLP (transcription/spatial.py) against the paper's model, finite differences
and the envelope theorem."""
from __future__ import annotations

import copy

import casadi as ca
import numpy as np
import pytest

import knit_nlp
from knit_nlp.weft.model.problem import load_problem, parse_problem
from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.solving.solve import WeftSolver
from knit_nlp.weft.transcription.factory import transcribe
from knit_nlp.weft.transcription.spatial import Spatial, build_spatial
from knit_nlp.problems import resolve
from knit_nlp.weft.model.basis import phi
from knit_nlp.weft.model.spatial.crossing_contact import separation
from knit_nlp.weft.model.spatial.curve3d import bending3d_numpy, positions3d
from knit_nlp.weft.model.spatial.repulsion import sample_s

ACRYLIC_2x2 = {"fabric": {"courses": 2, "wales": 2},
               "loop": {"length": 11.28, "harmonics": 3}, "material": {"R_f": 0.045},
               "yarn": {"radius": 0.74, "geometry": "3d", "elevation_modes": 4},
               "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                         {"loop": [1, 2], "point": "H", "displacement": [0.0, 0.8]}]}


def test_the_papers_limit_is_the_planar_full_model() -> None:
    """φ frozen at 0, crossing contacts off, the paper's springs on: eq. 28 (wada_fig7) solved
    by the 3-D builder gives the planar full model's coefficients and energy to 1e-8."""
    pr = load_problem(resolve("wada_fig7"))
    full = transcribe(pr)
    planar = WeftSolver(full, tol=1e-12, verbose=None).once(full.p0, full.x0)
    sp = build_spatial(pr, Spatial(elevation=False, contacts=False, springs=True))
    spatial = WeftSolver(sp, tol=1e-12, verbose=None).once(sp.p0, sp.x0)
    assert planar.success and spatial.success
    np.testing.assert_allclose(sp.coefficients(spatial.x), full.coefficients(planar.x), atol=1e-8)
    assert spatial.objective == pytest.approx(planar.objective, abs=1e-8)
    assert np.abs(sp.starts3d(spatial.x)[..., 2]).max() == 0.0


@pytest.fixture(scope="module")
def small():
    pr = parse_problem(ACRYLIC_2x2, "small3d.toml")
    return pr, transcribe(pr)


def test_objective_equals_an_independent_evaluation(small) -> None:
    """f at a perturbed consistent state (every lifted block recomputed) equals the bending of
    each loop by numpy quadrature (S4) plus the crossing energy (C1) of the separations
    measured on numpy centrelines at the crossings' material coordinates (S2, S6) plus the
    other contacts' repulsion (R1) of numpy samples."""
    pr, nlp = small
    rng = np.random.default_rng(5)
    A = nlp.coefficients(nlp.x0) + 0.005 * rng.normal(size=nlp.coefficients(nlp.x0).shape)
    B = nlp.elevations(nlp.x0) + 0.005 * rng.normal(size=nlp.elevations(nlp.x0).shape)
    X = nlp.starts3d(nlp.x0) + 0.02 * rng.normal(size=(2, 2, 3))
    sig = nlp.x.get(nlp.x0, "sigma") + 0.05 * rng.normal(size=(2, 4))
    x = nlp.lift3d(A, B, X, sig)
    sh, shell = nlp.shape, pr.yarn.shell()
    bend = sum(bending3d_numpy(A[i, j], B[i, j], sh.coeffs, sh.elevation, pr.L, pr.t, sh.modes,
                               pr.R_f) for i in range(2) for j in range(2))
    contact = 0.0
    core = 2 * shell.core_radius                # (C3) written out: each wrap's law starts at h₀
    scale = np.maximum(1.0, (2 * shell.radius - core) / (sh.h0 - core))
    for c in range(4):                      # wraps of loops (2, j) over (1, j), 2 each
        j = c // 2
        ends = []
        for (i, s) in ((1, sig[0, c]), (0, sig[1, c])):
            pos = X[i, j] + positions3d(A[i, j], B[i, j], [s], pr.L, pr.t, sh.modes)[0]
            th = phi(s, pr.L, pr.t)[0] @ A[i, j]
            el = phi(s, pr.L, sh.modes)[0] @ B[i, j]
            ends.append((pos, np.array([np.cos(el) * np.cos(th), np.cos(el) * np.sin(th), np.sin(el)])))
        h, sin_a = separation(ends[0][0][None], ends[0][1][None], ends[1][0][None],
                              ends[1][1][None], nlp.signs[c:c + 1])
        contact += float(shell.crossing_energy(core + scale[c % 2] * (h - core), sin_a)[0])
    assert contact > 0
    # the other contacts (R1): w² v(d′), d′ of (C3), over the neighbour list, numpy samples
    nb = nlp.neighbours
    s = sample_s(pr.L, nb.samples)
    pts = np.array([X[i, j] + positions3d(A[i, j], B[i, j], s, pr.L, pr.t, sh.modes)
                    for i in range(2) for j in range(2)])
    d = np.linalg.norm(pts[nb.ka, nb.qa] - pts[nb.kb, nb.qb], axis=1)
    d = core + nb.scale * (d + nb.shift - core)
    contact += float(np.sum((pr.L / nb.samples) ** 2 * shell.energy(d)))
    spring_contact, bending, work = nlp.energy(x, nlp.p0)
    assert bending == pytest.approx(bend, rel=1e-8)          # 8 against 16 Gauss nodes
    assert spring_contact == pytest.approx(contact, rel=1e-7)


def test_derivatives_against_finite_differences(small) -> None:
    """The gradient of f and the Jacobian of g that IPOPT gets, against central differences
    at a perturbed state (every block moved, crossings pressed)."""
    pr, nlp = small
    rng = np.random.default_rng(7)
    x = nlp.x0 + 1e-3 * rng.normal(size=nlp.x0.size)
    p = nlp.p0
    f = ca.Function("f", [nlp.nlp["x"], nlp.nlp["p"]], [nlp.nlp["f"], nlp.nlp["g"]])
    grad = ca.Function("j", [nlp.nlp["x"], nlp.nlp["p"]],
                       [ca.gradient(nlp.nlp["f"], nlp.nlp["x"]), ca.jacobian(nlp.nlp["g"], nlp.nlp["x"])])
    gf, jg = (np.asarray(v) for v in grad(x, p))
    eps = 1e-6
    for k in rng.choice(x.size, 25, replace=False):
        e = np.zeros(x.size)
        e[k] = eps
        (fp, gp), (fm, gm) = f(x + e, p), f(x - e, p)
        assert float(fp - fm) / (2 * eps) == pytest.approx(gf[k, 0], rel=1e-5, abs=1e-9)
        np.testing.assert_allclose(np.asarray(gp - gm).ravel() / (2 * eps),
                                   np.asarray(jg[:, k]).ravel(), rtol=1e-5, atol=1e-8)


def test_envelope_theorem_with_crossing_contacts(small) -> None:
    """dV/dtarget = reaction (−multiplier of the clamp row) at a minimum with pressed
    crossings: a central difference of the minimum over re-solves."""
    pr, nlp = small
    solver = WeftSolver(nlp, tol=1e-12, verbose=None)
    params = WeftParams.of(pr)
    base = solver.continuation(params.vector(), nlp.x0, 4)
    assert base.success
    state = nlp.crossing_state(base.x)
    assert np.any(state["compression"] < 0)                  # some wrap is pressed
    row = nlp.clamp_table.clamp_rows[1].position
    reaction = -base.lam_g[row]
    target = params.targets[1]
    step = 1e-4
    for d in range(2):
        values = []
        for sgn in (1, -1):
            moved = target.copy()
            moved[d] += sgn * step
            rep = solver.once(params.with_(targets={2: moved}).vector(), base.x)
            assert rep.success
            values.append(rep.objective)
        assert (values[0] - values[1]) / (2 * step) == pytest.approx(reaction[d], rel=1e-5, abs=1e-9)


def test_a_fabric_clamped_where_it_lies_carries_no_force() -> None:
    """Clamps given as zero displacements hold the natural 3-D fabric where it lies, on the
    wraps' own lattice (2.97 x 2.00 mm for the acrylic, not the paper's 2.53 x 2.23): the
    answer is the natural state, with no energy and no reaction (on the paper's lattice the
    clamps pressed it 0.44 mm together)."""
    doc = copy.deepcopy(ACRYLIC_2x2)
    doc["clamp"][1]["displacement"] = [0.0, 0.0]
    pr = parse_problem(doc, "rest3d.toml")
    w, c = pr.lattice
    assert (w, c) == (pr.yarn.natural3d.wale_spacing, pr.yarn.natural3d.course_spacing)
    assert w - pr.natural.wale_spacing > 0.3                      # the wraps' wider lattice
    out = knit_nlp.solve(pr).to_json()
    assert out["success"]
    assert abs(out["energy"]["total"]) < 1e-9
    assert max(abs(v) for cl in out["clamps"] for v in cl["reaction"]) < 1e-7


def test_the_plan_views_natural_fabric_is_the_3d_one_projected(small) -> None:
    """What the pictures and studies draw as the natural fabric of a 3-D problem
    (``natural_centrelines``) is the NLP's natural 3-D centrelines projected (S2 from the
    natural loop, on the 3-D lattice), not the paper's loop (0.54 mm RMS away for the acrylic)."""
    from knit_nlp.weft.model.centrelines import natural_centrelines
    pr, nlp = small
    np.testing.assert_allclose(natural_centrelines(pr, 41),
                               nlp.natural_centrelines3d(41)[..., :2], rtol=0, atol=1e-9)
