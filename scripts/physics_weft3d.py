"""The 3-D weft model's physics beside the planar model's (issue 39, "Physics"; docs/weft3d.md).

1. Stockinette specimens of N x N loops (default 6 x 6) between two rigid clamps
   (``calibration.specimen``: along the courses the yarn ends of every course, along the wales
   the bottom sinkers and the top heads), pulled along each direction in even strain steps to
   55 %: the stiffness per width at 10 % strain in each direction and their ratio (the measured
   acrylic fabric: wale 2.4 times stiffer per width), and the tangent stiffening from 5 % to 50 %
   (measured: x6). K(e) = (F(e + 0.025) - F(e - 0.025)) / 0.05 (``calibration.checks``), per
   width: divided by the specimen's pitch width (courses x c, or wales x w).
2. The 3-D model's 12 x 12 fabric stretched 50 % along the courses and 30 % along the wales
   between rigid edges, and pushed together by 20 % along each: every designed crossing's order
   (flipped) and the smallest separation against the hard core (``spatial_block``).

Both models have the acrylic yarn (L = 11.28 mm, R_f = 0.045 N mm^2, mm and N) and nothing
fitted: the planar model the paper's crossing springs (k_a L^2 / R_f = 100, k_b L^2 / R_f = 1),
the 3-D model radius 0.74 mm and stitch-by-stitch's soft-shell law (its defaults).

    python scripts/physics_weft3d.py [--size 6] [--big 12] [--skip-big] [--out results]

Prints one line per solved node (stderr) and the tables (stdout); writes physics_weft3d.json.
Times are wall seconds on whatever machine runs it.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from knit_nlp.weft.inverse.calibration.checks import HALF
from knit_nlp.weft.inverse.calibration.curve import SpecimenModel
from knit_nlp.weft.inverse.calibration.specimen import build_specimen

L, R_F = 11.28, 0.045
BASE = {"units": {"length": "mm", "force": "N"}, "loop": {"length": L},
        "solver": {"max_iter": 300, "max_time": 30}}   # per step; a failed step is halved
MODELS = {
    "planar": {"material": {"R_f": R_F, "k_a": 100 * R_F / L ** 2, "k_b": R_F / L ** 2}},
    "3d": {"material": {"R_f": R_F}, "yarn": {"radius": 0.74, "geometry": "3d",
                                              "elevation_modes": 4}},
}
STEP = 0.025
PULL = np.round(np.arange(STEP, 0.55 + 1e-9, STEP), 4)
BIG = {("courses", 0.5), ("wales", 0.3), ("courses", -0.2), ("wales", -0.2)}


def doc_of(model: str) -> dict[str, Any]:
    return {**BASE, **MODELS[model]}


def log(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def pull(model: str, direction: str, m: int, n: int, strains: np.ndarray) -> dict[str, Any]:
    """One specimen pulled (or pushed) through ``strains``: its curve and, in 3-D, the crossing
    state at every node."""
    t0 = time.perf_counter()
    doc = doc_of(model)
    sp = build_specimen(doc, "<physics>", direction, m, n, f"{model}_{direction}")
    sm = SpecimenModel(sp)
    nodes: list[dict[str, Any]] = []

    def report(strain: float, rep: Any) -> None:
        row = {"strain": strain, "force_N": float(sm.force(rep.lam_g)),
               "iterations": rep.iterations, "wall_s": time.perf_counter() - t0}
        if sm.spatial:
            block = sm.eq.wnlp.spatial_block(rep.x, sm.params(doc["material"], strain * sp.gauge))
            row.update(flipped=block["flipped"], smallest_separation=block["smallest_separation"],
                       slid_off_loop=block["slid_off_loop"])
        nodes.append(row)
        log(f"{model} {direction} {m} x {n}: strain {strain:+.3f} force {row['force_N']:.4g} N"
            + (f" flipped {row['flipped']} smallest separation {row['smallest_separation']:.4f}"
               f" mm" if sm.spatial else "") + f" ({row['wall_s']:.0f} s)")
    c = sm.pull_to(doc["material"], strains, report)
    out = {"model": model, "direction": direction, "courses": m, "wales": n,
           "pitch_width_mm": sp.pitch_width, "gauge_mm": sp.gauge, "complete": c.complete,
           "asked": float(strains[-1]),
           "reason": c.reason, "strain": (c.u / sp.gauge).tolist(), "force_N": c.force.tolist(),
           "nodes": nodes, "solves": c.solves, "iterations": c.iterations,
           "wall_s": time.perf_counter() - t0}
    if sm.spatial:
        out["core_mm"] = 2 * sp.problem.yarn.core_radius
        out["touch_mm"] = 2 * sp.problem.yarn.radius
    return out


def tangent(run: dict[str, Any], e: float) -> float | None:
    """K(e) per pitch width (N/mm per unit strain) on the run's nodes (linear between them)."""
    strain, force = np.array(run["strain"]), np.array(run["force_N"])
    if strain.size == 0 or strain[-1] < e + HALF - 1e-9:
        return None
    k = (np.interp(e + HALF, strain, force) - np.interp(e - HALF, strain, force)) / (2 * HALF)
    return float(k / run["pitch_width_mm"])


def stiffness_rows(runs: list[dict[str, Any]]) -> list[dict[str, Any]]:
    rows = []
    for model in MODELS:
        by = {r["direction"]: r for r in runs if r["model"] == model}
        row: dict[str, Any] = {"model": model}
        for d, r in by.items():
            k10, k5, k45, k50 = (tangent(r, e) for e in (0.10, 0.05, 0.45, 0.50))
            row[d] = {"K10_per_width": k10, "K5_per_width": k5, "K50_per_width": k50,
                      "stiffening_5_50": None if k5 in (None, 0) or k50 is None else k50 / k5,
                      "stiffening_5_45": None if k5 in (None, 0) or k45 is None else k45 / k5,
                      "reached": r["strain"][-1], "reason": r["reason"], "wall_s": r["wall_s"],
                      "size": f"{r['courses']} x {r['wales']}"}
        kc = row.get("courses", {}).get("K10_per_width")
        kw = row.get("wales", {}).get("K10_per_width")
        row["wale_over_course_at_10"] = None if kc in (None, 0) or kw is None else kw / kc
        rows.append(row)
    return rows


def show(v: float | None, fmt: str = ".3g") -> str:
    return "n/a" if v is None else format(v, fmt)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=6, help="loops per side of the pulls (>= 6)")
    ap.add_argument("--big", type=int, default=12, help="loops per side of the 3-D stretch")
    ap.add_argument("--skip-big", action="store_true")
    ap.add_argument("--only", default="", help="comma list of model:direction to run "
                    "(the N x N pulls; 'none': only the big 3-D runs)")
    ap.add_argument("--max-time", type=float, default=30.0, help="wall seconds per step")
    ap.add_argument("--big-runs", default="", help="comma list of direction:strain of the big "
                    "3-D runs (default: courses:0.5,wales:0.3,courses:-0.2,wales:-0.2)")
    ap.add_argument("--out", default="results")
    args = ap.parse_args(argv)
    BASE["solver"]["max_time"] = args.max_time
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    only = {tuple(s.split(":")) for s in args.only.split(",") if s}
    runs = []
    for model in MODELS:
        for direction in ("courses", "wales"):
            if only and (model, direction) not in only:
                continue
            runs.append(pull(model, direction, args.size, args.size, PULL))
            json.dump({"pulls": runs}, open(out / "physics_weft3d.json", "w"), indent=1)
    rows = stiffness_rows(runs)
    big = []
    if not args.skip_big:
        chosen = [(d, float(e)) for d, e in (r.split(":") for r in args.big_runs.split(",") if r)]
        for direction, strain in chosen or sorted(BIG, key=lambda b: (-b[1], b[0])):
            steps = np.round(np.arange(STEP, abs(strain) + 1e-9, STEP), 4) * np.sign(strain)
            big.append(pull("3d", direction, args.big, args.big, steps))
            json.dump({"pulls": runs, "stiffness": rows, "big": big},
                      open(out / "physics_weft3d.json", "w"), indent=1)
    json.dump({"pulls": runs, "stiffness": rows, "big": big},
              open(out / "physics_weft3d.json", "w"), indent=1)
    print("| model | size | course K(10%)/W (N/mm) | wale K(10%)/W (N/mm) | wale / course "
          "| course K(50%)/K(5%) | wale K(50%)/K(5%) | reached (course, wale) | wall s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for row in rows:
        c, w = row.get("courses", {}), row.get("wales", {})
        print(f"| {row['model']} | {c.get('size', w.get('size', ''))} | "
              f"{show(c.get('K10_per_width'))} | {show(w.get('K10_per_width'))} | "
              f"{show(row['wale_over_course_at_10'])} | {show(c.get('stiffening_5_50'))} | "
              f"{show(w.get('stiffening_5_50'))} | {show(c.get('reached'), '.3f')}, "
              f"{show(w.get('reached'), '.3f')} | {c.get('wall_s', 0) + w.get('wall_s', 0):.0f} |")
    print("| measured acrylic | | | | 2.4 | 6 | | | |")
    if big:
        print("\n| 3-D, rigid edges | asked | reached | flipped | smallest separation (mm) | "
              "core 2R_c (mm) | crossing points slid off their loop | wall s | why it stopped |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in big:
            last = r["nodes"][-1] if r["nodes"] else {}
            flips = max((n["flipped"] for n in r["nodes"]), default=None)
            sep = min((n["smallest_separation"] for n in r["nodes"]), default=None)
            print(f"| {r['courses']} x {r['wales']} along the {r['direction']} | "
                  f"{r['asked']:+.2f} | "
                  f"{show(last.get('strain'), '+.3f')} | {show(flips, 'd')} | {show(sep, '.4f')} | "
                  f"{r.get('core_mm', 0):.3g} | {show(last.get('slid_off_loop'), 'd')} | "
                  f"{r['wall_s']:.0f} | {r['reason'] or 'reached'} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
