"""The acrylic yarn's soft-shell compression law fitted on its compression tests (issue 40 item 2).

    python scripts/fit_compression.py                       # every sample, the whole loading ramp
    python scripts/fit_compression.py --max-force 1         # only up to 1 N
    python scripts/fit_compression.py --contact-length-mm 5 --out results

Reads ``problems/real_fabric/yarn_compression/`` (stitch-by-stitch ``compressionTests.xls``,
sheets acrylic-1..3 and ``Yarn Diameters``, MIT licence beside them; ``SOURCE.md`` there) and
fits ``SoftShell`` (``knit_nlp/weft/model/compression.py``) through the test's geometry, a yarn
segment between two flat plates (``knit_nlp/weft/inverse/calibration/compression_fit.py``:
force = ℓ·F∥(g₀ − travel), eq. P2): each sample alone, then all of them pooled (one law, one
g₀ per sample). The outer radius is held at half the sample's free diameter. Printed per fit:
the core radius R_c, k·ℓ (the rigidity times the contact length, which is all the force level
says; ℓ is not recorded), the exponent p, the gaps g₀, each ± its standard error, and the RMS
of log(model / measured force). With ``--contact-length-mm`` also the rigidity k itself.
With ``--out`` writes ``yarn_compression_fit.png`` (measured points and the fitted laws, force
on a log axis against the plates' travel) and ``yarn_compression_fit.json``.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from knit_nlp.figures import new_figure, save_figure  # noqa: E402
from knit_nlp.weft.inverse.calibration.compression_fit import (MIN_FORCE, CompressionFit,  # noqa: E402
                                                                Sample, fit_compression,
                                                                read_sample)

DATA = ROOT / "problems" / "real_fabric" / "yarn_compression"


def samples(folder: Path, max_force: float | None) -> list[Sample]:
    """Every ``acrylic_<n>.csv`` with its free diameter from ``yarn_diameters.csv``."""
    with open(folder / "yarn_diameters.csv", newline="") as fh:
        rows = csv.DictReader(line for line in fh if not line.startswith("#"))
        diameters = {r["sample"]: float(r["acrylic_mm"]) for r in rows}
    return [read_sample(folder / f"acrylic_{n}.csv", d, max_force)
            for n, d in sorted(diameters.items())]


def _pm(value: float, se: float | None) -> str:
    return f"{value:.4g} ({'bound' if se is None else f'± {se:.2g}'})"


def describe(label: str, fit: CompressionFit, contact_length: float | None) -> str:
    v, se = fit.values, fit.std_errors
    gaps = ", ".join(f"{n}: {_pm(v[f'gap0_{n}'], se[f'gap0_{n}'])}" for n in fit.samples)
    k = ("" if contact_length is None else
         f"; k = {v['rigidity_length'] / contact_length:.4g} N/mm³ at ℓ = {contact_length:g} mm")
    lines = [f"{label}: R = {', '.join(f'{r:g}' for r in fit.radii)} mm (held: free diameter / 2); "
             f"R_c = {_pm(v['core_radius'], se['core_radius'])} mm; k·ℓ = "
             f"{_pm(v['rigidity_length'], se['rigidity_length'])} N/mm²{k}; p = "
             f"{_pm(v['exponent'], se['exponent'])}",
             f"    g0 (mm) {gaps}; rms log(model/measured) {fit.rms_log:.3f} over {fit.points} points"]
    lines += [f"    warning: {w}" for w in fit.warnings]
    return "\n".join(lines)


def exponential(s: Sample) -> str:
    """What the data show without a law: log F against the travel, a straight line?"""
    slope, icpt = np.polyfit(s.travel, np.log(s.force), 1)
    rms = np.sqrt(np.mean((icpt + slope * s.travel - np.log(s.force)) ** 2))
    return (f"force ∝ exp(travel / {1 / slope:.3f} mm), rms log {rms:.3f} (a two-parameter "
            "exponential, for comparison)")


def plot(path: Path, data: list[Sample], singles: list[CompressionFit], pooled: CompressionFit,
         max_force: float | None) -> Path:
    fig = new_figure(figsize=(7.5, 5.2), constrained_layout=True)
    ax = fig.subplots()
    for k, (s, single) in enumerate(zip(data, singles)):
        colour = f"C{k}"
        ax.plot(s.travel, s.force, ".", ms=2.5, color=colour,
                label=f"{s.name}: measured (free diameter {s.free_diameter:g} mm)")
        t = np.linspace(s.travel.min(), s.travel.max(), 300)
        ax.plot(t, single.model_force(0, t), "-", color=colour, lw=1.5,
                label=f"{s.name}: law fitted alone (rms log {single.rms_log:.2f})")
        ax.plot(t, pooled.model_force(k, t), "--", color=colour, lw=1.0,
                label=f"{s.name}: pooled law (rms log {pooled.rms_log:.2f} over all)")
    ax.set_yscale("log")
    ax.set_xlabel("plates' travel c from the machine's start (mm); gap g = g0 − c")
    ax.set_ylabel("force on the plates (N)")
    top = "the largest force" if max_force is None else f"{max_force:g} N"
    ax.set_title("acrylic yarn between flat plates: force = k·ℓ · F∥(g; R, R_c, p) (eq. P2)\n"
                 f"fitted from {MIN_FORCE * 1000:g} mN to {top}; R held at free diameter / 2",
                 fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    ax.grid(alpha=0.3, which="both")
    return save_figure(fig, path, dpi=110)


def _json(fit: CompressionFit) -> dict:
    return {"samples": fit.samples, "radius_mm": fit.radii, "values": fit.values,
            "std_errors": fit.std_errors, "at_bound": fit.at_bound, "rms_log": fit.rms_log,
            "points": fit.points, "warnings": fit.warnings}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--max-force", type=float, default=None,
                        help="fit only up to this force (N); default: the whole loading ramp")
    parser.add_argument("--contact-length-mm", type=float, default=None,
                        help="the contact length ℓ along the yarn, to print k = (k·ℓ)/ℓ")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    data = samples(args.data, args.max_force)
    singles = [fit_compression([s]) for s in data]
    for s, fit in zip(data, singles):
        print(describe(f"{s.name} alone", fit, args.contact_length_mm))
        print(f"    the data alone: {exponential(s)}")
    pooled = fit_compression(data)
    print(describe("pooled", pooled, args.contact_length_mm))
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        png = plot(args.out / "yarn_compression_fit.png", data, singles, pooled, args.max_force)
        doc = {"max_force_N": args.max_force, "min_force_N": MIN_FORCE,
               "singles": [_json(f) for f in singles], "pooled": _json(pooled)}
        js = args.out / "yarn_compression_fit.json"
        js.write_text(json.dumps(doc, indent=1))
        print(f"wrote {png}, {js}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
