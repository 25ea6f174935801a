"""Fit and calibrate with yarn contact (issue 19, "Everywhere"; issue 20, run c): their forward
solves are contact solves and their sensitivities hold the active contacts (checked against
central differences of forward contact solves, and shown wrong without the contacts), a fit and
a calibration on data the contact model made at known values give those values back, and the
one factory (``equilibrium_for``) is the only way to an equilibrium of a problem with a radius.

The specimen: 2 x 3 loops (L = 11.28 mm) pulled along the wales between rigid clamps with
r = 0.95 mm: the courses narrow and five contacts push from strain 0.13 on (measured at r = 1.0,
the largest radius until the same-yarn rule refused radii above 0.961 here; at the
start the thick pairs merely touch, so the first nodes sit on the kink of the active set and
are left out of the comparisons)."""
from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest

from calibration_files import SYNTH_DOC, SYNTH_TRUTH, synthetic_spec, write_columns
import knit_nlp
from knit_nlp.cli import main
from knit_nlp.weft.inverse.calibration.curve import (SpecimenModel, fd_derivatives,
                                                     implicit_derivatives, strains_at)
from knit_nlp.weft.inverse.calibration.specimen import build_specimen, specimen_doc
from knit_nlp.weft.inverse.forward import equilibrium_for
from knit_nlp.weft.solving.contact.equilibrium import ContactEquilibrium
from knit_nlp.weft.solving.solve import Equilibrium
from knit_nlp.weft.inverse.fit import Fitter
from knit_nlp.weft.inverse.observations import Observation
from knit_nlp.weft.model.problem import parse_problem

RADIUS = 0.95              # below 0.961, the largest radius this natural loop admits (contact.rule)
DOC = {**SYNTH_DOC, "material": SYNTH_TRUTH, "yarn": {"radius": RADIUS}}
JAMMED = 0.1                # axial strain from which the contacts push (measured: node 0.13 on)
TRAVEL = 5.0                # mm of the fit case's pull (axial strain 0.3: five contacts active)
POINTS = [((1, 1), 0.5), ((1, 2), 0.25), ((2, 2), 0.5), ((2, 3), 0.75), ((1, 3), 0.0)]
TRUTH = np.array([SYNTH_TRUTH["k_a"], SYNTH_TRUTH["k_b"]])


def _error(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


# --- calibrate: the curve's sensitivities ------------------------------------------------------

@pytest.fixture(scope="module")
def pulled():
    """The specimen's contact curve to strain 0.3 and the node sensitivities to the material."""
    model = SpecimenModel(build_specimen(DOC, "<t>", "wales", 2, 3, "t"))
    c = model.curve(SYNTH_TRUTH, goal=1e9, strain_limit=0.3)
    assert isinstance(model.eq, ContactEquilibrium)
    jammed = c.u / model.specimen.gauge >= JAMMED
    assert jammed.sum() >= 3
    assert all(model.eq.state(x).n_active >= 1 for x, j in zip(c.xs, jammed) if j)
    return model, c, jammed


def test_curve_sensitivities_with_active_contacts_match_central_differences(pulled):
    """∂F/∂θ and ∂(lateral width)/∂θ at fixed clamp travel, at the nodes where contacts push,
    from the contact KKT system against central differences of curves re-solved with contact
    (measured: 1e-4 and 3e-4 at worst); the paper's model's KKT system at the same states
    (active gap rows dropped) is off by more than 10 % in the lateral width."""
    model, c, jammed = pulled
    names = ["k_a", "k_b", "R_f"]
    _, Ft, _, Lt = model.node_sensitivities(c, names)
    with pytest.MonkeyPatch.context() as mp:          # the paper's KKT system at each node
        mp.setattr(model.eq, "linear_system",
                   lambda x, lam, p: Equilibrium.linear_system(model.eq, x, lam, p, False))
        _, Ft0, _, Lt0 = model.node_sensitivities(c, names)
    worst = 0.0
    for k, name in enumerate(names):
        h = 1e-3 * SYNTH_TRUTH[name]
        up, down = (model.on_grid({**SYNTH_TRUTH, name: SYNTH_TRUTH[name] + d}, c)
                    for d in (h, -h))
        fd_f = (up.force - down.force)[jammed] / (2 * h)
        fd_l = (up.lateral - down.lateral)[jammed] / (2 * h)
        assert _error(Ft[jammed, k], fd_f) < 1e-3, name
        assert _error(Lt[jammed, k], fd_l) < 1e-3, name
        worst = max(worst, _error(Lt0[jammed, k], fd_l))
    assert worst > 0.1


def test_a_contact_curve_steps_from_its_last_state_and_its_nodes_are_fresh_solves(pulled):
    """Every step of a contact curve is one load step from the previous node (the cheap route:
    no paper's solve and contact rounds from it), and where the contacts push its nodes are the
    equilibria that contact solves from the natural fabric reach: same clamp force and lateral
    width (measured: at most 1.1e-7 relative; red when the curve solves from x0 alone)."""
    model, c, jammed = pulled
    routes = {model.eq.blocks[np.asarray(x).tobytes()].route for x in c.xs[1:]}
    assert all(r.startswith("one load step with contact from the last solved state")
               for r in routes), routes
    fresh = SpecimenModel(model.specimen)
    for k in np.flatnonzero(jammed)[[0, -1]]:
        rep = fresh.eq.solve(model.params(SYNTH_TRUTH, c.u[k]))
        assert rep.success
        assert abs(fresh.force(rep.lam_g) - c.force[k]) < 1e-5 * abs(c.force[k])
        assert abs(fresh.lateral(rep.x)[0] - c.lateral[k]) < 1e-5 * abs(c.lateral[k])


def test_strain_sensitivities_at_fixed_force_with_contact_implicit_and_fd_agree(pulled):
    """The calibration's d(strain at a fixed force)/dθ where the contacts push: the implicit
    path (``sensitivities = "implicit"``) and the finite-difference one agree."""
    model, c, jammed = pulled
    forces = np.linspace(c.force[jammed][0], c.force[-1], 4)[1:-1]
    names = ["k_b", "R_f"]
    ia, il = implicit_derivatives(model, c, names, forces)
    fa, fl = fd_derivatives(model, c, names, forces)
    for imp, fd in ((ia, fa), (il, fl)):
        assert np.all(np.abs(imp - fd).max(axis=0) < 2e-2 * np.abs(fd).max(axis=0))


def test_calibrate_with_contact_gives_back_the_values_its_curve_was_made_with(tmp_path):
    """Round trip through ``knit_nlp.calibrate`` with ``[yarn] radius``: the contact model's own
    wale-pull curve (k_b = 0.001 N/mm) as a columns test, noise-free, fitted from k_b = 0.0015
    with the implicit sensitivities: k_b back to 1 % (measured 0.3 %: the data are the PCHIP
    of a coarser curve than the fit's). To strain 0.22 only: the final evaluation's curve to
    3.0 stopped at 0.263 in one run (a contact branch with less force)."""
    sp = build_specimen(DOC, "<synthetic>", "wales", 2, 3, "synthetic")
    c = SpecimenModel(sp).curve(SYNTH_TRUTH, goal=1e9, strain_limit=0.22)
    width, top = 10.0 * sp.pitch_width, 10.0 * c.force[-1]
    forces = np.linspace(0.0, 0.99 * c.force[-1], 200)
    axial, lateral = strains_at(c, sp, forces)
    write_columns(tmp_path / "synthetic.csv", forces * 10.0, axial, lateral)
    spec = synthetic_spec(tmp_path, width, '["k_b"]', {**SYNTH_TRUTH, "k_b": 0.0015},
                          direction="wales", tables=f"[yarn]\n    radius = {RADIUS}",
                          forces=f"[{0.3 * top:.6g}, {0.6 * top:.6g}, {0.9 * top:.6g}]")
    res = knit_nlp.calibrate(spec)
    assert res.success, res.message
    assert res.parameters()["k_b"]["value"] == pytest.approx(SYNTH_TRUTH["k_b"], rel=1e-2)
    assert res.tests[0].metric.rms_axial < 1e-2


# --- fit: observed points ----------------------------------------------------------------------

def _case():
    doc = specimen_doc(DOC, "wales", 2, 3, "pull")
    doc["rigid_clamp"][1]["translation"] = [0.0, TRAVEL]
    return parse_problem(doc, "pull.toml")


def _observed(pr) -> list[Observation]:
    """The observed points where the contact model puts them at the true values."""
    probe = Fitter([pr], [Observation("pull", lp, "s", s * pr.L, np.zeros(2)) for lp, s in POINTS],
                   ["k_a", "k_b"])
    assert probe.solve_cases(TRUTH)
    assert probe.cases[0].eq.state(probe.cases[0].x).n_active >= 1
    xy = probe.positions(probe.cases[0])
    return [Observation("pull", lp, "s", s * pr.L, xy[k]) for k, (lp, s) in enumerate(POINTS)]


def test_the_fits_jacobian_with_active_contacts_matches_central_differences():
    """d(residual)/d(k_a, k_b) at values off the truth, contacts pushing: the fit's Jacobian
    against central differences of the residual over forward contact solves (measured 1e-4);
    the paper's model's sensitivities at the same state are off by 5 % (more than 3 %)."""
    pr = _case()
    fitter = Fitter([pr], _observed(pr), ["k_a", "k_b"])
    v = TRUTH * [1.3, 0.8]
    assert fitter.solve_cases(v)
    J, _ = fitter.jacobian(v)
    c = fitter.cases[0]
    dx0, _ = c.eq.sensitivity(c.x, c.lam, fitter._params(c, v), fitter._dp(c), sliding=False)
    J0 = np.asarray(c.points(c.x)[1] @ ca.DM(dx0))
    fd = []
    for k in range(2):
        rows = []
        for sign in (1, -1):
            w = v.copy()
            w[k] *= 1 + sign * 1e-3
            assert fitter.solve_cases(w)
            rows.append(fitter.residual())
        fd.append((rows[0] - rows[1]) / (2e-3 * v[k]))
    fd = np.array(fd).T
    assert max(_error(J[:, k], fd[:, k]) for k in range(2)) < 1e-3
    assert max(_error(J0[:, k], fd[:, k]) for k in range(2)) > 0.03


def test_fit_with_contact_gives_back_the_values_the_points_were_made_with(tmp_path, capsys):
    """``knit-nlp fit`` of a problem with ``[yarn] radius`` on points the contact model put at
    k_a = 0.01, k_b = 0.001, from 1.3 and 0.8 times them: both back to 1e-6, exit 0, the
    fitted case's picture drawn."""
    pr = _case()
    obs = _observed(pr)
    doc = specimen_doc(DOC, "wales", 2, 3, "pull")
    lines = ['name = "pull"', "[fabric]", "courses = 2", "wales = 3", "[loop]",
             "length = 11.28", "[material]", f"k_a = {TRUTH[0] * 1.3}", f"k_b = {TRUTH[1] * 0.8}",
             f"R_f = {SYNTH_TRUTH['R_f']}", "[yarn]", f"radius = {RADIUS}", "[units]",
             'length = "mm"', 'force = "N"']
    for k, rc in enumerate(doc["rigid_clamp"]):
        lines += ["[[rigid_clamp]]"] + [f'{key} = "{val}"' for key, val in rc.items()]
        if k == 1:
            lines.append(f"translation = [0.0, {TRAVEL}]")
    (tmp_path / "pull.toml").write_text("\n".join(lines) + "\n")
    (tmp_path / "obs.csv").write_text("case,course,wale,point,x,y\n" + "".join(
        f"pull,{o.loop[0]},{o.loop[1]},{o.s},{float(o.xy[0])!r},{float(o.xy[1])!r}\n" for o in obs))
    out = tmp_path / "out"
    code = main(["fit", str(tmp_path / "pull.toml"), "--observations", str(tmp_path / "obs.csv"),
                 "--params", "k_a", "k_b", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    js = json.loads((out / "pull.fit.json").read_text())
    assert js["success"]
    for name, truth in zip(("k_a", "k_b"), TRUTH):
        assert js["parameters"][name]["value"] == pytest.approx(truth, rel=1e-6)
    assert (out / "pull.fit.png").is_file()


# --- the one way to an equilibrium with a radius -----------------------------------------------

def test_the_factory_gives_contact_to_problems_with_a_radius_only():
    """``equilibrium_for`` is the one choice; the paper's Equilibrium refuses a radius in one
    line naming the factory (it would drop the contacts), and a contact equilibrium refuses
    sensitivities at a state it never solved (they would miss its contacts)."""
    pr = _case()
    eq = equilibrium_for(pr)
    assert isinstance(eq, ContactEquilibrium)
    doc = specimen_doc(SYNTH_DOC, "wales", 2, 3, "plain")
    assert type(equilibrium_for(parse_problem(doc, "plain.toml"))) is Equilibrium
    with pytest.raises(ValueError, match=r"ignores \[yarn\] radius.*equilibrium\(problem\)"):
        Equilibrium(pr)
    with pytest.raises(ValueError, match="solve it here first"):
        eq.sensitivity(eq.wnlp.x0, np.zeros(eq.wnlp.n_constraints), eq.wnlp.p0,
                       np.zeros((eq.wnlp.p0.size, 1)))
