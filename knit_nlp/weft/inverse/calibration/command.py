"""``knit-nlp calibrate SPEC.toml [--out DIR]``: the command-line door to :func:`calibrate`.

Exit codes as every command: 0 the fit converged and every test is within its targets
(``spec.TARGETS``, or the spec's ``[calibrate.targets]``); 1 otherwise, as for a solve that did
not converge (files still written, ``"success": false``); 2 a bad spec or test file (one line,
nothing written). The summary ends with the verdict, one line per test.
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from ....outdir import prepare_out
from ....progress import end_lines
from ....provenance import check_overwrite
from .calibrate import calibrate
from .checks import describe
from .result import CalibrationResult
from .spec import load_spec


def run(args: argparse.Namespace) -> int:
    """Read and check everything, then solve, then write: bad input writes nothing."""
    spec = load_spec(args.spec)
    if getattr(args, "breaks", False):
        spec = replace(spec, breaks=True)
    out = prepare_out(args.out, spec.name, ("calibration", "curves"))
    check_overwrite(out.glob(f"{spec.name}.calibration.json"), spec.source, args.force)
    result = calibrate(spec, progress=_progress)
    paths = result.save(out)
    print(summary(result, paths))
    return 0 if result.success else 1


def _progress(line: str) -> None:
    """A progress line on stderr (the summary and verdict go to stdout), on a line of its own:
    an IPOPT progress line still open there is ended first (the breaks' lines were glued onto
    the last solve's iterate line)."""
    end_lines()
    print(f"calibrate: {line}", file=sys.stderr, flush=True)


def summary(result: CalibrationResult, paths: list[Path]) -> str:
    """What the command prints: values with standard errors, per test the metric."""
    lines = [f"{result.name}: {result.status} ({result.nit} evaluations, "
             f"{result.timings['total_s']:.1f} s, {result.timings['forward_solves']} forward "
             f"solves)"]
    for name, row in result.parameters().items():
        measured = f"; measured {row['measured']:.4g}" if "measured" in row else ""
        if row["fitted"]:
            se = row.get("std_error")
            err = "undetermined" if se is None else f"± {se:.3g}"
            start = "" if measured else f"; from {row['initial']:.4g}"
            lines.append(f"  {name} = {row['value']:.6g} {err} (fitted{start}{measured})")
            lines += _scan_lines(result)
        else:
            lines.append(f"  {name} = {row['value']:.6g} (held{', measured' if measured else ''})")
    given = result.given()
    lines.append(f"  clamp width {given['clamp_width_mm']:g} mm ({given['clamp_width_source']}); "
                 f"loop length {given['loop_length_mm']:g} mm (held)")
    for t in result.tests:
        m = t.metric
        lat = "" if m.rms_lateral is None else f", lateral {m.rms_lateral:.4f}"
        axial = "n/a" if m.rms_axial is None else f"{m.rms_axial:.4f}"
        state = "" if t.complete else f"  [model curve incomplete: {t.reason}]"
        lines.append(f"  {t.test.file} ({t.test.use}, {t.test.direction}, "
                     f"{t.specimen.label}): rms strain error axial {axial}{lat}{state}")
        lines.append(f"    checks: {describe(t.checks)}")
        lines.append(f"    {t.check_line()}")
    for key, ratio in result.checks().items():
        if ratio is not None and key.startswith("wale_over_course"):
            show = lambda v: "n/a" if v is None else f"{v:.3g}"     # noqa: E731
            lines.append(f"  {key.replace('_', ' ')}: {show(ratio['model'])} (measured "
                         f"{show(ratio['measured'])})")
    lines += figures_lines(result)
    lines += breaks_lines(result)
    for w in (result.fit.warnings if result.fit is not None else []):
        lines.append(f"  warning: {w}")
    lines.append(f"  wrote {', '.join(str(p) for p in paths)}")
    lines.append("verdict:" if result.fit is None or result.fit.success
                 else f"verdict (the fit did not converge: {result.fit.status}):")
    lines += [f"  {t.verdict()}" for t in result.tests]
    return "\n".join(lines)


def breaks_lines(result: CalibrationResult) -> list[str]:
    """With ``[calibrate] breaks`` (or ``--breaks``): where the model breaks (issue 40 item 5,
    ``breaks``), the Markdown table docs/real_fabric.md shows."""
    if result.breaks is None:
        return []
    return ([f"  where the model breaks: each measured value alone, times each factor, from "
             f"the answer; nothing re-fitted ({result.breaks.seconds:.0f} s):"]
            + [f"    {row}" for row in result.breaks.markdown()])


def figures_lines(result: CalibrationResult) -> list[str]:
    """With ``[calibrate] beside``: a table of what a researcher checks first (issue 40 item
    4), this model's row beside the other's and the measured one, per test."""
    if result.beside is None:
        return []
    show = lambda v, f=".3g": "n/a" if v is None else format(v, f)     # noqa: E731
    rows = [("model", result.figures()), ("beside", result.beside.figures())]
    key = next(k for k in result.checks() if k.startswith("wale_over_course"))
    out = [f"  figures, model beside model (measured last): rms axial, lateral; F(10%), "
           f"F(30%) N; stiffening 5 -> 45%"]
    for k, t in enumerate(result.tests):
        axis = "x" if t.test.direction == "courses" else "y"
        for _, fig in rows:
            f = fig["tests"][k] if k < len(fig["tests"]) else None
            if f is None or f["file"] != t.test.file:
                continue
            c, e = f["checks"]["model"], f["rms_strain_error"]
            out.append(f"    {axis} {fig['geometry']:>6} {fig['name']} ({f['use']}, "
                       f"{_size(f)}): {show(e['axial'], '.4f')}, "
                       f"{show(e['lateral'], '.4f')}; {show(c['force_N']['0.1'])}, "
                       f"{show(c['force_N']['0.3'])}; {show(c['stiffening'])}")
        m = t.checks["measured"]
        out.append(f"    {axis} measured: {show(m['force_N']['0.1'])}, "
                   f"{show(m['force_N']['0.3'])}; {show(m['stiffening'])}")
    ratios = [(fig["geometry"], fig[key]) for _, fig in rows]
    if all(r is not None for _, r in ratios):
        out.append("    wale / course stiffness per width at 10%: " + ", ".join(
            f"{g} {show(r['model'])}" for g, r in ratios)
            + f" (measured {show(ratios[0][1]['measured'])})")
    return out


def _size(figure: dict) -> str:
    """A figures row's specimen: "3 x 5" (loops) or "periodic cell"."""
    if figure.get("specimen") == "periodic":
        return "periodic cell"
    return f"{figure['courses']} x {figure['wales']}"


def _scan_lines(result: CalibrationResult) -> list[str]:
    """The scan of a single fitted value's start (``[calibrate] scan``): where the least
    squares started."""
    tried = result.fit.scan if result.fit is not None else []
    if not tried:
        return []
    best = min(tried, key=lambda t: t[1])
    return [f"    start scanned at {len(tried)} values {tried[0][0]:.4g} to {tried[-1][0]:.4g}: "
            f"best rms strain residual {best[1]:.4g} at {best[0]:.4g}"]
