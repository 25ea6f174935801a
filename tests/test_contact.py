"""Yarn contact (issue 19): closed forms, the envelope theorem with active contacts, derivatives
against finite differences, the crossing counter on hand-made centrelines, and the refusals."""
from __future__ import annotations

import dataclasses

import casadi as ca
import numpy as np
import pytest

from knit_nlp.weft.api import solve
from knit_nlp.weft.model.cases import diagonal_pull, unclamped
from knit_nlp.weft.model.contact.crossings import Crossings, find_crossings, judge
from knit_nlp.weft.model.contact.curves import Curves
from knit_nlp.weft.model.contact.natural import NaturalFabric
from knit_nlp.weft.model.contact.pairs import Grid
from knit_nlp.weft.model.parametrisation import Full, Reduced
from knit_nlp.weft.model.params import WeftParams
from knit_nlp.weft.model.problem import Clamp, Load, Yarn, parse_problem
from knit_nlp.weft.output.check import check
from knit_nlp.weft.output.results import WeftResult
from knit_nlp.weft.solving.contact.rounds import ContactSolver, Step
from knit_nlp.weft.solving.contact.equilibrium import ContactRefused
from knit_nlp.weft.solving.solve import SolveReport, WeftSolver
from knit_nlp.weft.transcription.contact import Slots
from knit_nlp.weft.transcription.factory import transcribe
from knit_nlp.weft.transcription.full import build_nlp

L = 10.0


def rods(push: float, r: float = 0.2, c: float = 1.0):
    """Rod A (course 1) clamped at its start along x; rod B (course 2) parallel above it, held
    in x and angle at its start, free to move in y, pushed down at its middle (two straight
    natural courses: no crossings, so the second course is added past the file reader, which
    asks two courses for the 2 + 2 crossings of a knit)."""
    doc = {"fabric": {"courses": 1, "wales": 1},
           "loop": {"preset": "straight", "length": L, "harmonics": 3, "course_spacing": c},
           "material": {"R_f": 1000.0},
           "clamp": [{"loop": [1, 1], "point": "start", "position": [0.0, 0.0], "angle": 0.0}]}
    pr = parse_problem(doc, "rods")
    held = Clamp((2, 1), "start", 0.0, np.array([0.0, c]), (True, False), 0.0)
    return dataclasses.replace(pr, courses=2, yarn=Yarn(r), name="rods",
                               clamps=pr.clamps + (held,),
                               loads=(Load((2, 1), L / 2, L / 2, np.array([0.0, -push])),))


def squeezed(d: float, r: float | None = 0.15):
    """One jersey loop between two rigid clamps holding its ends (and their angles), the right
    one moved left by d: the loop's neck closes."""
    doc = {"name": "squeeze", "fabric": {"courses": 1, "wales": 1},
           "rigid_clamp": [{"points": [{"loop": [1, 1], "point": "start"}]},
                           {"points": [{"loop": [1, 1], "point": "end"}], "translation": [-d, 0.0]}],
           "clamp": [{"loop": [1, 1], "point": "start", "fix": [], "angle": 0.0},
                     {"loop": [1, 1], "point": "end", "fix": [], "angle": 0.0}]}
    if r:
        doc["yarn"] = {"radius": r}
    return parse_problem(doc, "squeeze")


def test_straight_rods_stop_at_2r_and_carry_the_push():
    """Closed form: B comes down on A and stops with its centreline 2r above A's; A's clamp
    carries the whole push, and the contact forces (the gap rows' multipliers) add up to it
    (B's only vertical forces are the load and the contacts)."""
    push, r = 0.3, 0.2
    res = solve(rods(push, r))
    assert res.success
    block = res.contact
    assert block.smallest_gap == pytest.approx(2 * r, rel=1e-6)
    assert res.starts[1, 0, 1] == pytest.approx(2 * r, abs=1e-5)     # B's start, above A's
    assert res.clamps[0].reaction[1] == pytest.approx(push, rel=1e-8)
    assert sum(c.force for c in block.contacts) == pytest.approx(push, rel=2e-3)
    assert check(res.to_json(), res.problem).ok


def test_a_loop_pressed_between_rigid_clamps_keeps_its_legs_2r_apart():
    """Without contact the squeezed loop's legs come within 0.4 x 2r of each other; with it no
    gap is short, no crossing appears, and the clamps push far harder (the neck is jammed)."""
    d, r = 0.5, 0.15
    free, jammed = solve(squeezed(d, None)), solve(squeezed(d, r))
    assert free.success and jammed.success
    before, after = check(free.to_json(), squeezed(d, r)), check(jammed.to_json(), squeezed(d, r))
    assert before.short_gaps and before.smallest_gap < 0.5 * 2 * r
    assert after.ok and after.smallest_gap >= 2 * r * (1 - 1e-3)
    assert jammed.contact.active >= 1
    assert jammed.rigid_clamps[0].force[0] > 10 * free.rigid_clamps[0].force[0] > 0


def test_envelope_theorem_with_active_contacts():
    """With the contacts active, the moving clamp's reaction along its motion is the derivative
    of the stored energy by its translation (central differences of the contact NLP's minimum,
    the same pairs, re-solved at translations d ± h)."""
    d, h = 0.5, 1e-4
    pr = squeezed(d)
    base = build_nlp(pr)
    contact = ContactSolver(WeftSolver(base), pr.yarn.radius)
    report = SolveReport(False, "", base.x0, np.zeros(base.n_constraints), np.nan, 0, 0.0)
    p_at = WeftParams.natural(pr).vector()
    run = contact.run(base.params.vector(), p_at, base.x0, 4, report)
    used, lam = run.solved.pairs, run.solved.lam_gap    # the pairs of the last solve
    assert run.report.success and (lam < -1e-3).any()               # a contact pushes

    def energy(delta: float) -> float:
        p = WeftParams.of(pr).with_(rigid={2: (-(d + delta), 0.0, 0.0)}).vector()
        rep, _ = contact.solve_once(p, run.report.x, used, None, report, [], "fd")
        assert rep.success
        return float(sum(base.energy(rep.x[:base.n_variables], p)[:2]))

    result = WeftResult(base, run.report, base.params, 0.0, 0.0)
    dU = (energy(h) - energy(-h)) / (2 * h)
    assert -result.rigid_clamps[1].force[0] == pytest.approx(dU, rel=1e-5)
    assert dU > 0.1                                          # contact dominates (free: 0.03)


def _random_contact_nlp(seed: int = 1, n: int = 6):
    pr = parse_problem(diagonal_pull(3), "x")
    base = build_nlp(pr)
    rng = np.random.default_rng(seed)
    kA, kB = rng.integers(0, pr.n_loops, n), rng.integers(0, pr.n_loops, n)
    c = transcribe(pr, Full(), contact=Slots(kA, kB), base=base)
    sA, sB = rng.uniform(0, L, n), rng.uniform(0, L, n)
    x = c.lift_slots(base.x0, sA, sB) + 0.01 * rng.normal(size=c.n_variables)
    p = c.parameters(base.p0, sA, sB, rng.choice([-1.0, 1.0], n))
    return c, x, p, rng


def test_contact_derivatives_match_finite_differences():
    """jac_g and hess_lag (closed form) against central differences of g and of ∇(λᵀg), in
    every column: the loops' coefficients (∂I/∂a, the cells' and the partial cell's parts),
    starts and the slots' own variables."""
    c, x, p, rng = _random_contact_nlp()
    X, P = c.nlp["x"], c.nlp["p"]
    g = ca.Function("g", [X, P], [c.nlp["g"]])
    lam = rng.normal(size=c.n_constraints)
    grad = ca.Function("gl", [X, P], [ca.gradient(ca.dot(ca.MX(lam), c.nlp["g"]), X)])
    J = np.asarray(ca.densify(c.nlpsol_options["jac_g"](x, p)[1]))
    H = np.asarray(ca.densify(c.nlpsol_options["hess_lag"](x, p, 0.0, lam)))
    H = H + np.triu(H, 1).T
    h = 1e-6
    rows = c.g.slice("contact_lift").start
    for k in range(c.n_variables):
        e = np.zeros(c.n_variables)
        e[k] = h
        fd = (np.asarray(g(x + e, p)) - np.asarray(g(x - e, p))).ravel() / (2 * h)
        np.testing.assert_allclose(J[rows:, k], fd[rows:], atol=1e-7)
        fd2 = (np.asarray(grad(x + e, p)) - np.asarray(grad(x - e, p))).ravel() / (2 * h)
        np.testing.assert_allclose(H[:, k], fd2, atol=2e-6 * max(1.0, np.abs(fd2).max()))


def _two_rods(a_angle: float, b_start, b_angle: float, b_curv: float = 0.0) -> Curves:
    """Course 1: a straight loop from the origin at angle a_angle; course 2: a loop from
    b_start at b_angle with constant curvature b_curv (coefficients of θ = a·φ(s): the linear
    and constant slots)."""
    coeffs = np.zeros((2, 1, 8))
    coeffs[0, 0, 7] = a_angle
    coeffs[1, 0, 6], coeffs[1, 0, 7] = b_curv, b_angle
    starts = np.array([[[0.0, 0.0]], [b_start]], dtype=float)
    return Curves.of(coeffs, starts, L)


@pytest.mark.parametrize("curves, expected", [
    (_two_rods(0.0, (5.0, -3.0), np.pi / 2), 1),                     # B crosses A once
    (_two_rods(0.0, (2.0, 0.5), -0.6, 0.2), 2),                      # an arc dipping through A
    # an arc of radius 10 whose lowest point (s = 5.025, between samples) touches A: tangent
    (_two_rods(0.0, (5.0 - 10 * np.sin(0.5025), 10 * (1 - np.cos(0.5025))), -0.5025, 0.1), 0),
    (_two_rods(0.0, (0.0, 0.5), 0.0), 0),                            # apart, parallel
])
def test_crossing_counter_on_hand_made_centrelines(curves, expected):
    """Crossing, an arc passing through (two), touching (tangent: not a crossing), apart."""
    found = find_crossings(curves, Grid(2, 1, L, 200))
    assert len(found) == expected
    assert all(found.kA == 0) and all(found.kB == 1)


def test_crossing_judge_counts_against_the_natural_fabric():
    """The natural jersey has exactly its designed crossings (4 per vertically neighbouring
    pair of loops) and none new; the paper's diagonal pull has yarns passing through."""
    pr = parse_problem(unclamped(4, 4), "x")
    fab = NaturalFabric.of(pr, 0.15)
    nat = Curves.of(np.broadcast_to(pr.natural.coeffs, (4, 4, 8)), pr.natural_starts(), L)
    found = find_crossings(nat, Grid(4, 4, L, 100))
    assert len(found) == 4 * 3 * 4
    assert judge(fab, found, 4, 4).clean and judge(fab, found, 4, 4).lost == 0
    assert fab.crossings((1, 0)) == 4 and fab.crossings((2, 0)) == 0 == fab.crossings((1, 1))
    pull = solve(parse_problem(diagonal_pull(5), "x"))
    verdict = judge(fab, find_crossings(Curves.of(pull.coefficients, pull.starts, L),
                                        Grid(5, 5, L, 100)), 5, 5)
    assert not verdict.clean


def test_a_sheared_row_of_interlocks_is_judged_as_slides_in_any_order():
    """Two courses of 4 loops: three interlocks each slid one loop along (one crossing of
    loops (1,j) and (2,j+1) each, one fewer on (1,j)-(2,j)), as by the 100 x 100 pull's pinned
    corner. Every excess crossing has a missing one next to it: no new crossing, none lost. The
    greedy pairing spent (1,2)-(2,2)'s missing crossing on (1,1)-(2,2) and (1,3)-(2,3)'s on
    (1,2)-(2,3), and called (1,3)-(2,4) new; the steps of that pull were halved for it."""
    pr = parse_problem(unclamped(2, 4), "x")
    fab = NaturalFabric.of(pr, 0.15)
    pairs = [(j, 4 + j) for j in range(4) for _ in range(4 if j == 3 else 3)]
    pairs += [(j, 5 + j) for j in range(3)]
    kA, kB = (np.array(v) for v in zip(*pairs))
    z = np.zeros(len(pairs))
    verdict = judge(fab, Crossings(kA, z, kB, z, np.zeros((len(pairs), 2))), 2, 4)
    assert verdict.clean and verdict.lost == 0 and verdict.lost_pairs == {}
    extra = Crossings(np.append(kA, 0), np.append(z, 0), np.append(kB, 6), np.append(z, 0),
                      np.zeros((len(pairs) + 1, 2)))
    assert judge(fab, extra, 2, 4).new == {(0, 6): 1}     # two loops along: not a slide


def test_natural_gaps_of_the_jersey_preset():
    """Thick yarn: the jersey's closest non-crossing pieces, two courses apart, are 0.352
    apart (so any r above 0.176 = 0.0176 L makes them thick)."""
    fab = NaturalFabric.of(parse_problem(unclamped(3, 3), "x"), 0.5)
    gap = fab.table((2, 0)).natural_gap
    assert float(gap.min()) == pytest.approx(0.352, abs=2e-3)
    assert float(fab.table((0, 0)).natural_gap.min()) == pytest.approx(0.529, abs=2e-3)


@pytest.mark.parametrize("radius", [0.15, 0.5])
def test_natural_tables_skip_only_offsets_whose_pieces_are_all_apart(monkeypatch, radius):
    """The shortcut for far loop offsets (every piece more than 2r apart, no designed box
    reaching in) gives the same required gaps, min(2r, natural gap), as the full table."""
    pr = parse_problem(unclamped(3, 3), "x")
    offsets = [(di, dj) for di in range(-2, 3) for dj in range(-3, 4)]
    fast = NaturalFabric._new(pr, radius)
    quick = {o: np.minimum(2 * radius, fast.table(o).natural_gap) for o in offsets}
    import knit_nlp.weft.model.contact.natural as natural
    monkeypatch.setattr(natural, "_box_distance", lambda a, b: 0.0)
    slow = NaturalFabric._new(pr, radius)
    skipped = 0
    for o in offsets:
        full = np.minimum(2 * radius, slow.table(o).natural_gap)
        np.testing.assert_array_equal(quick[o], full)
        assert fast.table(o).interlocks == slow.table(o).interlocks
        skipped += fast.table(o).natural_gap.strides == (0, 0)
    assert skipped >= 10                                   # the shortcut is taken


def test_positions_by_the_cell_rule_match_adaptive_quadrature():
    """Curves.points (the rule the contact rows use) against scipy's adaptive quadrature of
    eq. (1) on loops like the natural jersey's with every harmonic perturbed, at points in
    every cell and a little past both ends."""
    from scipy.integrate import quad
    rng = np.random.default_rng(7)
    coeffs = rng.normal(size=(4, 1, 8)) * np.r_[np.full(6, 0.4), 0.05, 1.0]
    coeffs[:, 0, 0] += 2.0
    curves = Curves.of(coeffs, rng.normal(size=(4, 1, 2)), L)
    k = np.repeat(np.arange(4), 25)
    s = rng.uniform(-0.3, L + 0.3, k.size)
    got = curves.points(k, s)
    for kk, ss, pt in zip(k, s, got):
        theta = lambda u: curves.angle(np.array(kk), np.array(u))      # noqa: E731
        ref = [quad(lambda u: np.cos(theta(u)), 0.0, ss, epsabs=1e-13, limit=200)[0],
               quad(lambda u: np.sin(theta(u)), 0.0, ss, epsabs=1e-13, limit=200)[0]]
        np.testing.assert_allclose(pt - curves.starts[kk], ref, atol=1e-7)


def test_the_reduced_model_is_refused_with_a_radius():
    pr = dataclasses.replace(parse_problem(diagonal_pull(4), "x"), yarn=Yarn(0.2))
    with pytest.raises(ContactRefused, match="reduced model: no yarn contact yet"):
        solve(pr, Reduced())
    with pytest.raises(ValueError):
        solve(pr, warm_from_reduced=True)


def test_warm_start_from_a_contact_result_reaches_the_next_load_step():
    """calib's use: a load path as separate solves, each started from the last result."""
    first = solve(squeezed(0.3))
    second = solve(squeezed(0.5), start=first)
    assert second.success and check(second.to_json(), squeezed(0.5)).ok
    direct = solve(squeezed(0.5))
    assert second.energy.total == pytest.approx(direct.energy.total, rel=1e-6)


def test_lifted_contact_points_start_on_their_rows():
    c, x, p, _ = _random_contact_nlp(seed=3)
    x0 = c.lift_slots(c.base.x0, c.p.get(p, "contact_s_A").ravel(),
                      c.p.get(p, "contact_s_B").ravel())
    g = np.asarray(ca.Function("g", [c.nlp["x"], c.nlp["p"]], [c.nlp["g"]])(x0, p)).ravel()
    assert np.abs(g[c.g.slice("contact_lift")]).max() < 1e-12


def test_the_contact_nlp_is_a_weft_nlp_read_through_its_base():
    """The factory's contact NLP (``transcribe(problem, Full(), contact=Slots(...))``) offers
    the protocol: its parameter layout names where each slot's s_A, s_B and σ lie in the vector
    ``parameters`` builds, and what the protocol reads of a decision vector (loops, starts,
    centrelines, energy) is its base part's; a reduced model with contact is refused."""
    c, x, p, rng = _random_contact_nlp(seed=4)
    base, nb = c.base, c.base.n_variables
    sA, sB = rng.uniform(0, L, c.n_slots), rng.uniform(0, L, c.n_slots)
    sigma = rng.choice([-1.0, 1.0], c.n_slots)
    q = c.parameters(base.p0, sA, sB, sigma)
    assert q.size == c.p.size and c.n_variables == nb + 5 * c.n_slots
    for name, want in (("contact_s_A", sA), ("contact_s_B", sB), ("contact_sigma", sigma)):
        np.testing.assert_array_equal(c.p.get(q, name).ravel(), want)
    np.testing.assert_array_equal(c.centrelines(x), base.centrelines(x[:nb]))
    assert c.energy(x, q) == base.energy(x[:nb], base.p0)
    np.testing.assert_array_equal(c.coefficients(c.lift(base.coefficients(x[:nb]),
                                                        base.starts(x[:nb]))),
                                  base.coefficients(x[:nb]))
    with pytest.raises(ValueError, match="full model"):
        transcribe(base.problem, Reduced(), contact=Slots(c.kA, c.kB))


def test_a_contact_solve_keeps_to_its_time_budget():
    """[solver] max_time bounds the contact rounds too: out of time is reported, not hidden."""
    pr = squeezed(0.5)
    pr = dataclasses.replace(pr, solver=dataclasses.replace(pr.solver, max_time=0.05))
    res = solve(pr)
    assert not res.success and res.status == "Maximum_WallTime_Exceeded"


def test_without_a_radius_nothing_changes(monkeypatch):
    """The paper's model: no contact code runs (every ContactSolver made is counted) and the
    result has no contact block. The same problem with a radius that never binds (r = 0.05:
    the squeezed neck stays 1.15 x 2r open in the paper's answer) runs the contact code and
    gives the paper's answer bit for bit; one that binds (r = 0.15) moves the loop, so the
    comparison can see a difference."""
    made = []
    real = ContactSolver.__init__

    def counted(self, *args, **kwargs):
        made.append(1)
        real(self, *args, **kwargs)
    monkeypatch.setattr(ContactSolver, "__init__", counted)
    free = solve(squeezed(0.5, None))
    assert not made and "contact" not in free.to_json() and free.success
    loose = solve(squeezed(0.5, 0.05))
    assert made and loose.success
    assert loose.contact.route == "paper's model: no contact needed"
    np.testing.assert_array_equal(loose.coefficients, free.coefficients)
    np.testing.assert_array_equal(loose.starts, free.starts)
    tight = solve(squeezed(0.5, 0.15))
    assert np.abs(tight.coefficients - free.coefficients).max() > 0.05


def test_a_failed_step_after_a_widened_search_reports_the_solved_pairs(monkeypatch):
    """Load steps that fail after one success widen the search (new pairs) and give up: the run
    must report the pairs of its last solved step with their multipliers, not the newer search
    (they differed in length: an IndexError in the result's contact block at 10 x 10)."""
    pr = squeezed(0.5)
    base = build_nlp(pr)
    contact = ContactSolver(WeftSolver(base), pr.yarn.radius)
    report = SolveReport(False, "", base.x0, np.zeros(base.n_constraints), np.nan, 0, 0.0)
    real_step, real_pairs, solved = contact.step, contact.pairs, []

    def step(*args, **kwargs):              # the first step is solved, every later one fails
        out = real_step(*args, **kwargs) if not solved else Step("Invalid_Number_Detected")
        solved.append(out)
        return out

    def pairs(x):                           # a search after the first step finds one pair fewer
        found = real_pairs(x)
        return found.select(np.arange(len(found)) > 0) if solved else found

    monkeypatch.setattr(contact, "step", step)
    monkeypatch.setattr(contact, "pairs", pairs)
    run = contact.run(base.params.vector(), WeftParams.natural(pr).vector(), base.x0, 2, report,
                      max_halvings=1)
    assert solved[0].success and not run.report.success
    assert len(run.pairs) == len(run.lam_gap) == len(solved[0].pairs)


def test_the_pair_search_takes_the_samples_a_chunk_at_a_time_with_the_same_answer(monkeypatch):
    """find_pairs takes the samples' neighbours and feet CHUNK samples at a time (all at once,
    the checker on a 100 x 100 result took more than 9.9 GB): the pairs of a crossed state
    (the paper's 4 x 4 pull) are the same, in the same order, with chunks of 7 samples (their
    points to 1e-14 L: numpy's vector operations may round differently on shorter arrays; at
    the default CHUNK the 10 x 10 and 30 x 30 pulls' pairs are the same bit for bit)."""
    from knit_nlp.weft.model.contact import pairs as P
    pr = parse_problem({**diagonal_pull(4), "yarn": {"radius": 0.15}}, "pull 4")
    base = build_nlp(pr)
    x = WeftSolver(base, verbose=None).once(base.params.vector(), base.x0).x
    whole = ContactSolver(WeftSolver(base), 0.15).pairs(x)
    monkeypatch.setattr(P, "CHUNK", 7)
    chunked = ContactSolver(WeftSolver(base), 0.15).pairs(x)
    assert len(whole) > 100
    for f in dataclasses.fields(whole):
        np.testing.assert_allclose(getattr(chunked, f.name), getattr(whole, f.name), rtol=0,
                                   atol=1e-14 * pr.L)
