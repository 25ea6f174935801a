"""``<name>.calibration.png``: per test, measured strains against force as a band (median and
range over runs) and the model's curve, axial and lateral; fitted tests drawn solid, predicted
ones dashed, on the same colours (blue axial, orange lateral). It reads a
``result.CalibrationResult`` (and its ``TestOutcome``s) without importing it: the result module
imports this one to save itself."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ....figures import new_figure, save_figure
from .metric import levels

COLOURS = {"axial": "tab:blue", "lateral": "tab:orange"}
BAND_POINTS = 150


def _panel(ax, t: Any, other: Any = None, other_name: str = "") -> None:
    measured = t.test.measured
    forces = np.linspace(0.0, measured.common_force, BAND_POINTS)
    style = "-" if t.test.use == "fit" else "--"
    kinds = ("axial", "lateral") if measured.has_lateral else ("axial",)
    right = max(measured.max_force, t.metric.forces[-1]) * 1.02
    for kind in kinds:
        runs = levels(measured, forces, lateral=kind == "lateral")
        colour = COLOURS[kind]
        ax.fill_between(forces, runs.min(axis=0), runs.max(axis=0), color=colour, alpha=0.2,
                        lw=0, label=f"measured {kind}: range of {len(measured.runs)} runs")
        ax.plot(forces, np.median(runs, axis=0), color=colour, lw=1.0, ls=":",
                label=f"measured {kind}: median")
        model = t.curve.sample_axial if kind == "axial" else t.curve.sample_lateral
        what = "model on a fit test" if t.test.use == "fit" else "model, predicted (held out)"
        shown = t.curve.sample_force <= right       # (the curve may run on past the data)
        ax.plot(t.curve.sample_force[shown], model[shown], color=colour, lw=2.0, ls=style,
                label=f"{what} ({kind})")
        if other is not None and len(other.curve.sample_force):
            o_model = other.curve.sample_axial if kind == "axial" else other.curve.sample_lateral
            o_shown = other.curve.sample_force <= right
            ax.plot(other.curve.sample_force[o_shown], o_model[o_shown], color=colour, lw=1.0,
                    ls="-.", alpha=0.7, label=f"{other_name} ({kind})")
        points = t.metric.measured_axial if kind == "axial" else t.metric.measured_lateral
        ax.plot(t.metric.forces, points, "o", ms=4, mfc="white", color=colour)
    first = t.check.get("first_not_clean") if t.check else None
    if first is not None and first["force_N"] <= right:
        ax.plot(first["force_N"], first["axial_strain"], "x", color="k", ms=8, mew=1.5,
                label="first model answer the check finds not clean (axial)")
    ax.axhline(0.0, color="0.6", lw=0.5)
    ax.set_xlabel("force (N)")
    ax.set_ylabel("strain (–)")
    ax.set_xlim(0.0, right)
    rms = t.metric
    lat = "" if rms.rms_lateral is None else f", lateral {rms.rms_lateral:.3f}"
    axial = "n/a" if rms.rms_axial is None else f"{rms.rms_axial:.3f}"
    state = "" if t.complete else f"\nmodel curve stops: {t.reason}"      # wrapped, not cut
    ax.set_title(f"{t.test.file}: pulled along the {t.test.direction} ({t.test.use})\n"
                 f"model: {t.specimen.label}; rms strain error axial "
                 f"{axial}{lat}{state}\n{_checks_line(t.checks)}\n{_other_line(other, other_name)}"
                 f"{t.verdict()}\n{t.check_line()}", fontsize=8, wrap=True)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.17), ncol=2)
    ax.grid(alpha=0.3)


def _other_line(other: Any, name: str) -> str:
    """The other model's figures on the same test, for a panel's title ('' without one)."""
    if other is None:
        return ""
    show = lambda v, f=".3g": "n/a" if v is None else format(v, f)     # noqa: E731
    c = other.checks["model"]
    lat = other.metric.rms_lateral
    return (f"{name}: rms axial {show(other.metric.rms_axial, '.3f')}"
            + ("" if lat is None else f", lateral {lat:.3f}")
            + f"; F(10%) {show(c['force_N']['0.1'])}, F(30%) {show(c['force_N']['0.3'])} N; "
              f"stiffening {show(c['stiffening'])}\n")


def _checks_line(c: dict[str, Any]) -> str:
    """Model (measured) force at 10 and 30 % strain and stiffening, for a panel's title."""
    show = lambda v, f=".3g": "n/a" if v is None else format(v, f)     # noqa: E731
    forces = ", ".join(f"F({float(e):.0%}) {show(c['model']['force_N'][e])} "
                       f"({show(c['measured']['force_N'][e])}) N" for e in c["model"]["force_N"])
    return (f"model (measured): {forces}; stiffening 5->45% {show(c['model']['stiffening'])} "
            f"({show(c['measured']['stiffening'])})")


def plot_calibration(path: Path, result: Any) -> Path:
    """One panel per test (module doc); circles: the measured medians the metric uses."""
    n = len(result.tests)
    cols = min(n, 2)
    rows = (n + cols - 1) // cols
    fig = new_figure(figsize=(6.4 * cols, 5.6 * rows + 0.6), constrained_layout=True)
    axes = fig.subplots(rows, cols, squeeze=False)
    beside = getattr(result, "beside", None)
    others = {} if beside is None else {o.test.file: o for o in beside.tests}
    name = "" if beside is None else (
        f"beside: {beside.name} ({'3-D' if beside.spec.spatial else 'planar'} model, dash-dot)")
    for ax, t in zip(axes.ravel(), result.tests):
        _panel(ax, t, others.get(t.test.file), name)
    for ax in axes.ravel()[n:]:
        ax.set_visible(False)
    units = result.spec.base.units
    vals = ", ".join(
        f"{k} = {v['value']:.4g}" + (" (fitted)" if v["fitted"] else "")
        for k, v in result.parameters().items())
    ratio = ""
    for key, r in result.checks().items():
        if r is not None and key.startswith("wale_over_course"):
            show = lambda v: "n/a" if v is None else f"{v:.3g}"     # noqa: E731
            ratio = (f"; wale / course stiffness per width at 10 % strain: model "
                     f"{show(r['model'])}, measured {show(r['measured'])}")
    fig.suptitle(f"{result.name}: {vals}; clamp width {result.spec.clamp_width:g} {units.length}"
                 f"\n({_units(result)}; circles: measured medians at the metric forces)"
                 f"{ratio}{_beside_ratio(result)}", fontsize=9)
    return save_figure(fig, path, dpi=110)


def _beside_ratio(result: Any) -> str:
    """The other model's wale / course stiffness ratio, for the figure's title."""
    beside = result.checks().get("beside")
    if not beside:
        return ""
    r = next((v for k, v in beside.items() if k.startswith("wale_over_course")), None)
    shown = "n/a" if r is None or r["model"] is None else f"{r['model']:.3g}"
    return f"; {beside['name']} ({beside['geometry']}): {shown}"


def _units(result: Any) -> str:
    """The units of the values in the figure's title (those the model uses)."""
    u = result.spec.base.units
    f, length = u.force, u.length
    if not result.spec.spatial:
        return f"k_a, k_b in {f}/{length}, R_f in {f}·{length}²"
    return (f"R_f in {f}·{length}², radius and core_radius in {length}, contact_rigidity in "
            f"{f}/{length}³")
