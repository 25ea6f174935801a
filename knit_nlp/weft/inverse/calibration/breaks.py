"""Where the model breaks (issue 40 item 5): how far each measured value would have to move,
alone, from the calibration's answer for the model to meet each target.

From the answer (the fitted values where they landed, everything else as the spec holds it),
one measured value at a time is set to its answer times each factor of its scan and every test
is evaluated again as in the final evaluation (``Calibration.outcome``: the same curve, metric
and checks); nothing is re-fitted. The measured values are those the model uses and the spec
holds: the yarn's radius (with ``[yarn]``), its bending modulus R_f, in 3-D the compression
law's core radius and exponent, the loop length (the stitch length), and the clamp width (where
a test's width is given in clamp widths). A value the spec fits is not scanned. The specimens
keep their loop counts: only the value moves.

The targets are those of the verdict (``spec.TARGETS``: each test's RMS strain errors) and
issue 40's two checks where the test measured them (``CHECK_TARGETS``): the tangent stiffening
5 % -> 45 % within 30 % of the measured one, and the force at 30 % strain within 20 %. Per
value and target the table gives the scan's factor nearest 1 (in log) at which the target is
met, with the factor before it that missed (the bracket), or "not met" with the best figure any
factor reached. A factor at which the problem refuses the value, or the model cannot be built
(``errors``: why), counts as missed and is named in the table ("no model at").
docs/real_fabric.md, "Where the model breaks".
"""
from __future__ import annotations

import copy
import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ....errors import ProblemError
from ...model.problem import parse_problem
from .result import DIRECTION_AXIS
from .spec import YARN_VALUES, CalibrationSpec, spec_values

if TYPE_CHECKING:
    from .result import CalibrationResult, TestOutcome

FACTORS = (0.5, 0.7, 1.4, 2.0, 4.0)     # each value times these, alone
# The core radius sits at the compression fit's bound (1e-4 mm: no core within the tests), so
# factors of it say nothing; its scan is fractions of the yarn's radius, up to the source's own
# 0.325 mm of 0.74 (0.44) and past it.
CORE_FRACTIONS = (0.05, 0.2, 0.44, 0.7)
# issue 40's targets on the checks (checks.py), relative to the measured value: (name, the
# figure's keys in a test's checks, largest relative miss)
CHECK_TARGETS = (("stiffening", ("stiffening",), 0.30), ("F(30%)", ("force_N", "0.3"), 0.20))
LABELS = {"radius": ("radius", "mm"), "R_f": ("R_f", "N mm²"),
          "core_radius": ("core radius", "mm"), "contact_exponent": ("contact exponent", ""),
          "loop_length": ("loop length", "mm"), "clamp_width": ("clamp width", "mm")}


@dataclass(frozen=True)
class Target:
    """One target of one test: an RMS strain error at most ``limit`` (``kind`` "rms"), or a
    check within ``limit`` of its measured value (``kind`` "ratio": model over measured)."""

    test: int
    kind: str
    what: str                       # the strain ("axial") or the check ("stiffening", "F(30%)")
    limit: float
    label: str

    def figure(self, t: "TestOutcome") -> float | None:
        """The outcome's figure for this target (None: the model did not give it)."""
        if self.kind == "rms":
            return t.errors().get(self.what)
        model, measured = (_check(t.checks[side], self.what) for side in ("model", "measured"))
        return None if model is None or not measured else model / measured

    def met(self, figure: float | None) -> bool:
        if figure is None:
            return False
        return figure <= self.limit if self.kind == "rms" else abs(figure - 1.0) <= self.limit

    def miss(self, figure: float | None) -> float:
        """How far a figure is from meeting the target (for the best one)."""
        if figure is None:
            return np.inf
        return figure if self.kind == "rms" else abs(figure - 1.0)


def _check(side: dict[str, Any], what: str) -> float | None:
    """The check ``what`` (a name of CHECK_TARGETS) of one side of a test's checks."""
    value: Any = side
    for key in dict((n, keys) for n, keys, _ in CHECK_TARGETS)[what]:
        value = value[key]
    return value


def targets(outcomes: list["TestOutcome"]) -> list[Target]:
    """Every test's verdict targets, then issue 40's checks where the test measured them."""
    out = []
    for k, t in enumerate(outcomes):
        axis = DIRECTION_AXIS[t.test.direction]
        for strain, limit in t.targets.items():
            out.append(Target(k, "rms", strain, limit, f"{axis} {strain} RMS ≤ {limit:g}"))
        for what, _, limit in CHECK_TARGETS:
            if _check(t.checks["measured"], what) is not None:
                out.append(Target(k, "ratio", what, limit, f"{axis} {what} within {limit:.0%}"))
    return out


def measured_names(spec: CalibrationSpec) -> tuple[str, ...]:
    """The measured values the model uses and the spec holds (module doc)."""
    names = ["radius"] if spec.base.yarn is not None else []
    names.append("R_f")
    if spec.spatial:
        names += ["core_radius", "contact_exponent"]
    names.append("loop_length")
    if any(t.width is None for t in spec.tests):
        names.append("clamp_width")
    return tuple(n for n in names if n not in spec.fit)


def answer_value(result: "CalibrationResult", name: str) -> float:
    """A measured value at the calibration's answer."""
    spec = result.spec
    if name == "loop_length":
        return float(spec.base.L)
    if name == "clamp_width":
        return float(spec.clamp_width)
    if name == "radius" and not spec.spatial:
        return float(spec.base.yarn.radius)
    return float(result.values[name])


def scan_factors(result: "CalibrationResult", name: str,
                 factors: tuple[float, ...] | None = None) -> tuple[float, ...]:
    """The factors a value is scanned over: ``factors`` or FACTORS, the core radius's
    CORE_FRACTIONS of the radius."""
    if factors is not None:
        return tuple(factors)
    if name == "core_radius":
        core, radius = answer_value(result, name), answer_value(result, "radius")
        return tuple(f * radius / core for f in CORE_FRACTIONS)
    return FACTORS


def moved_spec(result: "CalibrationResult", name: str, value: float) -> CalibrationSpec:
    """The spec at the answer with one measured value set to ``value``: every value the model
    uses written into its tables (so that none follows the moved one: a core radius left out
    would follow the radius), nothing fitted, the tests and their loop counts kept.
    ProblemError when the problem refuses the value."""
    spec = result.spec
    if name == "clamp_width":
        return replace(spec, values=dict(result.values), fit=(), beside=None, breaks=False,
                       clamp_width=value)
    doc = copy.deepcopy(spec.doc)
    for key in result.reported():
        table = "yarn" if key in YARN_VALUES else "material"
        doc.setdefault(table, {})[key] = result.values[key]
    if name == "loop_length":
        doc.setdefault("loop", {})["length"] = value
    elif name == "radius" and not spec.spatial:
        doc["yarn"]["radius"] = value
    else:
        doc["yarn" if name in YARN_VALUES else "material"][name] = value
    base = parse_problem({**doc, "fabric": {"courses": 2, "wales": 2}}, spec.source)
    return replace(spec, doc=doc, base=base, values=spec_values(base), fit=(), beside=None,
                   breaks=False)


@dataclass
class ValueScan:
    """One measured value's scan: its answer, and per factor the targets' figures."""

    name: str
    answer: float
    factors: tuple[float, ...]
    figures: list[list[float | None]]      # per factor (the answer's first, factor 1), per target
    errors: list[str]                      # per factor: why nothing was evaluated ("" if it was)

    def all_factors(self) -> tuple[float, ...]:
        return (1.0, *self.factors)

    def cell(self, q: int, target: Target) -> dict[str, Any]:
        """Target ``q``: the factor nearest 1 meeting it, with its bracket, or the best one."""
        qs = self.all_factors()
        figs = [row[q] for row in self.figures]
        met = [k for k, f in enumerate(figs) if target.met(f)]
        out: dict[str, Any] = {"target": target.label, "answer_figure": figs[0]}
        if met:
            k = min(met, key=lambda j: abs(np.log(qs[j])))
            side = [j for j in range(len(qs)) if (qs[j] - 1.0) * (qs[k] - 1.0) >= 0
                    and abs(np.log(qs[j])) < abs(np.log(qs[k]))]
            missed = max(side, key=lambda j: abs(np.log(qs[j])), default=0)
            out.update(met=True, factor=qs[k], value=self.answer * qs[k], figure=figs[k],
                       missed_factor=qs[missed] if k else None)
            return out
        best = min(range(len(qs)), key=lambda j: target.miss(figs[j]))
        out.update(met=False, best_factor=qs[best] if figs[best] is not None else None,
                   best_figure=figs[best])
        return out

    def to_json(self, targets_: list[Target]) -> dict[str, Any]:
        label, unit = LABELS[self.name]
        return {"value": self.name, "label": label, "unit": unit, "answer": self.answer,
                "points": [{"factor": q, "value": self.answer * q, "error": e or None,
                            "figures": dict(zip((t.label for t in targets_), row))}
                           for q, row, e in zip(self.all_factors(), self.figures,
                                                ["", *self.errors])],
                "targets": [self.cell(q, t) for q, t in enumerate(targets_)]}


@dataclass
class Breaks:
    """The table: one scan per measured value over the same targets."""

    targets: list[Target]
    scans: list[ValueScan]
    seconds: float = 0.0

    def to_json(self) -> dict[str, Any]:
        return {"targets": [{"label": t.label, "test": t.test, "kind": t.kind, "what": t.what,
                             "limit": t.limit} for t in self.targets],
                "values": [s.to_json(self.targets) for s in self.scans],
                "seconds": self.seconds,
                "how": "one measured value at a time times each factor from the answer, "
                       "nothing re-fitted; figures: RMS strain error, or model over measured"}

    def markdown(self) -> list[str]:
        """The table in Markdown (the summary prints it; docs/real_fabric.md shows it)."""
        head = "| measured value (answer) | scan (factors) | " + " | ".join(
            t.label for t in self.targets) + " |"
        rows = [head, "|" + "---|" * (len(self.targets) + 2)]
        for s in self.scans:
            label, unit = LABELS[s.name]
            qs = s.factors
            scan = f"× {_g(min(qs))} .. {_g(max(qs))} ({len(qs)})"
            cells = [_cell(s.cell(q, t), t, unit) for q, t in enumerate(self.targets)]
            refused = [f"×{_g(q)}" for q, e in zip(qs, s.errors) if e]
            note = f"; no model at {', '.join(refused)}" if refused else ""
            answer = f"{s.answer:.4g}" + (f" {unit}" if unit else "")
            rows.append(f"| {label} ({answer}) | {scan}{note} | "
                        + " | ".join(cells) + " |")
        return rows


def _g(q: float) -> str:
    return f"{q:.3g}"


def _fig(f: float | None, target: Target) -> str:
    if f is None:
        return "n/a"
    return f"{f:.3g}" if target.kind == "rms" else f"{f:.3g}× measured"


def _cell(c: dict[str, Any], target: Target, unit: str) -> str:
    if c["met"] and c["factor"] == 1.0:
        return f"met at the answer ({_fig(c['figure'], target)})"
    if c["met"]:
        value = f"{c['value']:.3g}" + (f" {unit}" if unit else "")
        return (f"met at ×{_g(c['factor'])} = {value} ({_fig(c['figure'], target)}; missed at "
                f"×{_g(c['missed_factor'])})")
    if c["best_factor"] is None:
        return "not met (n/a: no curve reaches every force)" if target.kind == "rms" else (
            "not met (n/a: no model curve reaches the strain)")
    return f"not met (best {_fig(c['best_figure'], target)} at ×{_g(c['best_factor'])})"


Evaluate = Callable[[CalibrationSpec], list["TestOutcome"]]


def where_it_breaks(result: "CalibrationResult", evaluate: Evaluate,
                    names: tuple[str, ...] | None = None,
                    factors: tuple[float, ...] | None = None,
                    progress: Callable[[str], None] | None = None) -> Breaks:
    """The table of ``result`` (module doc): ``evaluate(spec)`` every test of a spec at its
    values as the final evaluation makes it (``calibrate.evaluate``), ``names`` the values to
    scan (default :func:`measured_names`), each over ``factors`` (default
    :func:`scan_factors`)."""
    say = progress or (lambda line: None)
    t0 = time.perf_counter()
    targets_ = targets(result.tests)
    names = measured_names(result.spec) if names is None else names
    base = [target.figure(result.tests[target.test]) for target in targets_]
    scans = []
    total = sum(len(scan_factors(result, n, factors)) for n in names)
    done = 0
    for name in names:
        answer = answer_value(result, name)
        qs = scan_factors(result, name, factors)
        figures, errors = [base], []
        for q in qs:
            done += 1
            say(f"breaks: {LABELS[name][0]} × {q:.3g} ({done} of {total}), "
                f"{time.perf_counter() - t0:.0f} s")
            try:
                outcomes = evaluate(moved_spec(result, name, answer * q))
            except (ProblemError, ValueError, RuntimeError) as err:
                # the problem refuses the value (ProblemError), or the model cannot be built
                # or solved there (a radius ×0.7 in 3-D: the natural loops' projections no
                # longer cross, ValueError): reported in the table, the scan goes on
                figures.append([None] * len(targets_))
                errors.append(str(err) if isinstance(err, ProblemError)
                              else f"{type(err).__name__}: {err}")
                continue
            figures.append([t.figure(outcomes[t.test]) for t in targets_])
            errors.append("")
        scans.append(ValueScan(name, answer, qs, figures, errors))
    return Breaks(targets_, scans, time.perf_counter() - t0)
