"""A calibration spec: a weft problem file describing the specimen, plus ``[[test]]`` tables
(measured tests) and a ``[calibrate]`` table (what to fit). docs/real_fabric.md.

Everything is checked, and every test file read and checked, before any model is built: a bad
spec or CSV is one :class:`ProblemError` (exit 2) and nothing is written.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ....errors import ProblemError, quoted
from ....problems import problems_dir
from ....tomlio import Table, load_toml
from ...model.params import MATERIAL
from ...model.problem import WeftProblem, parse_problem
from .curve import SENSITIVITIES
from .measured import FORMATS, MeasuredTest, read_test
from .metric import METRIC_FORCES, check_reaches
from .specimen import DIRECTIONS, loop_counts

FITTABLE = MATERIAL
# The 3-D model ([yarn] geometry = "3d", docs/weft3d.md): the crossings' soft-shell law
# (model/compression.py) in the yarn's values. Only its rigidity k may be fitted: the yarn's
# compression tests give k times the probe's unrecorded width, never k itself
# (docs/real_fabric.md, "The yarn's compression law"), and it enters the NLP exactly as an
# overall energy scale (``calibrate.TestModel``: no rebuild). k_a, k_b act in 3-D only with
# [yarn] crossing_springs = true; the radius, core and exponent shape the natural 3-D loop and
# the law's form and are held (`knit-nlp calibrate --breaks` moves them one at a time: breaks.py).
YARN_VALUES = ("radius", "core_radius", "contact_rigidity", "contact_exponent")
SPATIAL_FITTABLE = ("R_f", "contact_rigidity")
REFERENCES = ("natural", "straight")    # [calibrate] bending_reference of a periodic cell
# Values the yarn's own tests measure (stitch-by-stitch, Singal et al. 2024: the acrylic's
# bending modulus from cantilever tests, data/Yarn_bending/; its radius,
# code/fabric_simulations/stockinetteconfig.dat): held unless the spec fits them, and a fitted
# one is reported beside the value the spec gives for it. k_a and k_b, the planar model's
# crossing springs, and the 3-D model's contact rigidity have no measurement: their spec
# values are only starting values.
MEASURED = {"R_f": "the yarn's bending modulus", "radius": "the yarn's radius"}
# The testing machine's clamp, mm: stitch-by-stitch data/uniaxial_experiments/template.nb sets
# clampSizeInPhysicalUnits = 35.5 and computes stress as force / (fabricSize · 35.5 / clampSize);
# a tracking file's clamp_size_px / fabric_width_px give the width in clamp widths.
CLAMP_WIDTH_MM = 35.5
CLAMP_SOURCE = ("stitch-by-stitch data/uniaxial_experiments/template.nb: "
                "clampSizeInPhysicalUnits = 35.5")
LENGTH_SCALE_GONE = ("length_scale (mm per clamp width) is not fitted any more: it is the "
                     "specimen's size, which the source gives (" + CLAMP_SOURCE + " mm), not a "
                     "material value; remove it and write clamp_width_mm = 35.5 (the default) "
                     "under [calibrate]")
# A test's model (``[calibrate] specimen``): the specimen between two rigid clamps with free
# edges (specimen.py), or the 3-D model's loop as a periodic cell, a fabric with no edges
# (cell.py).
SPECIMENS = ("clamped", "periodic")
CELL_SAMPLES = 80           # model.spatial.periodic.SAMPLES (48, 64, 80: course F(10 %) 0.329,
                            # 0.334, 0.335 N; docs/real_fabric.md)
USES = ("fit", "predict")
STRAINS = ("axial", "lateral")
OWN_TABLES = ("test", "calibrate")
REFUSED = {"clamp": "the calibration grips every test with its own two rigid clamps",
           "rigid_clamp": "the calibration grips every test with its own two rigid clamps",
           "load": "a test is pulled by its clamp, not by loads",
           "reduction": "the calibration solves the full model"}
DEFAULT_MIN_LOOPS = 6
MAX_LOOPS_SPEC = 40
MAX_TESTS = 16
FIT_LEVELS = 20             # fit forces: evenly spaced up to the largest force every run reaches
# The verdict's targets (issue 40): RMS strain error at the metric's forces a test must stay
# within, by its use and strain. A spec may change them in [calibrate.targets] as
# fit_axial, fit_lateral, predict_axial, predict_lateral (a strain without a target is reported,
# not judged).
TARGETS: dict[str, dict[str, float]] = {"fit": {"axial": 0.03},
                                        "predict": {"axial": 0.05, "lateral": 0.05}}


@dataclass(frozen=True)
class TestSpec:
    """One ``[[test]]`` table, read and checked, with its measured runs."""

    file: str                              # as written in the spec
    format: str
    direction: str
    use: str
    measured: MeasuredTest
    width: float | None                    # specimen width (length units), if given
    aspect: float                          # gauge / width used for the loop counts
    aspect_source: str                     # "pins", "spec", "fabric", "none" (periodic)
    courses: int
    wales: int
    table: str

    @property
    def width_clamps(self) -> float | None:
        return None if self.width is not None else self.measured.width_clamps

    def fit_forces(self) -> np.ndarray:
        top = self.measured.common_force
        return top * np.arange(1, FIT_LEVELS + 1) / FIT_LEVELS


@dataclass(frozen=True)
class CalibrationSpec:
    """A checked calibration spec."""

    name: str
    description: str
    source: Path
    doc: dict[str, Any]                    # the weft problem tables shared by every test
    base: WeftProblem                      # that problem on a placeholder 2 x 2 fabric
    tests: tuple[TestSpec, ...]
    fit: tuple[str, ...]
    values: dict[str, float]               # k_a, k_b, R_f (starting values, or held)
    clamp_width: float                     # mm: one clamp width (a test's width unit)
    forces: tuple[float, ...]
    strains: tuple[str, ...]
    min_loops: int
    sensitivities: str
    targets: dict[str, dict[str, float]]   # by use, by strain: the largest RMS error allowed
    beside: Path | None = None             # a spec whose model's figures are shown beside
    breaks: bool = False                   # also the table of where the model breaks (breaks.py)
    specimen: str = "clamped"              # SPECIMENS: clamped specimens or a periodic cell
    scan: bool = False                     # a single fitted value's start scanned (fit.py)
    cell_samples: int = CELL_SAMPLES       # a periodic cell's other-contact samples per loop
    bending_reference: str = "natural"     # a periodic cell's: "natural" or "straight"

    @property
    def spatial(self) -> bool:
        """The 3-D model ([yarn] geometry = "3d")."""
        return self.base.yarn is not None and self.base.yarn.spatial

    def test_name(self, k: int) -> str:
        return f"{self.name}_test{k + 1}"


def load_spec(path: Path | str) -> CalibrationSpec:
    """Read and check a calibration spec and its test files: a path, or a shipped spec's name
    (:func:`spec_path`)."""
    path = spec_path(str(path))
    return parse_spec(load_toml(path), path)


def spec_path(text: str) -> Path:
    """The spec file: a path, else the same name (with or without ``.toml``) under the named
    problems' folder, which an installed package carries (``knit_nlp.problems``)."""
    path = Path(text)
    try:
        if path.exists():
            return path
        for candidate in (problems_dir() / text, problems_dir() / f"{text}.toml"):
            if candidate.is_file():
                return candidate
    except (OSError, ValueError):        # a NUL or an over-long name: load_spec says so
        pass
    return path


def parse_spec(doc: dict[str, Any], source: Path | str) -> CalibrationSpec:
    """Check a parsed spec document (``source`` names it and anchors its test files)."""
    source = Path(source)
    top = Table(doc, source, "")
    for key, why in REFUSED.items():
        if top.has(key):
            raise top.error(key, f"not in a calibration spec: {why}")
    shared = {k: copy.deepcopy(v) for k, v in doc.items() if k not in OWN_TABLES}
    fabric = shared.pop("fabric", None)
    base = parse_problem({**shared, "fabric": {"courses": 2, "wales": 2}}, source)
    if base.units.force != "N":
        raise ProblemError(source, "units", "force", f"the tests' forces are in newtons "
                           f"(force_N); set force = \"N\" (got {quoted(base.units.force)})")
    if base.units.length != "mm":
        raise ProblemError(source, "units", "length", f"the clamp width and the yarn's measured "
                           f"values are in mm; set length = \"mm\" (got "
                           f"{quoted(base.units.length)})")
    fixed = _fabric(top) if fabric is not None else None
    cal = top.table("calibrate", required=True)
    if cal.has("length_scale") or (isinstance(cal.data.get("fit"), list)
                                   and "length_scale" in cal.data["fit"]):
        raise cal.error("length_scale" if cal.has("length_scale") else "fit", LENGTH_SCALE_GONE)
    spatial = base.yarn is not None and base.yarn.spatial
    fit = tuple(cal.strings("fit", choices=fittable(base)))
    if len(set(fit)) != len(fit):
        raise cal.error("fit", "lists a value twice")
    clamp_width = cal.number("clamp_width_mm", CLAMP_WIDTH_MM, positive=True)
    forces = tuple(cal.numbers("forces", list(METRIC_FORCES)))
    if not forces or any(f <= 0 for f in forces) or list(forces) != sorted(set(forces)):
        raise cal.error("forces", "must be positive forces in N, increasing, each once")
    strains = tuple(cal.strings("strains", list(STRAINS), choices=STRAINS))
    if not strains or len(set(strains)) != len(strains) or "axial" not in strains:
        raise cal.error("strains", "must list axial (and optionally lateral), each once")
    min_loops = cal.integer("min_loops", DEFAULT_MIN_LOOPS, minimum=2, maximum=MAX_LOOPS_SPEC)
    sens = cal.string("sensitivities", "curve_differences" if spatial else "implicit",
                      choices=SENSITIVITIES)
    if spatial and sens != "curve_differences":
        raise cal.error("sensitivities", f"{quoted(sens)} is not offered for the 3-D model "
                        "(its KKT sensitivities are not taken through the calibration yet); "
                        "write \"curve_differences\" or leave it out")
    specimen = _specimen(cal, base, fixed is not None)
    cell_samples = cal.integer("cell_samples", CELL_SAMPLES, minimum=24, maximum=200)
    if cal.has("cell_samples") and specimen != "periodic":
        raise cal.error("cell_samples", "samples a periodic cell's contacts: remove it, or "
                        "write specimen = \"periodic\"")
    reference = cal.string("bending_reference", "natural", choices=REFERENCES)
    if cal.has("bending_reference") and specimen != "periodic":
        raise cal.error("bending_reference", "chooses a periodic cell's bending reference (a "
                        "finite specimen bent from a straight yarn does not relax, "
                        "docs/weft3d.md): remove it, or write specimen = \"periodic\"")
    beside = _beside(cal, source)
    breaks = cal.boolean("breaks", False)
    scan = cal.boolean("scan", False)
    if scan and len(fit) != 1:
        raise cal.error("scan", f"scans the start of a single fitted value; this spec fits "
                        f"{len(fit)}: fit one value, or remove scan")
    targets = _targets(cal.table("targets"))
    cal.finish()
    tests = tuple(_read_test(t, source, base, fixed, min_loops, forces, specimen == "periodic")
                  for t in top.tables("test"))
    if not tests:
        raise top.error("test", "a calibration needs at least one [[test]] table")
    if len(tests) > MAX_TESTS:
        raise top.error("test", f"{len(tests)} tests; at most {MAX_TESTS}")
    if fit and not any(t.use == "fit" for t in tests):
        raise top.error("test", "fitting needs at least one test with use = \"fit\"")
    values = spec_values(base)
    zero = [n for n in fit if values[n] <= 0]
    if zero:
        raise ProblemError(source, "material", zero[0], "a fitted value starts from its "
                           "[material] value, which must be positive (the fit works on its "
                           "logarithm)")
    name = top.stem("name")
    return CalibrationSpec(name, top.string("description", ""), source, shared, base, tests,
                           fit, values, clamp_width, forces, strains, min_loops, sens, targets,
                           beside, breaks, specimen, scan, cell_samples, reference)


def spec_values(base: WeftProblem) -> dict[str, float]:
    """The material values a spec's problem gives: k_a, k_b, R_f, and in 3-D the yarn's
    compression law (``YARN_VALUES``): the fit's starting values, or held."""
    values = {"k_a": base.k_a, "k_b": base.k_b, "R_f": base.R_f}
    if base.yarn is not None and base.yarn.spatial:
        values.update({k: float(getattr(base.yarn, k)) for k in YARN_VALUES})
    return values


def fittable(base: WeftProblem) -> tuple[str, ...]:
    """The values a spec may fit: the planar model's k_a, k_b, R_f; in 3-D R_f and the
    contact rigidity, with k_a, k_b where the file turns the crossing springs on."""
    yarn = base.yarn
    if yarn is None or not yarn.spatial:
        return FITTABLE
    return (*SPATIAL_FITTABLE, *(("k_a", "k_b") if yarn.crossing_springs else ()))


def _specimen(cal: Table, base: WeftProblem, sized: bool) -> str:
    """``[calibrate] specimen``: "clamped" (default) or "periodic", the 3-D model's periodic
    cell, which has no size, no crossing springs and no friction (cell.py)."""
    kind = cal.string("specimen", "clamped", choices=SPECIMENS)
    if kind != "periodic":
        return kind
    yarn = base.yarn
    if yarn is None or not yarn.spatial:
        raise cal.error("specimen", "the periodic cell is the 3-D model's: set [yarn] geometry "
                        "= \"3d\", or write specimen = \"clamped\"")
    why = ("[yarn] crossing_springs = true (the cell has no crossing springs)"
           if yarn.crossing_springs else "[yarn] friction > 0 (the cell has no friction)"
           if yarn.friction > 0 else "[fabric] (a periodic cell has no size)" if sized else
           "min_loops (a periodic cell has no size)" if cal.has("min_loops") else None)
    if why is not None:
        raise cal.error("specimen", f"a periodic cell cannot take {why}: remove it, or write "
                        "specimen = \"clamped\"")
    return kind


def _beside(cal: Table, source: Path) -> Path | None:
    """``[calibrate] beside``: another calibration spec (a path relative to this one, or a
    shipped spec's name) on the same tests, whose model's figures are reported beside this
    one's (issue 40 item 4: the planar model's beside the 3-D model's); None without it."""
    text = cal.string("beside", None)
    if text is None:
        return None
    path = spec_path(str(source.parent / text))
    if not path.is_file():
        path = spec_path(text)
    if not path.is_file():
        raise cal.error("beside", f"no calibration spec {quoted(text)} (a path relative to "
                        "this spec, or a shipped spec's name)")
    if path.resolve() == source.resolve():
        raise cal.error("beside", "names this spec itself")
    return path


def _targets(tab: Table) -> dict[str, dict[str, float]]:
    """The verdict's targets: :data:`TARGETS` with the spec's ``[calibrate.targets]`` on top."""
    out = {use: dict(by_strain) for use, by_strain in TARGETS.items()}
    for use in USES:
        for strain in STRAINS:
            value = tab.number(f"{use}_{strain}", None, positive=True)
            if value is not None:
                out.setdefault(use, {})[strain] = value
    tab.finish()
    return out


def _fabric(top: Table) -> tuple[int, int]:
    """An explicit specimen size, used for every test instead of the aspect ratio."""
    tab = top.table("fabric")
    m, n = tab.integer("courses", minimum=2, maximum=MAX_LOOPS_SPEC * 5), tab.integer(
        "wales", minimum=1, maximum=MAX_LOOPS_SPEC * 5)
    tab.finish()
    return m, n


def _read_test(tab: Table, source: Path, base: WeftProblem, fixed: tuple[int, int] | None,
               min_loops: int, forces: tuple[float, ...], periodic: bool = False) -> TestSpec:
    """One ``[[test]]`` table and its file; a clamped specimen's loop counts from its aspect
    ratio (a periodic cell has none: 0 x 0)."""
    tab.allow("file", "format", "direction", "use", "width", "aspect")
    file = tab.string("file")
    fmt = tab.string("format", choices=FORMATS)
    direction = tab.string("direction", choices=DIRECTIONS)
    use = tab.string("use", choices=USES)
    width = tab.number("width", None, positive=True)
    aspect = tab.number("aspect", None, positive=True)
    tab.finish()
    measured = read_test(_resolve(source.parent, file, tab), file, fmt)
    check_reaches(measured, forces, "[calibrate] forces")
    if width is None and measured.width_clamps is None:
        raise tab.error("width", f"{quoted(file)} records no width (no clamp_size_px / "
                        "fabric_width_px comment line): give width = the specimen's width in "
                        "length units")
    if aspect is not None:
        source_name = "spec"
    elif measured.aspect is not None:
        aspect, source_name = measured.aspect, "pins"
    elif periodic:
        source_name = "none"
    elif fixed is None:
        raise tab.error("aspect", f"{quoted(file)} has no pin positions: give aspect = gauge "
                        "length / width, or the specimen's [fabric]")
    else:
        source_name = "fabric"
    if periodic:
        m, n = 0, 0
    elif fixed is not None:
        m, n = fixed
    else:
        m, n = loop_counts(base, direction, aspect, min_loops)
    return TestSpec(file, fmt, direction, use, measured, width, float(aspect or 0.0),
                    source_name, m, n, tab.name)


def _resolve(folder: Path, rel: str, tab: Table) -> Path:
    """A test file named in the spec: a relative path that stays inside the spec's folder
    (symbolic links followed), as for jacquard design files."""
    if not rel or "\0" in rel or Path(rel).is_absolute():
        raise tab.error("file", f"must be a relative path inside the spec's folder; got "
                        f"{quoted(rel)}")
    try:
        root = folder.resolve()
        path = (root / rel).resolve()
    except (OSError, RuntimeError) as err:
        raise tab.error("file", f"cannot resolve {quoted(rel)} ({quoted(err)})") from None
    if not path.is_relative_to(root):
        raise tab.error("file", f"{quoted(rel)} leads outside the spec's folder; test files "
                        "must lie in it or below it")
    return path
