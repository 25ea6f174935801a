"""Calibration: fit material values on measured tests, predict the rest.

Each test is a specimen model (``specimen``, ``curve``); its real force is the model force
times the width ratio s = W / (pitch width), W the test's real width in mm (given, or its width
in clamp widths × the clamp width, 35.5 mm by default: ``spec.CLAMP_WIDTH_MM``). The fit matches, on every ``use = "fit"`` test, the
model's strains at 20 forces evenly spaced up to the largest force every run reaches against
every run's strains at its first frame reaching them (axial, and lateral where measured and
asked for). Tests with ``use = "predict"`` never enter the fit: they are evaluated once, at the
fitted values, with the metric (``metric``) and the standard errors the fit's covariance
implies for the model's strains.
"""
from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import numpy as np

from ...model.params import MATERIAL
from .breaks import where_it_breaks
from .checks import HALF, STIFFENING, outcome_checks
from .cell import CellModel, build_cell_specimen
from .curve import (MAX_STRAIN, Curve, CurveModel, SpecimenModel, fd_derivatives,
                    implicit_derivatives, strains_at)
from .fit import MAX_EVALUATIONS, PENALTY, SCAN_FACTORS, FitOutcome, fit_log
from .measured import MeasuredTest
from .metric import levels, metric
from .result import CalibrationResult, ModelCurve, TestOutcome
from .spec import CalibrationSpec, TestSpec, load_spec
from .specimen import build_specimen

GOAL_MARGIN = 1.02          # the model curve runs to 2 % past the largest measured force
STRAIN_LIMIT_FACTOR = 3.0   # ... or stops at 3 times the largest measured axial strain
STRAIN_LIMIT_FLOOR = 0.5    #     (but not below 0.5, nor above curve.MAX_STRAIN)
CURVE_SAMPLES = 121         # model curve points written and drawn
CHECKS_STRAIN = STIFFENING[1] + HALF    # ... and to the largest strain the checks read
# The 3-D model's curves stop at 60 % axial strain (the checks read up to 47.5 %, the course
# tests reach 51 %): past it its course pulls straighten the loops onto their crossings and the
# steps stall (2 x 3 acrylic: to 122 % strain in 300-iteration steps; 3 x 5: a step past 50 %
# ran 268 iterations at max violation 1.2 without converging, measured)
SPATIAL_MAX_STRAIN = 0.6
CURVES_KEPT = 4             # model curves a test remembers (the fit's base and its differences)
# ``curve_differences``: forward differences of whole curves in log(value), step 0.05. The
# curve's nodes follow the force, so its strains at fixed forces carry an interpolation noise
# of about 2e-4 (curve.NODES); a 5 % change of a value moves them by 1e-3 to 1e-2 (3-D course
# pull, contact rigidity and R_f), so the noise is a few per cent of the difference.
CURVE_FD_LOG_STEP = 0.05


class TestModel:
    """One test's specimen model and its curves at given values (the last one cached)."""

    def __init__(self, spec: CalibrationSpec, k: int) -> None:
        self.test: TestSpec = spec.tests[k]
        self.clamp_width = spec.clamp_width
        if spec.specimen == "periodic":
            self.specimen, cell = build_cell_specimen(spec.base, self.test.direction,
                                                      spec.cell_samples, spec.bending_reference)
            self.model: CurveModel = CellModel(self.specimen, cell, spec.bending_reference)
        else:
            self.specimen = build_specimen(spec.doc, str(spec.source), self.test.direction,
                                           self.test.courses, self.test.wales,
                                           spec.test_name(k))
            self.model = SpecimenModel(self.specimen)
        # the contact rigidity the 3-D NLP was built with (``energy_scale``)
        self.rigidity = spec.values.get("contact_rigidity") if spec.spatial else None
        self._cache: dict[tuple[float, ...], Curve] = {}
        self.min_strain = 0.0          # the final evaluation's curve runs to CHECKS_STRAIN too
        measured = max(float(np.max(r.axial)) for r in self.measured.runs)
        self.max_strain = SPATIAL_MAX_STRAIN if spec.spatial else MAX_STRAIN
        self.strain_limit = min(self.max_strain,
                                max(STRAIN_LIMIT_FLOOR, STRAIN_LIMIT_FACTOR * measured))
        self.solves = 0
        self.iterations = 0

    @property
    def measured(self) -> MeasuredTest:
        return self.test.measured

    def width(self, values: dict[str, float] | None = None) -> float:
        """The real specimen's width in mm: the test's own, or its width in clamp widths times
        the clamp width (``values`` is not used: the width is given, never fitted)."""
        if self.test.width is not None:
            return self.test.width
        return float(self.measured.width_clamps * self.clamp_width)

    def energy_scale(self, values: dict[str, float] | None = None) -> float:
        """λ = k / k₀ of the 3-D model (1 for the planar one): its energy is
        U = R_f·B(x) + k·C(x) [+ k_a, k_b springs] (S4, S7), so at the clamps' positions the
        equilibrium at (R_f, k_a, k_b, k) is the one at (R_f/λ, k_a/λ, k_b/λ, k₀) with every
        force times λ. A fitted contact rigidity therefore re-solves the NLP built at k₀ with
        the material divided by λ and scales its forces (tested against an NLP built at k).
        A model whose NLP takes k as a parameter (``takes_rigidity``: the periodic cell,
        cell.py) is given k itself, λ = 1."""
        if self.rigidity is None or values is None or self.model.takes_rigidity:
            return 1.0
        return values["contact_rigidity"] / self.rigidity

    def scale(self, values: dict[str, float] | None = None) -> float:
        """Real force over model force: width over the model specimen's pitch width (times the
        3-D model's energy scale λ, ``energy_scale``)."""
        return self.width() / self.specimen.pitch_width * self.energy_scale(values)

    def material(self, values: dict[str, float]) -> dict[str, float]:
        """The NLP's material parameters at ``values`` (divided by λ, ``energy_scale``; with
        the contact rigidity for a model that takes it)."""
        lam = self.energy_scale(values)
        out = {k: values[k] / lam for k in MATERIAL}
        if self.model.takes_rigidity and self.rigidity is not None:
            out["contact_rigidity"] = values["contact_rigidity"]
        return out

    def curve(self, values: dict[str, float]) -> Curve:
        material = self.material(values)
        key = (*material.values(), self.strain_limit, self.min_strain)
        if key not in self._cache:
            goal = GOAL_MARGIN * self.measured.max_force / self.scale(values)
            c = self.model.curve(material, goal, self.strain_limit, self.min_strain)
            self.solves += c.solves
            self.iterations += c.iterations
            if len(self._cache) >= CURVES_KEPT:
                self._cache.pop(next(iter(self._cache)))
            self._cache[key] = c
        return self._cache[key]

    def strains(self, values: dict[str, float], forces: np.ndarray,
                extrapolate: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Model axial and lateral strain at real forces (N); past the curve's end NaN, or
        continued along its last tangent (``extrapolate``, for the fit)."""
        return strains_at(self.curve(values), self.specimen,
                          np.asarray(forces) / self.scale(values), extrapolate)

    def derivatives(self, values: dict[str, float], forces: np.ndarray, names: list[str],
                    method: str) -> tuple[np.ndarray, np.ndarray]:
        """d(axial, lateral strain at real forces)/d(log value) for ``names``."""
        if method == "curve_differences":
            return self.curve_differences(values, forces, names)
        c = self.curve(values)
        fm = np.asarray(forces) / self.scale(values)
        if not names:
            return np.zeros((len(fm), 0)), np.zeros((len(fm), 0))
        finder = implicit_derivatives if method == "implicit" else fd_derivatives
        dax, dlat = finder(self.model, c, names, fm)
        if method != "implicit":
            self.solves += 2 * len(c.u) * len(names)
        scale = np.array([values[n] for n in names])
        return dax * scale, dlat * scale

    def curve_differences(self, values: dict[str, float], forces: np.ndarray,
                          names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """d(axial, lateral strain at real forces)/d(log value) by forward differences of
        whole curves, step ``CURVE_FD_LOG_STEP`` in log value (the 3-D model's sensitivities:
        one more curve per value)."""
        base = self.strains(values, forces, extrapolate=True)
        dax, dlat = np.zeros((len(forces), len(names))), np.zeros((len(forces), len(names)))
        for q, name in enumerate(names):
            moved = {**values, name: values[name] * np.exp(CURVE_FD_LOG_STEP)}
            ax, lat = self.strains(moved, forces, extrapolate=True)
            dax[:, q] = (ax - base[0]) / CURVE_FD_LOG_STEP
            dlat[:, q] = (lat - base[1]) / CURVE_FD_LOG_STEP
        return dax, dlat

    def matched(self, strains: tuple[str, ...]) -> tuple[str, ...]:
        """The strains this test contributes to a fit."""
        return tuple(s for s in strains if s == "axial" or self.measured.has_lateral)


class Calibration:
    """The spec's test models and the least-squares problem over the fitted values."""

    def __init__(self, spec: CalibrationSpec,
                 progress: Callable[[str], None] | None = None) -> None:
        t0 = time.perf_counter()
        self.spec = spec
        self.progress = progress or (lambda line: None)
        self.evaluations = 0
        self.models = [TestModel(spec, k) for k in range(len(spec.tests))]
        self.build_s = time.perf_counter() - t0
        self.t0 = t0
        self.names = list(spec.fit)
        self._fit_data = {}
        for tm in self.models:
            if tm.test.use == "fit":
                forces = tm.test.fit_forces()
                self._fit_data[id(tm)] = (forces, levels(tm.measured, forces),
                                          levels(tm.measured, forces, lateral=True)
                                          if tm.measured.has_lateral else None)

    def values(self, fitted: np.ndarray) -> dict[str, float]:
        return {**self.spec.values, **dict(zip(self.names, map(float, fitted)))}

    def _fit_models(self) -> list[TestModel]:
        return [tm for tm in self.models if tm.test.use == "fit"]

    def residual(self, fitted: np.ndarray) -> np.ndarray:
        """Model minus measured strains over every fit test, run and fit force."""
        v = self.values(fitted)
        parts = []
        for tm in self._fit_models():
            forces, ax, lat = self._fit_data[id(tm)]
            model_ax, model_lat = tm.strains(v, forces, extrapolate=True)
            for kind in tm.matched(self.spec.strains):
                model, data = (model_ax, ax) if kind == "axial" else (model_lat, lat)
                parts.append(np.nan_to_num(model[None, :] - data, nan=PENALTY).ravel())
        r = np.concatenate(parts)
        self.evaluations += 1
        most = MAX_EVALUATIONS + (len(SCAN_FACTORS) if self.spec.scan else 0)
        self.progress(f"fit: evaluation {self.evaluations} (at most {most}), rms "
                      f"strain residual {np.sqrt(np.mean(r ** 2)):.4g}, "
                      f"{time.perf_counter() - self.t0:.0f} s")
        return r

    def jacobian(self, fitted: np.ndarray) -> np.ndarray:
        """d residual / d log(fitted values)."""
        v = self.values(fitted)
        rows = []
        for tm in self._fit_models():
            forces, ax, lat = self._fit_data[id(tm)]
            dax, dlat = tm.derivatives(v, forces, self.names, self.spec.sensitivities)
            for kind in tm.matched(self.spec.strains):
                d, data = (dax, ax) if kind == "axial" else (dlat, lat)
                # a level no frame reaches is the constant PENALTY in the residual: no slope
                rows.append(np.where(np.isnan(data).ravel()[:, None], 0.0,
                                     np.tile(np.nan_to_num(d), (data.shape[0], 1))))
        return np.vstack(rows)

    def fit(self) -> FitOutcome | None:
        if not self.names:
            return None
        initial = np.array([self.spec.values[n] for n in self.names])
        return fit_log(self.names, initial, self.residual, self.jacobian, self.spec.scan)

    def outcome(self, tm: TestModel, values: dict[str, float],
                cov_log: np.ndarray | None) -> TestOutcome:
        """A test at the final values: its metric, checks, model curve and strain uncertainty.
        The curve may run to ``curve.MAX_STRAIN`` (3-D: ``SPATIAL_MAX_STRAIN``) here, to reach
        the largest measured force,
        and it runs at least to the strain the checks read (``CHECKS_STRAIN``), past that force
        where the model is stiffer than the fabric."""
        tm.strain_limit, tm.min_strain = tm.max_strain, CHECKS_STRAIN
        c = tm.curve(values)
        forces = np.array(self.spec.forces)
        ax, lat = tm.strains(values, forces)
        points = metric(tm.measured, self.spec.forces, ax, lat)
        se_ax = se_lat = None
        if cov_log is not None and c.complete:
            dax, dlat = tm.derivatives(values, forces, self.names, self.spec.sensitivities)
            se_ax = np.sqrt(np.maximum(np.einsum("fi,ij,fj->f", dax, cov_log, dax), 0.0))
            se_lat = np.sqrt(np.maximum(np.einsum("fi,ij,fj->f", dlat, cov_log, dlat), 0.0))
        scale = tm.scale(values)
        top = c.force[-1] * scale if len(c.force) else 0.0
        # drawn where the data are (plot.py: to the largest measured or metric force), and on
        # to the last node (a wale cell jammed at 6,932 N left one sample below 30 N)
        drawn = min(top, max(tm.measured.max_force, self.spec.forces[-1]) * 1.02)
        sample = np.union1d(np.linspace(0.0, drawn, CURVE_SAMPLES),
                            np.linspace(0.0, top, CURVE_SAMPLES))
        s_ax, s_lat = strains_at(c, tm.specimen, sample / scale) if len(c.force) > 1 else (
            np.zeros(0), np.zeros(0))
        curve = ModelCurve(c.force * scale, c.u / tm.specimen.gauge,
                           c.lateral / tm.specimen.lateral_width - 1.0, sample, s_ax, s_lat)
        reason = "" if c.complete else (f"{c.reason}: it reaches {top:.4g} N of the "
                                        f"{tm.measured.max_force:.4g} N measured")
        checks = outcome_checks((curve.axial, curve.force),
                                [(r.axial, r.force) for r in tm.measured.runs], tm.width())
        lattice = (tm.model.unloaded_lattice(c)
                   if isinstance(tm.model, CellModel) and c.xs else None)
        return TestOutcome(tm.test, tm.specimen, tm.width(values), points, se_ax, se_lat, curve,
                           c.complete, dict(self.spec.targets.get(tm.test.use, {})), reason,
                           checks, final_check(tm, c, curve), lattice)


def final_check(tm: TestModel, c: Curve, curve: ModelCurve) -> dict:
    """The own check every weft result carries (``output.check.own_check``, as
    ``WeftResult.checked``; in 3-D ``spatial_own_check``, all pairs of yarn pieces) of a
    test's answer at the final values and its largest load: the model curve's last node.
    Where that answer is not clean, the curve's nodes are checked from the unloaded one on up
    to the first that is not (``first_not_clean``: its force, strain and verdict): past it
    the model curve is not a clean answer. Where the last node is clean the nodes before it
    are not checked: the check of every node of every curve would cost as many checks as
    forward solves (``at`` says where it was made). A curve without a solved node has no
    answer to check: {} ("check: not made"; a loop twice as long in ``--breaks`` ended a
    38-minute run with an IndexError here)."""
    if not c.xs:
        return {}
    block = tm.model.check(c.xs[-1])
    out = {**block, "at": {"force_N": float(curve.force[-1]),
                           "axial_strain": float(curve.axial[-1]),
                           "node": "the model curve's last (largest load); the others are "
                                   "checked only where it is not clean"}}
    if not block["ok"]:
        out["first_not_clean"] = _first_not_clean(tm, c, curve, block)
    return out


def _first_not_clean(tm: TestModel, c: Curve, curve: ModelCurve, last: dict) -> dict:
    """The first node of the curve, from the unloaded one, whose answer the own check does not
    call clean (``last``, the last node's block, is not, so there is one): its index, force,
    axial strain and verdict."""
    k, block = len(c.xs) - 1, last
    for node, x in enumerate(c.xs[:-1]):
        seen = tm.model.check(x)
        if not seen["ok"]:
            k, block = node, seen
            break
    return {"node": k, "force_N": float(curve.force[k]), "axial_strain": float(curve.axial[k]),
            "verdict": block["verdict"]}


def evaluate(spec: CalibrationSpec) -> list[TestOutcome]:
    """Every test of ``spec`` at its values, nothing fitted, as the final evaluation makes it
    (``breaks``: a measured value moved from the answer)."""
    cal = Calibration(spec)
    return [cal.outcome(tm, dict(spec.values), None) for tm in cal.models]


def calibrate(spec_or_path: CalibrationSpec | str | Path,
              progress: Callable[[str], None] | None = None) -> CalibrationResult:
    """Fit a spec's ``[calibrate] fit`` values on its fit tests and evaluate every test
    (the Python entry point behind ``knit-nlp calibrate``). Bad input raises ProblemError.
    ``progress`` receives a line after every residual evaluation and before every test's
    final evaluation (the command prints them on stderr). With ``[calibrate] breaks = true``
    the result also carries where the model breaks (``breaks``: each measured value moved
    alone from the answer)."""
    spec = spec_or_path if isinstance(spec_or_path, CalibrationSpec) else load_spec(spec_or_path)
    t0 = time.perf_counter()
    cal = Calibration(spec, progress)
    t1 = time.perf_counter()
    ans = cal.fit()
    t2 = time.perf_counter()
    values = cal.values(ans.values) if ans is not None else dict(spec.values)
    cov_log = None
    if ans is not None and all(s is not None for s in ans.std_errors):
        se = np.array(ans.std_errors) / ans.values
        cov_log = ans.correlation * np.outer(se, se)
    outcomes = []
    for tm in cal.models:
        cal.progress(f"evaluating {tm.test.file} ({tm.test.use}, pulled along the "
                     f"{tm.test.direction}), {time.perf_counter() - t0:.0f} s")
        outcomes.append(cal.outcome(tm, values, cov_log))
    t3 = time.perf_counter()
    timings = {"build_s": cal.build_s, "fit_s": t2 - t1, "evaluate_s": t3 - t2,
               "total_s": t3 - t0, "forward_solves": sum(tm.solves for tm in cal.models),
               "ipopt_iterations": sum(tm.iterations for tm in cal.models)}
    beside = None
    if spec.beside is not None:       # the other model's figures, reported beside these
        say = progress or (lambda line: None)
        say(f"beside: calibrating {spec.beside}, {time.perf_counter() - t0:.0f} s")
        beside = calibrate(spec.beside, lambda line: say(f"beside: {line}"))
        timings["beside_s"] = beside.timings["total_s"]
    result = CalibrationResult(spec, values, ans, outcomes, timings, beside)
    if spec.breaks:
        result.breaks = where_it_breaks(result, evaluate, progress=progress)
        timings["breaks_s"] = result.breaks.seconds
    return result

