"""``[calibrate] specimen = "periodic"``: the 3-D model's periodic cell as a calibration's
specimen (``calibration.cell``; docs/real_fabric.md, "A periodic cell"). A spec that a cell
cannot follow is refused in one line; the contact rigidity enters the cell as an exact energy
scale; a fit started far from the answer, with ``scan``, recovers the contact rigidity of a
cell built directly at it; and a single value's scan starts the least squares at the best of
its factors."""
from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest

from calibration_files import noisy_columns
from knit_nlp.cli import main
from knit_nlp.errors import ProblemError
from knit_nlp.tomlio import toml_text
from knit_nlp.weft.inverse.calibration.calibrate import TestModel as CellTest
from knit_nlp.weft.inverse.calibration.cell import CellModel, build_cell_specimen
from knit_nlp.weft.inverse.calibration.curve import JAMMED, Curve, CurveModel
from knit_nlp.weft.inverse.calibration.fit import fit_log
from knit_nlp.weft.inverse.calibration.spec import load_spec, parse_spec
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.model.spatial.periodic import solve_cell

K_TRUE = 0.0012 * 16            # N/mm³: the synthetic test's contact rigidity
YARN = {"geometry": "3d", "radius": 0.74, "core_radius": 0.325, "contact_exponent": 2.4,
        "contact_rigidity": K_TRUE, "elevation_modes": 4}         # acrylic_3d_source's law
DOC = {"units": {"length": "mm", "force": "N"}, "loop": {"length": 11.28},
       "material": {"R_f": 0.045}, "yarn": YARN, "solver": {"max_iter": 150}}
STRAINS = np.arange(0.025, 0.301, 0.025)
SAMPLES = 40                    # other-contact samples per loop (80 in the shipped specs)


def cell_model(doc: dict) -> CellModel:
    pr = parse_problem({**doc, "fabric": {"courses": 2, "wales": 2}}, "<cell>")
    return CellModel(*build_cell_specimen(pr, "courses", SAMPLES))


def spec_doc(width: float, start: float, **calibrate) -> dict:
    return {"name": "cellfit", **DOC, "yarn": {**YARN, "contact_rigidity": start},
            "calibrate": {"fit": ["contact_rigidity"], "specimen": "periodic",
                          "cell_samples": SAMPLES, "forces": [1.0, 2.0, 3.0], **calibrate},
            "test": [{"file": "cell.csv", "format": "columns", "direction": "courses",
                      "use": "fit", "width": width}]}


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    """The cell's own course pull at K_TRUE to 30 % strain (built directly at K_TRUE), written
    as a ``columns`` test with noise; the folder and the width at which its top is 4 N."""
    folder = tmp_path_factory.mktemp("cellfit")
    model = cell_model(DOC)
    c = model.pull_to(DOC["material"], STRAINS)
    assert c.complete, c.reason
    width = noisy_columns(folder / "cell.csv", c, model.specimen, 4.0, 0.001, 3, 300, seed=5)
    return folder, width


def test_a_spec_a_periodic_cell_cannot_follow_is_refused_in_one_line(data):
    folder, width = data
    good = spec_doc(width, K_TRUE)
    assert parse_spec(good, folder / "cellfit.toml").specimen == "periodic"
    planar = {**{k: v for k, v in good.items() if k != "yarn"},
              "calibrate": {**good["calibrate"], "fit": ["R_f"]}}
    for doc, key, words in (
            (planar, "specimen", "geometry = \"3d\""),
            ({**good, "fabric": {"courses": 3, "wales": 3}}, "specimen", "[fabric]"),
            ({**good, "calibrate": {**good["calibrate"], "min_loops": 3}}, "specimen",
             "min_loops"),
            ({**good, "yarn": {**YARN, "friction": 0.2}}, "specimen", "friction"),
            ({**good, "yarn": {**YARN, "crossing_springs": True}, "material":
              {"R_f": 0.045, "k_a": 1.0, "k_b": 0.01}}, "specimen", "crossing springs"),
            ({**good, "calibrate": {**good["calibrate"], "specimen": "cylinder"}}, "specimen",
             "periodic"),
            ({**planar, "calibrate": {**planar["calibrate"], "specimen": "clamped"}},
             "cell_samples", "periodic"),
            ({**planar, "calibrate": {"fit": ["R_f"], "bending_reference": "straight"}},
             "bending_reference", "periodic"),
            ({**good, "calibrate": {**good["calibrate"], "bending_reference": "set"}},
             "bending_reference", "straight"),
            ({**good, "calibrate": {**good["calibrate"], "fit": ["R_f", "contact_rigidity"],
                                    "scan": True}}, "scan", "single")):
        with pytest.raises(ProblemError) as err:
            parse_spec(doc, folder / "cellfit.toml")
        text = str(err.value)
        assert f"[calibrate] {key}" in text and words in text and "\n" not in text, text


def test_the_fitted_contact_rigidity_reaches_the_cell_as_the_cell_built_at_it(data):
    """The spec's cell is built at k₀ = K_TRUE / 4; at the values k = K_TRUE its curve is the
    one of the cell built at K_TRUE, number for number (the NLP takes k; the clamped
    specimens' energy scale λ = k/k₀ found another equilibrium of the cell: U 0.00097 against
    0.00083 N·mm at 5 %, model.spatial.periodic)."""
    folder, width = data
    path = folder / "scale.toml"
    path.write_text(toml_text(spec_doc(width, K_TRUE / 4)))
    spec = load_spec(path)
    tm = CellTest(spec, 0)
    values = {**spec.values, "contact_rigidity": K_TRUE}
    strains = [0.05, 0.1]
    assert tm.energy_scale(values) == 1.0
    fitted = tm.model.pull_to(tm.material(values), strains).force * tm.scale(values)
    direct = cell_model(DOC).pull_to(DOC["material"], strains).force * tm.scale(values)
    base = tm.model.pull_to(tm.material(spec.values), strains).force * tm.scale(values)
    assert fitted[1:] == pytest.approx(direct[1:], rel=1e-7)
    assert abs(direct[2] / base[2] - 1) > 0.05          # k moves the force well beyond that


def test_a_scanned_fit_recovers_the_contact_rigidity_of_the_cell_that_made_the_data(data):
    """Started 16 times too soft, the fit scans its start and recovers K_TRUE within a few of
    its standard errors; the JSON records the scan and the specimen."""
    folder, width = data
    path = folder / "cellfit.toml"
    path.write_text(toml_text(spec_doc(width, K_TRUE / 16, scan=True)))
    code = main(["calibrate", str(path), "--out", str(folder / "out")])
    doc = json.loads((folder / "out" / "cellfit.calibration.json").read_text())
    row = doc["parameters"]["contact_rigidity"]
    assert code == 0, doc["tests"][0]["verdict"]
    assert abs(row["value"] - K_TRUE) < max(3 * row["std_error"], 0.02 * K_TRUE), row
    assert len(doc["scan"]) == 10
    best = min(doc["scan"], key=lambda s: s["rms_strain_residual"])
    assert best["value"] == pytest.approx(K_TRUE)       # 16 = 2⁴ is on the scan's grid
    specimen = doc["tests"][0]["specimen"]
    assert specimen["kind"] == "periodic" and specimen["bending_reference"] == "natural"
    # the natural lattice (w, c): the cell solved at rest from the natural state moved it by
    # 1.9e-3 mm on one machine (IPOPT's path differs in rounding; the equilibria are not unique)
    assert specimen["lattice_unloaded"] == pytest.approx(
        [specimen["gauge"], specimen["pitch_width"]], abs=3e-3)
    assert doc["tests"][0]["check"]["ok"] is True


def test_a_scan_starts_the_least_squares_at_its_best_factor():
    """A residual with a local minimum at every whole log₂ v and the global one at log₂ v = 5:
    without the scan the trust region ends in another (log₂ v = 4, started at 0); with it, the
    least squares starts at the scan's best factor, 2⁵, and ends there."""
    def f(z):
        return 0.02 * (z - 5) ** 2 + 0.3 * np.sin(np.pi * z) ** 2 + 1e-12

    def residual(v):
        return np.sqrt([f(np.log2(v[0]))])

    def jacobian(v):                            # d r / d log v
        h = 1e-6
        up, down = residual(v * np.exp(h)), residual(v * np.exp(-h))
        return ((up - down) / (2 * h))[:, None]

    unscanned = fit_log(["k"], np.array([1.0]), residual, jacobian)
    assert unscanned.scan == [] and abs(np.log2(unscanned.values[0]) - 5) > 0.5
    scanned = fit_log(["k"], np.array([1.0]), residual, jacobian, scan=True)
    assert [v for v, _ in scanned.scan] == pytest.approx([2.0 ** e for e in range(-3, 7)])
    assert np.log2(scanned.values[0]) == pytest.approx(5.0, abs=1e-3)


def test_a_straight_yarn_s_cell_is_read_from_its_relaxed_lattice():
    """``bending_reference = "straight"``: bent from a straight yarn the cell is prestressed and
    relaxes at zero force to another lattice; the curve starts there (no force, no strain),
    the pull sets the spacing along it to the relaxed one times 1 + strain, and force and
    lateral strain are read per the relaxed spacing across, from the cell's own solves."""
    pr = parse_problem({**DOC, "fabric": {"courses": 2, "wales": 2}}, "<cell>")
    specimen, cell = build_cell_specimen(pr, "courses", SAMPLES, "straight")
    model = CellModel(specimen, cell, "straight")
    R_f, k = DOC["material"]["R_f"], K_TRUE
    rest = model.rest(R_f, k)
    along, across = model.lattice(R_f, k)
    assert rest.success and rest.U > 0.05                  # N mm: the bent loop's prestress
    assert abs(along / specimen.gauge - 1) > 0.005 and abs(across / specimen.pitch_width - 1) > 0.005
    c = model.pull_to({"R_f": R_f, "contact_rigidity": k}, np.array([0.05, 0.1]))
    assert c.complete and c.force[0] == 0.0
    assert c.lateral[0] / specimen.lateral_width - 1 == pytest.approx(0.0, abs=1e-9)
    assert c.u[1:] / specimen.gauge == pytest.approx([0.05, 0.1])
    for node in (1, 2):
        x = c.xs[node]
        assert x[-2] == pytest.approx(along * (1 + c.u[node] / specimen.gauge), rel=1e-9)
        direct = solve_cell(cell, x[-2], R_f, x, rigidity=k)        # the node, solved again
        assert c.force[node] / specimen.pitch_width == pytest.approx(direct.F / across, rel=1e-6)
        assert c.lateral[node] / specimen.lateral_width - 1 == pytest.approx(
            cell.across(x) / across - 1, abs=1e-9)
    assert 0 < c.force[1] < c.force[2]


def test_the_shipped_cell_specs_hold_every_measured_value_and_fit_only_k():
    """``acrylic_3d_cell_x`` fits the contact rigidity on the course pull and predicts the wale
    pull; ``acrylic_3d_cell_xy`` fits it on both (issue 40 item 3); ``acrylic_3d_cell_straight_x``
    and ``_straight_xy`` are the two bent from a straight yarn: all as a periodic cell at the
    source's clamp width, with the yarn's measured values held; ``_straight_source_x`` reads the
    bending modulus as the source's simulation does (R_f = 2B), nothing else changed."""
    x, xy = load_spec("real_fabric/acrylic_3d_cell_x"), load_spec("real_fabric/acrylic_3d_cell_xy")
    straight = load_spec("real_fabric/acrylic_3d_cell_straight_x")
    straight_xy = load_spec("real_fabric/acrylic_3d_cell_straight_xy")
    assert [s.bending_reference for s in (x, xy, straight, straight_xy)] == [
        "natural", "natural", "straight", "straight"]
    for bent, natural in ((straight, x), (straight_xy, xy)):
        assert [(t.file, t.direction, t.use) for t in bent.tests] == [
            (t.file, t.direction, t.use) for t in natural.tests] and bent.values == natural.values
    for spec in (x, xy, straight, straight_xy):
        assert spec.specimen == "periodic" and spec.scan and spec.fit == ("contact_rigidity",)
        assert spec.clamp_width == 35.5 and spec.values["R_f"] == 0.045
        assert spec.values["radius"] == 0.74 and spec.base.L == 11.28
    assert [(t.direction, t.use) for t in x.tests] == [("courses", "fit"), ("wales", "predict")]
    assert [t.use for t in xy.tests] == ["fit", "fit"]
    source = load_spec("real_fabric/acrylic_3d_cell_straight_source_x")   # the other reading
    assert source.values == {**straight.values, "R_f": 2 * 0.045}        # of B: B∫κ² = ½(2B)∫κ²
    assert (source.bending_reference, source.fit, source.specimen) == (
        "straight", ("contact_rigidity",), "periodic")
    assert [(t.file, t.direction, t.use) for t in source.tests] == [
        (t.file, t.direction, t.use) for t in straight.tests]


class Scalar(CurveModel):
    """A curve model of one number (gauge 1): the travel u is the state; the solve succeeds
    where ``ok(u)`` (else ``status``) and reads ``force(u)``, no lateral change."""

    specimen = SimpleNamespace(gauge=1.0)

    def __init__(self, ok, force, status: str) -> None:
        self.ok, self.force, self.status = ok, force, status

    def params(self, material, u):
        return u

    def _solve(self, p, x0, curve: Curve, p0=None):
        curve.solves += 1
        ok = bool(self.ok(p))
        return SimpleNamespace(success=ok, status="ok" if ok else self.status,
                               x=np.array([p]), iterations=1)

    def read(self, rep):
        return self.force(float(rep.x[0])), 0.0

    def multipliers(self, rep):
        return np.zeros(1)


def test_a_curve_past_its_goal_stops_where_the_model_jams():
    """The stepper (``curve.CurveModel``) runs on past the goal force to the strain the checks
    read, but stops where the force passes ``JAMMED`` times the goal: here a model whose force
    u/(0.3 − u) diverges at u = 0.3 (gauge 1), goal 1, asked for strain 0.5. The curve ends
    past 100 N, below u = 0.3, complete, and says it jammed."""
    jamming = Scalar(lambda u: u < 0.3, lambda u: u / (0.3 - u), "jammed")
    c = jamming.curve({}, goal=1.0, strain_limit=0.6, min_strain=0.5)
    assert c.complete and "jams" in c.reason
    assert JAMMED < c.force[-1] and c.u[-1] < 0.3
    assert len(c.u) < 60 and c.solves < 200


def test_a_curve_whose_unloaded_state_does_not_solve_says_so_and_records_nothing():
    """``CurveModel.pull_to`` (as ``curve``): a straight yarn's cell that does not relax, or
    any specimen whose unloaded solve fails, gives an incomplete curve with the solver's
    status, not a first node read off a failed solve."""
    def unsolved():
        return Scalar(lambda u: u > 0, lambda u: u, "Infeasible_Problem_Detected")

    for c in (unsolved().pull_to({}, np.array([0.1, 0.2])), unsolved().curve({}, goal=1.0)):
        assert not c.complete and "unloaded" in c.reason and "Infeasible" in c.reason
        assert c.u.size == 0 and c.solves == 1


class Branchy(Scalar):
    """A Scalar whose solve lands on a lower branch (force less ``drop``) when a step longer
    than ``jump`` ends inside ``region``: the periodic cell's non-unique equilibria."""

    def __init__(self, force, jump: float, region: tuple[float, float], drop: float) -> None:
        super().__init__(lambda u: True, force, "")
        self.jump, self.region, self.drop = jump, region, drop

    def _solve(self, p, x0, curve: Curve, p0=None):
        rep = super()._solve(p, x0, curve, p0)
        rep.lower = x0 is not None and p - x0[0] > self.jump and self.region[0] < p < self.region[1]
        return rep

    def read(self, rep):
        return self.force(float(rep.x[0])) - (self.drop if rep.lower else 0.0), 0.0


def test_a_step_that_lands_on_a_lower_branch_is_tried_again_shorter():
    """``curve.CurveModel.curve``: a long step whose force falls (another equilibrium) is
    retried at a quarter of its length (``BRANCH_RETRIES`` a curve) and the curve goes on to its
    goal, every node's force rising; a force that truly peaks still ends the curve, saying so.
    Red with ``BRANCH_RETRIES = 0`` (the curve stopped at the first fall, 0.18 of the way)."""
    branchy = Branchy(lambda u: u, jump=0.05, region=(0.15, 0.3), drop=0.5)
    c = branchy.curve({}, goal=1.0)
    assert c.complete and c.force[-1] >= 1.0
    assert np.all(np.diff(c.force) > 0)
    peaked = Scalar(lambda u: True, lambda u: u * (0.6 - u), "")
    p = peaked.curve({}, goal=1.0)
    assert not p.complete and "stops rising" in p.reason
    assert 0.25 < p.u[-1] < 0.35 and p.solves < 60       # the peak: 0.3
