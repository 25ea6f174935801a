"""This project's periodic cell against stitch-by-stitch's own simulation of the same cell.

The source (Singal et al. 2024, ``code/fabric_simulations/stockinette.py``) minimises, per
stitch cell of width x (along the courses) with its height y free,

    E_s = B ∫ κ² ds + ε ∫ |d(κn)/ds|² ds + Σ_i Σ_j v(d_ij) ds_i ds_j

(its splines' ``energy``: ``bendMod · curv²`` with no ½, ``reg`` = ε the curvature
regularisation; its ``contact_energy`` visits every pair of pieces twice). This project's
cell (``periodic.py``) minimises ½ R_f ∫ κ² ds + k ∫∫ v (each pair once). The same energy
without the regularisation is therefore R_f = 2B and k = 2 k_s: ``source_yarn`` writes the
source's settings so. Bent from a straight yarn, as the source's, every contact sees the yarn's
own law (``periodic.wrap_thinning``).

The shipped sweep (problems/real_fabric/source_simulation/core300x.csv, the source's sample
``core300x.zip``: core radius 0.3 mm, x from 2.8 to 5.32 mm) is read at its lowest energy
over the four initialisations at each x. The cell is relaxed (x and y free), then solved at
each x with y free, each from the last. Printed per x: the source's y and energies beside
the cell's; then the force through one cell, the source's by differences of its energy
(dE/dx between neighbouring x), the cell's the pull row's multiplier (averaged over the same
two x); and both at the real course specimen's width (``course_width``: 66.56 mm), strain
from x = 2.8 mm.

    python scripts/source_cell.py [--thinned] [--to 5.35] [--samples 80] [--out DIR]

``--thinned`` builds the cell with the law thinned at the natural wraps (C3), the choice before
the straight yarn's cell saw the yarn's own law, for comparison. ``--out DIR`` also sweeps the
other choice and draws both beside the source (``DIR/source_cell.png``).
"""
from __future__ import annotations

import argparse
import csv
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from knit_nlp.weft.inverse.calibration.measured import read_stitch_by_stitch  # noqa: E402
from knit_nlp.weft.inverse.calibration.spec import CLAMP_WIDTH_MM  # noqa: E402
from knit_nlp.weft.model.problem import parse_problem  # noqa: E402
from knit_nlp.weft.model.spatial import periodic  # noqa: E402

SWEEP = ROOT / "problems" / "real_fabric" / "source_simulation" / "core300x.csv"
COURSE_TEST = ROOT / "problems" / "real_fabric" / "acrylic_stockinette_x.csv"
MEASURED_STRAIN = 0.6     # the measured course pulls end near 60 % strain


@dataclass(frozen=True)
class SourcePoint:
    """The source's lowest-energy answer at one cell width x (mm): its free height y (mm) and
    its energies per cell (N·mm)."""

    x: float
    y: float
    contact: float
    curve: float
    total: float


def read_sweep(path: Path = SWEEP) -> tuple[dict[str, float], list[SourcePoint]]:
    """The source's settings (its config's ``*key value`` lines, numbers only) and its sweep,
    the lowest total energy over the initialisations at each x, by x."""
    config, best, rows = {}, {}, []
    with open(path) as fh:
        for line in fh:
            if line.startswith("#"):
                config.update(_setting(line))
            else:
                rows.append(line)
    for r in csv.DictReader(rows):
        p = SourcePoint(float(r["x_mm"]), float(r["y_mm"]), float(r["contact_energy"]),
                        float(r["curve_energy"]), float(r["total_energy"]))
        key = round(p.x, 6)
        if key not in best or p.total < best[key].total:
            best[key] = p
    return config, [best[k] for k in sorted(best)]


def _setting(line: str) -> dict[str, float]:
    words = line[1:].split()
    if len(words) == 2 and words[0].startswith("*"):
        try:
            return {words[0][1:]: float(words[1])}
        except ValueError:
            return {}
    return {}


def source_yarn(config: dict[str, float], elevation_modes: int = 4) -> dict:
    """A problem document with the source's energy in this project's terms (module docstring):
    R_f = 2B (the source bends with B∫κ², here ½R_f∫κ²) and k = 2k_s (its double loop counts
    every pair twice); stitch length, radii and exponent as they are."""
    return {"loop": {"length": config["stitch_length"]},
            "material": {"R_f": 2.0 * config["bending_modulus"]},
            "yarn": {"geometry": "3d", "radius": config["yarn_radius"],
                     "core_radius": config["core_radius"],
                     "contact_exponent": config["contact_exponent"],
                     "contact_rigidity": 2.0 * config["contact_rigidity"],
                     "elevation_modes": elevation_modes},
            "units": {"length": "mm", "force": "N"}, "fabric": {"courses": 2, "wales": 2}}


@dataclass(frozen=True)
class CellPoint:
    """The cell at one width x: its height y, energy U and bending part (N·mm), force F (N)."""

    x: float
    y: float
    U: float
    bending: float
    F: float
    success: bool


def sweep_cell(config: dict[str, float], widths, samples: int = periodic.SAMPLES,
               thinned: bool | None = None, say=print) -> tuple[CellPoint, list[CellPoint]]:
    """The cell with the source's energy relaxed (x, y free), then at each width (y free),
    each solve from the last; stops at the first that fails. ``thinned``: the law thinned
    at the natural wraps (C3), for comparison (default: the straight yarn's cell's own
    choice, ``periodic.wrap_thinning``)."""
    doc = source_yarn(config)
    pr = parse_problem(doc, "source_simulation")
    shape, law, R_f = pr.yarn.natural3d, pr.yarn.shell(), pr.R_f
    cell = periodic.build_cell(shape, law, "courses", samples, straight=True,
                               thinned=thinned)
    bending = lambda x: float(cell.energy(x, [0.0, R_f, 0.0]))  # noqa: E731
    rest = periodic.solve_cell(cell, cell.spacing0, R_f, periodic.natural_state(shape), free=True)
    if not rest.success:
        raise RuntimeError(f"the source's cell did not relax: {rest.status}")
    x, out = rest.x, []
    for w in widths:
        s = periodic.solve_cell(cell, w, R_f, x)
        out.append(CellPoint(w, float(s.x[-1]), s.U, bending(s.x), s.F, s.success))
        say(f"  x {w:.3f}: {s.status} ({s.iterations} it)")
        if not s.success:
            break
        x = s.x
    return CellPoint(float(rest.x[-2]), float(rest.x[-1]), rest.U, bending(rest.x), 0.0,
                     True), out


def midpoint_forces(xs: np.ndarray, energies: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """dE/dx by differences between neighbouring widths, at their midpoints: (x_mid, F)."""
    return (xs[1:] + xs[:-1]) / 2, np.diff(energies) / np.diff(xs)


def at_strain(x0: float, xs: np.ndarray, F: np.ndarray, strain: float) -> float:
    """F interpolated at the width (1 + strain)·x0 (NaN outside the points)."""
    return float(np.interp((1 + strain) * x0, xs, F, left=np.nan, right=np.nan))


def course_width() -> float:
    """The measured course specimen's width (mm): its file's width in clamps times the source's
    clamp width, as ``calibrate`` and ``scripts/periodic_cell.py`` read it."""
    return read_stitch_by_stitch(COURSE_TEST, COURSE_TEST.name).width_clamps * CLAMP_WIDTH_MM


def report(src: list[SourcePoint], rest: CellPoint, cell: list[CellPoint]) -> str:
    """The table and its summary (module docstring)."""
    ok = [c for c in cell if c.success]
    n = len(ok)
    lines = [f"relaxed (x, y free): cell {rest.x:.4f} x {rest.y:.4f} mm, U {rest.U:.4f} N mm "
             f"(bending {rest.bending:.4f}, contact {rest.U - rest.bending:.4f}); source's "
             f"lowest energy {src[0].total:.4f} N mm at its first width {src[0].x:.3f} mm "
             f"(y {src[0].y:.4f} mm; its sweep starts there)",
             "x mm | source y, cell y (mm) | source U (curve, contact) | cell U (bending, "
             "contact) N mm"]
    for p, c in zip(src, ok):
        lines.append(f"{p.x:.3f} | {p.y:.4f}, {c.y:.4f} ({c.y / p.y - 1:+.2%}) | {p.total:.4f} "
                     f"({p.curve:.4f}, {p.contact:.4f}) | {c.U:.4f} ({c.bending:.4f}, "
                     f"{c.U - c.bending:.4f})")
    if n < len(src):
        lines.append(f"the cell stops at x = {cell[-1].x:.3f} mm (no equilibrium); the source's "
                     f"sweep goes on to {src[-1].x:.3f} mm")
    xs = np.array([p.x for p in src[:n]])
    xm, Fs = midpoint_forces(xs, np.array([p.total for p in src[:n]]))
    Fc = np.array([(a.F + b.F) / 2 for a, b in zip(ok[:-1], ok[1:])])
    lines.append("force through one cell dE/dx (N) at the midpoints, source | cell:")
    lines += [f"  {x:.3f}: {a:.4f} | {b:.4f} ({b / a:.2f}x)" if abs(a) > 1e-3 else
              f"  {x:.3f}: {a:.4f} | {b:.4f}" for x, a, b in zip(xm, Fs, Fc)]
    m = sum(p.x <= (1 + MEASURED_STRAIN) * src[0].x + 1e-9 for p in src[:n])
    dy = np.array([c.y / p.y - 1 for p, c in zip(src[:m], ok[:m])])
    rise_s, rise_c = src[m - 1].total - src[0].total, ok[m - 1].U - ok[0].U
    lines.append(f"to {MEASURED_STRAIN:.0%} strain (x {src[0].x:.2f}-{src[m - 1].x:.2f} mm): "
                 f"free height within {np.max(np.abs(dy)):.2%}; energy rise source "
                 f"{rise_s:.4f}, cell {rise_c:.4f} N mm ({rise_c / rise_s:.2f}x)")
    y0, width = src[0].y, course_width()
    for e in (0.1, 0.3):
        fs, fc = at_strain(src[0].x, xm, Fs, e), at_strain(src[0].x, xm, Fc, e)
        lines.append(f"at {e:.0%} strain from x = {src[0].x:.2f} mm, per width x {width:.2f} mm:"
                     f" source {fs / y0 * width:.3f} N, cell {fc / y0 * width:.3f} N")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--thinned", action="store_true",
                    help="the law thinned at the natural wraps (C3), for comparison")
    ap.add_argument("--to", type=float, default=5.35, help="the largest width x (mm)")
    ap.add_argument("--samples", type=int, default=periodic.SAMPLES)
    ap.add_argument("--out", type=Path, help="also draw both choices of the law here")
    args = ap.parse_args(argv)
    config, src = read_sweep()
    src = [p for p in src if p.x <= args.to + 1e-9]
    doc = source_yarn(config)
    law = ("thinned at the natural wraps" if args.thinned
           else "the yarn's own (a straight yarn's cell)")
    print(f"the source's settings ({SWEEP.relative_to(ROOT)}): R_f = 2B = "
          f"{doc['material']['R_f']:g} N mm^2, k = 2k_s = {doc['yarn']['contact_rigidity']:g} "
          f"N/mm^3, core {config['core_radius']:g} mm; law {law}")
    t0 = time.perf_counter()
    rest, cell = sweep_cell(config, [p.x for p in src], args.samples,
                            args.thinned or None)
    print(report(src, rest, cell))
    if args.out is not None:
        other = sweep_cell(config, [p.x for p in src], args.samples, not args.thinned or None,
                           say=lambda *_: None)[1]
        own, thin = (other, cell) if args.thinned else (cell, other)
        args.out.mkdir(parents=True, exist_ok=True)
        path = draw(src, own, thin, args.out / "source_cell.png")
        print(f"wrote {path}")
    print(f"{time.perf_counter() - t0:.1f} s")
    return 0


def draw(src: list[SourcePoint], own: list[CellPoint], thin: list[CellPoint],
         path: Path) -> Path:
    """The source's free height and force beside the cell's, with the yarn's own law and
    thinned, over the source's widths; the force axis stops at twice the source's largest
    (the cell's jam beyond it is said in the legend)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    xs = np.array([p.x for p in src])
    xm, Fs = midpoint_forces(xs, np.array([p.total for p in src]))
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.4))
    a.plot(xs, [p.y for p in src], "o", color="k", ms=4, label="source (stitch-by-stitch "
           "core300x: its lowest energy of 4 starts)")
    b.plot(xm, Fs, "o", color="k", ms=4, label="source: dE/dx of its energy")
    top = 2 * float(np.max(Fs))
    for pts, style, name in ((own, "-", "this cell, the yarn's own law"),
                             (thin, "--", "this cell, the law thinned at the wraps (C3)")):
        ok = [c for c in pts if c.success]
        a.plot([c.x for c in ok], [c.y for c in ok], style, label=name)
        over = [c.x for c in ok if c.F > top]
        note = f" (jammed: off the axis from {over[0]:.2f} mm)" if over else ""
        b.plot([c.x for c in ok if c.F <= top], [c.F for c in ok if c.F <= top], style,
               label=name + note)
    a.set_xlabel("cell width x along the courses (mm)")
    a.set_ylabel("free cell height y (mm)")
    b.set_xlabel("cell width x along the courses (mm)")
    b.set_ylabel("force through one cell (N)")
    b.set_ylim(0, top)
    a.grid(alpha=0.3)
    a.legend(fontsize=7.5, loc="upper right")
    b.grid(alpha=0.3)
    b.legend(fontsize=7.5, loc="upper left", framealpha=1)
    fig.suptitle("The periodic cell with the source's energy (R_f = 2B = 0.09 N mm², k = 2k_s "
                 "= 0.0012 N/mm³, core 0.3 mm) against the source's own simulation", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


if __name__ == "__main__":
    sys.exit(main())
