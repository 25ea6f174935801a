"""The measured specimens as clamped specimens of periodic cells (FE², one NLP): does the wale
pull's narrowing follow once the specimen has its clamps, its free sides and its real shape?

``knit-nlp calibrate`` reads a test through one uniaxial cell (the spacing across the pull
free: uniaxial stress). The wale specimen is twice as wide as its clamps are apart; its
clamps hold its width. Here each specimen is a mesh of triangles at its real size (the width
from the file, 35.5 mm per clamp width; the clamps' distance and the tracking pins' places
from the run's first frames, the mean over runs), every triangle a periodic cell
(``knit_nlp.weft.model.spatial.cell_fabric``), pulled between its clamps; the axial and lateral
strains are read between the pins' places, as the tracking reads them, and compared with
``calibrate``'s checks and metric (``calibration.checks``, ``calibration.metric``).

    python scripts/cell_fabric.py --rigidity 0.00465 [--spec real_fabric/acrylic_3d_cell_straight_x]
        [--directions wales,courses] [--mesh wales=6x3,courses=4x4] [--grading 1]
        [--to 0.6] [--step 0.0125]
        [--max-time 300] [--out DIR]

``--rigidity`` is the contact law's k (N/mm³): e.g. what ``knit-nlp calibrate`` fits for the
spec's uniaxial cell. Prints one line per node and per direction the checks, model beside
measured; ``--out DIR`` writes the curves as CSV and draws the deformed meshes.
"""
from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from knit_nlp.weft.inverse.calibration.checks import outcome_checks  # noqa: E402
from knit_nlp.weft.inverse.calibration.measured import (_GEOMETRY,  # noqa: E402
                                                        MeasuredTest, read_stitch_by_stitch)
from knit_nlp.weft.inverse.calibration.metric import METRIC_FORCES, metric  # noqa: E402
from knit_nlp.weft.inverse.calibration.spec import CLAMP_WIDTH_MM  # noqa: E402
from knit_nlp.weft.model.compression import SoftShell  # noqa: E402
from knit_nlp.weft.model.spatial.cell_fabric import (REACH, SAMPLES,  # noqa: E402
                                                     build_cell_fabric, displaced,
                                                     solve_cell_fabric, specimen_mesh)
from knit_nlp.weft.model.spatial.periodic import build_cell, natural_state, solve_cell  # noqa: E402
from scripts.periodic_cell import at_forces, checks_line, spec_problem  # noqa: E402

TESTS = {"courses": "acrylic_stockinette_x.csv", "wales": "acrylic_stockinette_y.csv"}
HALVINGS = 3                      # a failed step is tried again at half its length, this often


def first_frames(path: Path) -> dict[str, float]:
    """The specimen's shape in clamp widths and the pins' places as fractions, from every
    run's first frame (the mean over runs): ``gap`` the clamps' distance, ``bottom``/``top``
    the axial pins' distances from their clamps over the gap, ``span`` the lateral pins'
    distance over the fabric's width, ``height`` their height over the gap from the bottom
    clamp. Image y grows downwards; the bottom clamp has the larger y. (The specimen's width
    in clamp widths is the reader's, ``MeasuredTest.width_clamps``.)"""
    lines = path.read_text().splitlines()
    clamp_px, width_px = next(tuple(float(v) for v in m.groups()) for m in
                              map(_GEOMETRY.search, lines) if m and m.string.startswith("#"))
    first: dict[str, dict[str, float]] = {}
    for row in csv.DictReader(line for line in lines if not line.startswith("#")):
        first.setdefault(row["run"], {k: float(v) for k, v in row.items() if k != "run"})
    vals = {"gap": [], "bottom": [], "top": [], "span": [], "height": []}
    for r in first.values():
        gap = r["bottom_clamp_y"] - r["top_clamp_y"]
        vals["gap"].append(gap / clamp_px)
        vals["bottom"].append((r["bottom_clamp_y"] - r["bottom_pin_y"]) / gap)
        vals["top"].append((r["top_pin_y"] - r["top_clamp_y"]) / gap)
        vals["span"].append(abs(r["right_pin_x"] - r["left_pin_x"]) / width_px)
        vals["height"].append((r["bottom_clamp_y"] - 0.5 * (r["left_pin_y"] + r["right_pin_y"]))
                              / gap)
    return {k: float(np.mean(v)) for k, v in vals.items()}


def pins(width: float, height: float, f: dict[str, float]) -> np.ndarray:
    """The tracking pins' reference places (mm): axial bottom and top on the centre line,
    lateral left and right at their height."""
    cx, half = width / 2, f["span"] * width / 2
    return np.array([[cx, f["bottom"] * height], [cx, (1 - f["top"]) * height],
                     [cx - half, f["height"] * height], [cx + half, f["height"] * height]])


def strains(fab, z: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    """(axial, lateral) strain between the pins at state z."""
    d = displaced(fab, z, ref)
    return (float(np.linalg.norm(d[1] - d[0]) / np.linalg.norm(ref[1] - ref[0]) - 1),
            float(np.linalg.norm(d[3] - d[2]) / np.linalg.norm(ref[3] - ref[2]) - 1))


def pull(fab, y_rest: np.ndarray, R_f: float, k: float, height: float, ref: np.ndarray,
         to: float, step: float, top_force: float) -> list[dict]:
    """The specimen pulled in clamp-travel steps of ``step`` × height (halved on a failed
    solve, ``HALVINGS`` times) until the travel reaches ``to`` × height or the force
    ``top_force``; one dict per node."""
    z, e, out, h = fab.start(y_rest), 0.0, [], step
    while e < to - 1e-12:
        t0 = time.perf_counter()
        target = min(e + h, to)
        sol = solve_cell_fabric(fab, target * height, R_f, k, z)
        if not sol.success:
            if h < step / 2 ** (HALVINGS - 0.5):
                print(f"  travel {target:.4f}: {sol.status}: stop", flush=True)
                break
            h /= 2
            continue
        z, e = sol.z, target
        ax, lat = strains(fab, z, ref)
        L = np.asarray(fab.lattices(z))
        out.append({"travel": e, "F": sol.F, "axial": ax, "lateral": lat, "z": z})
        print(f"  travel {e:.4f}: F {sol.F:8.4f} N, axial {ax:+.4f}, lateral {lat:+.4f}; "
              f"cells w/w0 {L[:, 0].min() / fab.spacings[0]:.3f}-"
              f"{L[:, 0].max() / fab.spacings[0]:.3f}, c/c0 {L[:, 1].min() / fab.spacings[1]:.3f}"
              f"-{L[:, 1].max() / fab.spacings[1]:.3f}, |s|/c0 <= "
              f"{np.abs(L[:, 2]).max() / fab.spacings[1]:.3f} ({sol.iterations} it, "
              f"{time.perf_counter() - t0:.1f} s)", flush=True)
        if sol.F >= top_force:
            break
    return out


def compare(nodes: list[dict], test: MeasuredTest, width: float) -> dict:
    """calibrate's checks and metric of the specimen's curve (the strains the pins read)."""
    e = np.array([0.0] + [n["axial"] for n in nodes])
    F = np.array([0.0] + [n["F"] for n in nodes])
    lat = np.array([0.0] + [n["lateral"] for n in nodes])
    checks = outcome_checks((e, F), [(r.axial, r.force) for r in test.runs], width)
    pts = metric(test, METRIC_FORCES, at_forces(e, F, e, METRIC_FORCES),
                 at_forces(e, F, lat, METRIC_FORCES))
    return {"checks": checks, "rms_axial": pts.rms_axial, "rms_lateral": pts.rms_lateral,
            "e": e, "F": F, "lat": lat}


def report(direction: str, c: dict, seconds: float) -> str:
    """One line: the pull's time and top force, the checks and the metric."""
    return f"{direction} ({seconds:.0f} s, up to {c['F'].max():.3g} N), {checks_line(c)}"


def draw(path: Path, fab, nodes: list[dict], direction: str, ref: np.ndarray) -> None:
    """The mesh unloaded and at the last node, with the clamps and the tracking pins."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    m, last = fab.mesh, nodes[-1]
    x = np.asarray(fab.positions(last["z"]))
    d = displaced(fab, last["z"], ref)
    fig, ax = plt.subplots(figsize=(7.0, 4.6))
    ax.triplot(m.nodes[:, 0], m.nodes[:, 1], m.triangles, color="0.7", lw=0.8,
               label="unloaded: mesh (each triangle one periodic cell)")
    ax.triplot(x[:, 0], x[:, 1], m.triangles, color="C0", lw=1.0,
               label=f"at {last['F']:.1f} N (clamp travel {100 * last['travel']:.1f} % of the gap)")
    ax.plot(ref[:, 0], ref[:, 1], "o", color="0.45", ms=5, label="tracking pins, unloaded")
    ax.plot(d[:, 0], d[:, 1], "o", color="C3", ms=5, label="tracking pins, loaded")
    for yc, style in ((0.0, "-"), (m.height, "--"), (m.height * (1 + last["travel"]), "-")):
        ax.plot([0, m.width], [yc, yc], style, color="k", lw=2.5)
    ax.plot([], [], "-", color="k", lw=2.5, label="clamps (dashed: the top one unloaded)")
    ax.set_aspect("equal")
    ax.set_xlabel(f"across the pull (along the {'courses' if direction == 'wales' else 'wales'})"
                  f", mm")
    ax.set_ylabel(f"along the pull (along the {direction}), mm")
    ax.set_title(f"{direction} pull of the {m.width:.1f} mm wide specimen", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", default="real_fabric/acrylic_3d_cell_straight_x",
                    help="a calibration spec under problems/ whose [loop], [material] and "
                         "[yarn] give the yarn (bent from a straight yarn)")
    ap.add_argument("--rigidity", type=float, required=True, help="the law's k, N/mm^3")
    ap.add_argument("--bending-factor", type=float, default=1.0, help="R_f times this")
    ap.add_argument("--directions", default="wales,courses")
    ap.add_argument("--mesh", default="wales=6x3,courses=4x4",
                    help="squares across x along the pull, per direction (two triangles each)")
    ap.add_argument("--grading", type=float, default=1.0,
                    help="rows shrink by this factor from the middle toward each clamp")
    ap.add_argument("--to", type=float, default=0.6, help="the largest clamp travel / gap")
    ap.add_argument("--step", type=float, default=0.0125, help="clamp travel per step / gap")
    ap.add_argument("--top-force", type=float, default=30.0, help="stop above this force, N")
    ap.add_argument("--samples", type=int, default=SAMPLES)
    ap.add_argument("--reach", type=float, default=REACH)
    ap.add_argument("--max-time", type=float, default=300.0,
                    help="seconds per step's solve (a step near the lock-up may not converge)")
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    pr = spec_problem(args.spec)
    shape, law = pr.yarn.natural3d, pr.yarn.shell()
    law = SoftShell(law.radius, law.core_radius, args.rigidity, law.exponent)
    R_f = pr.R_f * args.bending_factor
    cell = build_cell(shape, law, "wales", args.samples, straight=True, reach=args.reach)
    rest = solve_cell(cell, cell.spacing0, R_f, natural_state(shape), free=True)
    if not rest.success:
        print(f"the unloaded cell did not converge ({rest.status})")
        return 1
    w0, c0 = (float(v) for v in rest.x[-2:])
    print(f"{args.spec}: k = {args.rigidity:g} N/mm^3, R_f = {R_f:g} N mm^2, {args.samples} "
          f"samples, reach {args.reach}; the relaxed cell w0 = {w0:.4f} mm, c0 = {c0:.4f} mm")
    meshes = dict(item.split("=") for item in args.mesh.split(","))
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
    for direction in args.directions.split(","):
        t0 = time.perf_counter()
        path = ROOT / "problems" / "real_fabric" / TESTS[direction]
        test, f = read_stitch_by_stitch(path, TESTS[direction]), first_frames(path)
        width, height = test.width_clamps * CLAMP_WIDTH_MM, f["gap"] * CLAMP_WIDTH_MM
        nx, ny = (int(v) for v in meshes[direction].split("x"))
        mesh = specimen_mesh(width, height, nx, ny, args.grading)
        ref = pins(width, height, f)
        fab = build_cell_fabric(shape, law, direction, mesh, (w0, c0), args.samples,
                                straight=True, reach=args.reach,
                                max_iter=150, max_time=args.max_time)
        print(f"{direction}: {width:.1f} mm wide, clamps {height:.1f} mm apart, {nx} x {ny} "
              f"rectangles (grading {args.grading:g}, the rows at the clamps "
              f"{mesh.nodes[nx + 1, 1]:.2f} mm; {len(mesh.triangles)} cells, {fab.lbz.size} "
              f"unknowns); pins: axial "
              f"{ref[1, 1] - ref[0, 1]:.1f} mm apart, lateral {ref[3, 0] - ref[2, 0]:.1f} mm",
              flush=True)
        nodes = pull(fab, rest.x[:-2], R_f, args.rigidity, height, ref, args.to, args.step,
                     args.top_force)
        if not nodes:
            continue
        c = compare(nodes, test, width)
        print(report(direction, c, time.perf_counter() - t0), flush=True)
        if args.out:
            with open(args.out / f"cell_fabric_{direction}.csv", "w", newline="") as fh:
                wr = csv.writer(fh)
                wr.writerow(["force_N", "axial_strain", "lateral_strain"])
                wr.writerows(zip(c["F"], c["e"], c["lat"]))
            draw(args.out / f"cell_fabric_{direction}.png", fab, nodes, direction, ref)
    return 0


if __name__ == "__main__":
    sys.exit(main())
