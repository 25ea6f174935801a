"""The typed result of a calibration and the files it writes (docs/real_fabric.md).

``CalibrationResult`` follows the results contract of the solve commands: ``success``,
``status``, ``message``, ``nit``, ``to_json()`` and ``save(out)``. It writes
``<name>.calibration.json`` (values, standard errors, correlation, per test its metric),
``<name>.curves.csv`` (every test's model curve: ``test,use,force_N,axial_strain,
lateral_strain``) and ``<name>.calibration.png`` (``plot``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ....jsonio import write_csv, write_json
from ....provenance import source_record
from ...model.params import MATERIAL
from .checks import RATIO_STRAIN, wale_over_course
from .metric import MetricPoints
from .plot import plot_calibration
from .spec import CLAMP_SOURCE, CLAMP_WIDTH_MM, MEASURED, YARN_VALUES

if TYPE_CHECKING:
    from .fit import FitOutcome
    from .spec import CalibrationSpec, TestSpec
    from .specimen import Specimen

CURVE_COLUMNS = ("test", "use", "force_N", "axial_strain", "lateral_strain")
DIRECTION_AXIS = {"courses": "x", "wales": "y"}
VERDICT = {"fit": ("fits", "does not fit"), "predict": ("predicted", "not predicted")}


@dataclass(frozen=True)
class ModelCurve:
    """A model test curve in the data's units: the solved nodes and a PCHIP-sampled curve."""

    force: np.ndarray              # N, at the solved nodes
    axial: np.ndarray
    lateral: np.ndarray
    sample_force: np.ndarray       # N, evenly spaced from 0 to the data's end and to the last node
    sample_axial: np.ndarray
    sample_lateral: np.ndarray


@dataclass(frozen=True)
class TestOutcome:
    """One test at the final values."""

    test: "TestSpec"
    specimen: "Specimen"
    width: float                   # length units
    metric: MetricPoints
    model_se_axial: np.ndarray | None      # standard error of the model's strain at the metric
    model_se_lateral: np.ndarray | None    # forces, from the fit's covariance
    curve: ModelCurve
    complete: bool                 # the model curve reached the largest measured force
    targets: dict[str, float]      # by strain: the largest RMS strain error allowed (spec)
    reason: str = ""
    checks: dict[str, Any] = field(default_factory=dict)   # checks.outcome_checks
    check: dict[str, Any] = field(default_factory=dict)    # calibrate.final_check: the answer
    #                                                        at the curve's largest load
    lattice: tuple[float, float] | None = None   # a periodic cell's unloaded (w, c): the
    #                                              curve's first node

    def check_line(self) -> str:
        """``check at 12.3 N (axial strain 0.475): clean: ...``: the own check of the model's
        answer at its largest load (the summary's and the panel's words)."""
        if not self.check:
            return "check: not made"
        at, first = self.check["at"], self.check.get("first_not_clean")
        line = (f"check at {at['force_N']:.4g} N (axial strain {at['axial_strain']:.3g}, the "
                f"curve's largest load): {self.check['verdict']}")
        if first is None:
            return line
        return (f"{line}; the first node not clean: {first['force_N']:.4g} N (axial strain "
                f"{first['axial_strain']:.3g}), the nodes before it clean")

    def errors(self) -> dict[str, float | None]:
        """RMS strain error by strain (None: the model did not reach every metric force)."""
        out = {"axial": self.metric.rms_axial}
        if self.metric.measured_lateral is not None:
            out["lateral"] = self.metric.rms_lateral
        return out

    def within(self) -> dict[str, bool]:
        """Per targeted strain: is its RMS error within the target? A strain the test did not
        measure cannot meet its target, nor can a model that did not reach every force."""
        errs = self.errors()
        return {k: errs.get(k) is not None and errs[k] <= target
                for k, target in self.targets.items()}

    @property
    def success(self) -> bool:
        """The test is within its targets (and its model curve complete)."""
        return self.complete and all(self.within().values())

    def verdict(self) -> str:
        """One line: ``fit on x: axial 0.0461 against 0.03: does not fit``."""
        use, axis = self.test.use, DIRECTION_AXIS[self.test.direction]
        errs = self.errors()
        parts = [f"{k} {_fmt(errs.get(k))} against {target:g}" for k, target in self.targets.items()]
        good, bad = VERDICT[use]
        head = f"fit on {axis}" if use == "fit" else f"predicted {axis}"
        tail = "" if self.complete else " (the model curve stops short of the largest force)"
        return f"{head} ({self.test.file}): {', '.join(parts) or 'no target'}: " \
               f"{good if self.success else bad}{tail}"

    def _cell_lattice(self) -> dict[str, Any]:
        """A periodic cell's bending reference and the unloaded lattice (w, c) its strains are
        read from (the natural lattice, or a straight yarn's relaxed one)."""
        return {"bending_reference": self.specimen.reference,
                "lattice_unloaded": None if self.lattice is None else list(self.lattice)}

    def to_json(self) -> dict[str, Any]:
        t, sp = self.test, self.specimen
        out = {"file": t.file, "format": t.format, "direction": t.direction, "use": t.use,
               "success": self.success, "complete": self.complete, "targets": self.targets,
               "within_target": self.within(), "verdict": self.verdict(),
               "rms_strain_error": {
                   "axial": self.metric.rms_axial, "lateral": self.metric.rms_lateral},
               "metric": self.metric.to_json(),
               "specimen": {"kind": sp.kind, "courses": sp.courses, "wales": sp.wales,
                            "aspect_measured": t.aspect if t.aspect_source in ("pins", "spec") else None,
                            "aspect_source": t.aspect_source, "aspect_model": sp.aspect,
                            "gauge": sp.gauge, "pitch_width": sp.pitch_width,
                            "width": self.width, "width_clamps": t.width_clamps,
                            **(self._cell_lattice() if sp.kind == "periodic" else {})},
               "checks": self.checks, "check": self.check,
               "runs": len(t.measured.runs), "max_force_measured": t.measured.max_force,
               "max_force_model": float(self.curve.force[-1]) if len(self.curve.force) else 0.0}
        if self.model_se_axial is not None:
            out["metric"]["model_std_error"] = {"axial": self.model_se_axial,
                                                "lateral": self.model_se_lateral}
        if not self.complete:
            out["reason"] = self.reason
        return out


@dataclass(repr=False)
class CalibrationResult:
    """Fitted values with standard errors and correlation, and every test's outcome."""

    spec: "CalibrationSpec"
    values: dict[str, float]
    fit: "FitOutcome | None"
    tests: list[TestOutcome]
    timings: dict[str, float] = field(default_factory=dict)
    beside: "CalibrationResult | None" = None      # ``[calibrate] beside``: another model
    # ``[calibrate] breaks``: a breaks.Breaks (not imported here: breaks reads these results)
    breaks: Any = None

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def success(self) -> bool:
        """The fit converged and every test is within its targets (the verdict)."""
        return (self.fit is None or self.fit.success) and all(t.success for t in self.tests)

    @property
    def status(self) -> str:
        if self.fit is not None and not self.fit.success:
            return self.fit.status
        if any(not t.complete for t in self.tests):
            return "Model_Curve_Incomplete"
        return "Within_Targets" if self.success else "Targets_Missed"

    @property
    def message(self) -> str:
        """The fit's word, then every test's verdict and why a curve stopped."""
        head = "nothing fitted" if self.fit is None else f"fit: {self.fit.message}"
        stops = [f"{t.test.file}: {t.reason}" for t in self.tests if not t.complete]
        return "; ".join([head, *(t.verdict() for t in self.tests), *stops])

    @property
    def energy(self) -> None:
        """The results contract's ``energy``: a calibration stores none (its many equilibria
        are in the tests' curves); ``fit.cost`` is the least-squares objective."""
        return None

    @property
    def nit(self) -> int:
        """Residual evaluations of the fit (each one model curve per fit test)."""
        return 0 if self.fit is None else self.fit.nit

    def parameters(self) -> dict[str, dict[str, Any]]:
        """Per material value: the answer, whether fitted, its start, its standard error, and
        for a measured value (``spec.MEASURED``) what the spec gives as its measurement."""
        fitted = list(self.spec.fit)
        out = {}
        for name in self.reported():
            row: dict[str, Any] = {"value": self.values[name], "fitted": name in fitted,
                                   "initial": self.spec.values[name]}
            if name in fitted and self.fit is not None:
                row["std_error"] = self.fit.std_errors[fitted.index(name)]
            if name in MEASURED:
                row["measured"] = self.spec.values[name]
            out[name] = row
        return out

    def reported(self) -> tuple[str, ...]:
        """The values the model uses: k_a, k_b, R_f; in 3-D R_f, the springs only where the
        file turns them on, and the crossings' compression law (``spec.YARN_VALUES``)."""
        if not self.spec.spatial:
            return MATERIAL
        springs = ("k_a", "k_b") if self.spec.base.yarn.crossing_springs else ()
        return (*springs, "R_f", *YARN_VALUES)

    def checks(self) -> dict[str, Any]:
        """Across tests: the ratio of wale to course stiffness per width (``checks``), and with
        ``[calibrate] beside`` the other model's figures (:meth:`figures`)."""
        ratio = wale_over_course([(t.test.direction, t.checks) for t in self.tests])
        out: dict[str, Any] = {f"wale_over_course_stiffness_per_width_at_{RATIO_STRAIN:g}": ratio}
        if self.beside is not None:
            out["beside"] = self.beside.figures()
        return out

    def figures(self) -> dict[str, Any]:
        """What a researcher checks first, per test, model beside measured (issue 40 item 4):
        RMS axial and lateral strain error, the force at 10 and 30 % strain, the stiffening
        5 -> 45 %; and the wale / course stiffness ratio per width at 10 %."""
        key = f"wale_over_course_stiffness_per_width_at_{RATIO_STRAIN:g}"
        return {"name": self.name, "geometry": "3d" if self.spec.spatial else "planar",
                "status": self.status,
                "values": {k: v["value"] for k, v in self.parameters().items()},
                "fitted": list(self.spec.fit),
                "tests": [{"file": t.test.file, "use": t.test.use, "direction": t.test.direction,
                           "specimen": t.specimen.kind,
                           "courses": t.specimen.courses, "wales": t.specimen.wales,
                           "rms_strain_error": {"axial": t.metric.rms_axial,
                                                "lateral": t.metric.rms_lateral},
                           "complete": t.complete, "checks": t.checks} for t in self.tests],
                key: wale_over_course([(t.test.direction, t.checks) for t in self.tests])}

    def given(self) -> dict[str, Any]:
        """What the source gives and the calibration holds: the clamp width (mm, and where it
        comes from) and the yarn's length per stitch (the loop length)."""
        return {"clamp_width_mm": self.spec.clamp_width,
                "clamp_width_source": CLAMP_SOURCE if self.spec.clamp_width == CLAMP_WIDTH_MM
                else "the spec's [calibrate] clamp_width_mm",
                "loop_length_mm": self.spec.base.L,
                "geometry": "3d" if self.spec.spatial else "planar"}

    def correlation(self) -> dict[str, Any]:
        names = list(self.spec.fit)
        matrix = self.fit.correlation.tolist() if self.fit is not None else []
        return {"names": names, "matrix": matrix}

    def __repr__(self) -> str:
        vals = ", ".join(f"{k}={v['value']:.4g}" for k, v in self.parameters().items())
        rms = "; ".join(f"{t.test.file} ({t.test.use}) axial {_fmt(t.metric.rms_axial)} lateral "
                        f"{_fmt(t.metric.rms_lateral)}" for t in self.tests)
        return (f"CalibrationResult({self.name!r}: success={self.success}, status={self.status!r}, "
                f"{vals}; rms strain error {rms})")

    def to_json(self) -> dict[str, Any]:
        """``<name>.calibration.json``."""
        units = self.spec.base.units
        out = {"name": self.name, "success": self.success, "status": self.status,
               "message": self.message, "nit": self.nit,
               "units": {**units.to_json(), "k_a": f"{units.force}/{units.length}",
                         "k_b": f"{units.force}/{units.length}",
                         "R_f": f"{units.force}·{units.length}²"},
               "fit": list(self.spec.fit), "parameters": self.parameters(),
               "given": self.given(),
               "correlation": self.correlation(),
               "metric_forces_N": list(self.spec.forces),
               "fit_strains": list(self.spec.strains),
               "sensitivities": self.spec.sensitivities,
               "tests": [t.to_json() for t in self.tests],
               "checks": self.checks(),
               "targets": self.spec.targets,
               "warnings": self.fit.warnings if self.fit is not None else [],
               "scan": [{"value": v, "rms_strain_residual": r} for v, r in self.fit.scan]
               if self.fit is not None else [],
               "timings": self.timings}
        if self.breaks is not None:
            out["breaks"] = self.breaks.to_json()
        source = source_record(str(self.spec.source))
        if source:
            out["source"] = source
        return out

    def curve_rows(self) -> list[dict[str, Any]]:
        """The rows of ``<name>.curves.csv``: every test's solved model curve nodes."""
        rows = []
        for t in self.tests:
            for f, a, lat in zip(t.curve.force, t.curve.axial, t.curve.lateral):
                rows.append({"test": t.test.file, "use": t.test.use, "force_N": f"{f:.9g}",
                             "axial_strain": f"{a:.9g}", "lateral_strain": f"{lat:.9g}"})
        return rows

    def save(self, out_dir: Path | str) -> list[Path]:
        """``DIR/<name>.calibration.json``, ``.curves.csv`` and ``.calibration.png``."""
        out = Path(out_dir)
        js = write_json(out / f"{self.name}.calibration.json", self.to_json())
        csv = write_csv(out / f"{self.name}.curves.csv", self.curve_rows(), CURVE_COLUMNS)
        png = plot_calibration(out / f"{self.name}.calibration.png", self)
        return [js, csv, png]


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.4f}"
