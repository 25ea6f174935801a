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

3. ``--straight``: the experiment of a *straight* bending reference (stitch-by-stitch's yarn,
   whose bending energy is 1/2 B int kappa^2 with no natural curvature) instead of the natural
   loop's (S4): the calibration spec's 3-D model (problems/real_fabric/acrylic_3d_x.toml, its
   fitted contact rigidity) with the reference curvature (1 - beta) times the natural loop's,
   relaxed at zero load (clamps at their natural positions) by raising beta from 0 towards 1
   in steps of ``--beta-step``, each one IPOPT solve warm-started from the last, until a solve
   fails; then the course and wale pulls from the furthest relaxed state reached and from the
   natural one (beta = 0), with forces relative to the relaxed state's clamp reaction, at the
   test's real width (clamp width 35.5 mm), beside the measured figures. Writes
   physics_weft3d_straight.json.

    python scripts/physics_weft3d.py --straight [--beta-step 0.05] [--out results]

Prints one line per solved node (stderr) and the tables (stdout); writes physics_weft3d.json.
Times are wall seconds on whatever machine runs it.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
import tomllib
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from knit_nlp.weft.inverse.calibration.checks import HALF, curve_checks
from knit_nlp.weft.inverse.calibration.curve import MAX_HALVINGS, SpecimenModel
from knit_nlp.weft.inverse.calibration.measured import read_stitch_by_stitch
from knit_nlp.weft.inverse.calibration.spec import CLAMP_WIDTH_MM
from knit_nlp.weft.inverse.calibration.specimen import build_specimen
from knit_nlp.weft.transcription import spatial

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


# -- 3. the straight bending reference (module docstring, item 3) ---------------------------
SPEC = Path(__file__).resolve().parents[1] / "problems" / "real_fabric" / "acrylic_3d_x.toml"
FITTED_RIGIDITY = 0.0108897     # N/mm^3: the shipped calibration's fit (docs/real_fabric.md)
SPECIMENS = {"courses": (3, 5), "wales": (3, 7)}    # the calibration's (min_loops = 3)
TESTS = {"courses": "acrylic_stockinette_x.csv", "wales": "acrylic_stockinette_y.csv"}
STRAIGHT_PULL = np.round(np.arange(STEP, 0.5 + 1e-9, STEP), 4)


class _Scaled:
    """The natural 3-D loop with its angles' coefficients times ``factor`` (the bending's
    reference only: positions, crossings and the start keep the natural loop)."""

    def __init__(self, shape: Any, factor: float) -> None:
        self._shape, self._factor = shape, factor

    @property
    def coeffs(self) -> np.ndarray:
        return self._factor * self._shape.coeffs

    @property
    def elevation(self) -> np.ndarray:
        return self._factor * self._shape.elevation

    def __getattr__(self, name: str) -> Any:
        return getattr(self._shape, name)


@contextmanager
def reference_scaled(factor: float) -> Iterator[None]:
    """NLPs built inside measure bending (S4) from ``factor`` times the natural loop's angles
    (theta0, phi0): 1 the model's own, 0 a straight yarn. The builder's energy reads the shape's
    ``coeffs`` and elevation (``_b0``) for the bending reference and, for applied moments,
    theta0; the specimens here have none."""
    original = spatial._Builder._energy

    def energy(self: Any, xb: Any, pb: Any) -> Any:
        shape = self.shape
        self.shape = _Scaled(shape, factor)
        try:
            return original(self, xb, pb)
        finally:
            self.shape = shape
    spatial._Builder._energy = energy
    try:
        yield
    finally:
        spatial._Builder._energy = original


def straight_doc(rigidity: float, max_time: float) -> dict[str, Any]:
    """The calibration spec's model (loop, material, yarn, units, solver) at ``rigidity``."""
    spec = tomllib.loads(SPEC.read_text())
    doc = {k: spec[k] for k in ("units", "loop", "material", "yarn", "solver")}
    doc["yarn"] = {**doc["yarn"], "contact_rigidity": rigidity}
    doc["solver"] = {"max_iter": 300, "max_time": max_time}
    return doc


def crossing_stats(sm: SpecimenModel, x: np.ndarray, p: np.ndarray) -> dict[str, Any]:
    """Compression h - 2r at the crossings (negative: pressed) and the crossing points slid off
    their loop, at state x."""
    st = sm.eq.wnlp.crossing_state(x)
    comp = st["compression"]
    return {"compression_min_mm": float(comp.min()),
            "compression_median_mm": float(np.median(comp)),
            "pressed": int(np.sum(comp < 0)), "crossings": int(comp.size),
            "contact_force_sum_N": float(np.sum(st["force"])),
            "sin_angle_min": float(st["sin_angle"].min()),
            "slid_off_loop": sm.eq.wnlp.spatial_block(x, p)["slid_off_loop"]}


def relax(doc: dict[str, Any], direction: str, betas: np.ndarray
          ) -> tuple[list[dict[str, Any]], dict[float, tuple[SpecimenModel, np.ndarray, float]]]:
    """Zero load, clamps at their natural positions: beta raised step by step, each solve one
    IPOPT solve from the last state; stops at the first failure. Returns a row per beta and,
    per beta relaxed, (its specimen model, state, clamp reaction F0)."""
    m, n = SPECIMENS[direction]
    rows, states, x = [], {}, None
    for beta in betas:
        t0 = time.perf_counter()
        with reference_scaled(1.0 - float(beta)):
            sp = build_specimen(doc, "<physics>", direction, m, n, f"straight_{direction}")
            sm = SpecimenModel(sp)
        p0 = sm.params(doc["material"], 0.0)
        rep = sm._step3d(p0, sm.eq.wnlp.x0 if x is None else x)
        row = {"beta": float(beta), "status": rep.status, "iterations": rep.iterations,
               "wall_s": time.perf_counter() - t0,
               "F0_model_N": float(sm.force(rep.lam_g)) if rep.success else None,
               **crossing_stats(sm, rep.x, p0)}
        rows.append(row)
        log(f"relax {direction} {m} x {n}: beta {beta:.3f} {rep.status} ({rep.iterations} it); "
            f"h - 2r min {row['compression_min_mm']:.3f} median {row['compression_median_mm']:.3f}"
            f" mm, {row['pressed']}/{row['crossings']} pressed, slid {row['slid_off_loop']}, "
            f"sin a min {row['sin_angle_min']:.3f}")
        if not rep.success:
            break
        x = rep.x
        states[float(beta)] = (sm, x, row["F0_model_N"])
    return rows, states


def pull_relative(sm: SpecimenModel, x: np.ndarray, f0: float, material: dict[str, float],
                  strains: np.ndarray, label: str) -> dict[str, Any]:
    """The pull from the relaxed state x, each node one IPOPT solve from the last (a failed
    step halved up to MAX_HALVINGS times), force relative to the relaxed reaction f0."""
    L0, t0 = sm.specimen.gauge, time.perf_counter()
    es, fs, reason, u = [0.0], [0.0], "", 0.0
    for strain in np.asarray(strains, dtype=float):
        target = strain * L0
        step, halvings = target - u, 0
        while u != target and halvings <= MAX_HALVINGS:
            nxt = target if abs(target - u) <= abs(step) else u + step
            rep = sm._step3d(sm.params(material, nxt), x)
            if rep.success:
                u, x = nxt, rep.x
            else:
                halvings, step = halvings + 1, step / 2
        if u != target:
            reason = f"no equilibrium past strain {u / L0:.3g} ({rep.status})"
            break
        es.append(float(strain))
        fs.append(float(sm.force(rep.lam_g)) - f0)
        log(f"  {label}: strain {target / L0:.3f} F - F0 {fs[-1]:.4g} N (model) "
            f"({time.perf_counter() - t0:.0f} s)")
    return {"strain": es, "force_model_N": fs, "reason": reason,
            "pitch_width_mm": sm.specimen.pitch_width, "wall_s": time.perf_counter() - t0,
            "final": crossing_stats(sm, x, sm.params(material, u))}


def straight_experiment(args: argparse.Namespace, out: Path) -> dict[str, Any]:
    """Item 3 of the module docstring; prints its tables."""
    doc = straight_doc(args.rigidity, args.max_time)
    betas = np.round(np.arange(0.0, 1.0 + 1e-9, args.beta_step), 6)
    result: dict[str, Any] = {"rigidity": args.rigidity, "directions": {}}
    for direction in ("courses", "wales"):
        test = read_stitch_by_stitch(SPEC.parent / TESTS[direction], TESTS[direction])
        width = test.width_clamps * CLAMP_WIDTH_MM
        measured = curve_checks([(r.axial, r.force) for r in test.runs], width)
        rows, states = relax(doc, direction, betas)
        pulls = {}
        for beta in sorted({0.0, max(states)}):
            sm, x, f0 = states[beta]
            run = pull_relative(sm, x, f0, doc["material"], STRAIGHT_PULL,
                                f"{direction} beta {beta:g}")
            scale = width / run["pitch_width_mm"]
            run["checks"] = curve_checks([(np.array(run["strain"]),
                                           np.array(run["force_model_N"]) * scale)], width)
            pulls[f"{beta:g}"] = run
        result["directions"][direction] = {"width_mm": width, "measured": measured,
                                           "relax": rows, "pulls": pulls}
        json.dump(result, open(out / "physics_weft3d_straight.json", "w"), indent=1)
    print("| reference | pull | F(10 %) N | F(30 %) N | stiffening 5 -> 45 % | K(10 %)/W N/mm "
          "| reached | relaxed: h - 2r min, median (mm); pressed |")
    print("|---|---|---|---|---|---|---|---|")
    for direction, d in result["directions"].items():
        last = d["relax"][-1]
        for beta, run in d["pulls"].items():
            c = run["checks"]
            rel = next(r for r in d["relax"] if f"{r['beta']:g}" == beta)
            print(f"| beta = {beta} | {direction} | {show(c['force_N']['0.1'])} | "
                  f"{show(c['force_N']['0.3'])} | {show(c['stiffening'])} | "
                  f"{show(c['stiffness_per_width'])} | {run['strain'][-1]:.3f} "
                  f"{run['reason']} | {rel['compression_min_mm']:.3f}, "
                  f"{rel['compression_median_mm']:.3f}; {rel['pressed']}/{rel['crossings']} |")
        m = d["measured"]
        print(f"| measured | {direction} | {show(m['force_N']['0.1'])} | "
              f"{show(m['force_N']['0.3'])} | {show(m['stiffening'])} | "
              f"{show(m['stiffness_per_width'])} | | |")
        print(f"|  | {direction}: relaxation stopped at beta = {last['beta']:g}: "
              f"{last['status']} | | | | | | |")
    for strain in (0.10, 0.05):
        ratio = {}
        for key in {b for d in result["directions"].values() for b in d["pulls"]}:
            k = []
            for d in ("courses", "wales"):
                run = result["directions"][d]["pulls"].get(key)
                k.append(None if run is None else tangent(
                    {**run, "force_N": run["force_model_N"]}, strain))
            ratio[key] = None if None in k or k[0] == 0 else k[1] / k[0]
        result[f"wale_over_course_at_{strain:g}"] = ratio
        print(f"wale / course stiffness per width at {strain:.0%}: " + ", ".join(
            f"beta {b}: {show(v)}" for b, v in sorted(ratio.items())))
    json.dump(result, open(out / "physics_weft3d_straight.json", "w"), indent=1)
    return result


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
    ap.add_argument("--straight", action="store_true", help="only the straight-reference "
                    "experiment (module docstring, item 3)")
    ap.add_argument("--beta-step", type=float, default=0.05, help="--straight: step of beta")
    ap.add_argument("--rigidity", type=float, default=FITTED_RIGIDITY,
                    help="--straight: contact rigidity (N/mm^3)")
    args = ap.parse_args(argv)
    BASE["solver"]["max_time"] = args.max_time
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.straight:
        straight_experiment(args, out)
        return 0
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
