"""The runs of issues 20 and 40 on the stitch-by-stitch acrylic stockinette, as one table.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python scripts/bench_calibration.py
    python scripts/bench_calibration.py --runs b,d        # a subset
    python scripts/bench_calibration.py --out DIR          # also each run's files (JSON, CSV, PNG)

Every run is the shipped spec ``problems/real_fabric/acrylic_fit_x.toml`` (run b) with a few
keys changed in memory, so the table says exactly what differs. The specimen has its real
width throughout (clamp width 35.5 mm, the source's; issue 40) and the yarn's measured values
(loop length 11.28 mm, R_f 0.045 N·mm²) are held unless a run says otherwise:

- a0  the paper's material (k_a L²/R_f = 100, k_b L²/R_f = 1 with the yarn's R_f and L),
      nothing fitted
- b   k_a, k_b fitted on x (axial and lateral strains), y predicted  [shipped]
- bx  as b, the fit matching the axial strain only
- bR  as b with the bending modulus R_f fitted too (a measured value: how far it must move)
- d   k_a, k_b fitted on x and y together  [shipped as acrylic_fit_xy.toml]
- c4k as b with yarn contact, ``[yarn] radius = 0.74`` mm (issue 19), on 4-loop specimens,
      k_a held at 3.5e4 N/mm (where every fit leaves it: at its bound, undetermined) and k_b
      fitted from b4's answer (docs/real_fabric.md, "Run c"; minutes, not in the default runs)
- b4k as c4k without contact (its same-run reference)
- b4, b8, b10   as b with 4, 8 and 10 loops on the specimens' shorter sides (b: 6)
- bfd as b with finite-difference sensitivities instead of the implicit-function ones
- e   the 3-D model (``problems/real_fabric/acrylic_3d_x.toml`` without its planar ``beside``):
      every measured value held, the crossings' contact rigidity fitted on x, y predicted
      [shipped]; e0 the same with nothing fitted (the 3-D model's prediction of both tests);
      e2, e4 as e0 with 2 and 4 loops on the shorter sides (e0: 3). Not in the default runs
      (minutes each): ``--runs e0,e2,e4,e``

Then, per run, what a researcher checks first (``metrics``): the course pull's tangent
stiffening from 5 % to 45 % strain and the wale pull's stiffness per width over the course
pull's at 10 %, model beside measured. Last, one Jacobian of run b's fit at its answer by both
sensitivity methods, alternated three times in one process (same-run ratio). Times are
wall-clock on a shared machine.
"""
from __future__ import annotations

import argparse
import copy
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from knit_nlp.errors import ProblemError  # noqa: E402
from knit_nlp.tomlio import load_toml  # noqa: E402
from knit_nlp.weft.inverse.calibration import calibrate, parse_spec  # noqa: E402
from knit_nlp.weft.inverse.calibration.calibrate import Calibration  # noqa: E402

SPEC = ROOT / "problems" / "real_fabric" / "acrylic_fit_x.toml"
SPEC3D = ROOT / "problems" / "real_fabric" / "acrylic_3d_x.toml"
RUNS3D = ("e", "e0", "e2", "e4")
PAPER = {"k_a": 100.0, "k_b": 1.0}          # Wada et al.'s k L² / R_f (k_a = 1, k_b = 0.01, R_f = 1, L = 10)
RUNS = ("a0", "b", "bx", "bR", "d", "b4", "b8", "b10", "bfd")
B4 = {"k_a": 3.5e4, "k_b": 7.4}             # about b4's answer at the real width (c4k, b4k:
                                            # with --runs only; contact takes minutes)


def _paper(doc: dict) -> dict:
    L, R_f = doc["loop"]["length"], doc["material"]["R_f"]
    doc["material"].update({k: v * R_f / L ** 2 for k, v in PAPER.items()})
    return doc


def _from(doc: dict, answer: dict) -> None:
    """k_a held at an answer's value, k_b fitted from that answer."""
    doc["material"].update(k_a=answer["k_a"], k_b=answer["k_b"])
    doc["calibrate"].update(fit=["k_b"])


def variant3d(name: str) -> dict:
    """The 3-D runs (module doc): the shipped 3-D spec, its planar ``beside`` left out."""
    doc = copy.deepcopy(load_toml(SPEC3D))
    cal = doc["calibrate"]
    cal.pop("beside", None)
    if name != "e":
        cal["fit"] = []
    if name in ("e2", "e4"):
        cal["min_loops"] = int(name[1:])
    doc["name"] = f"acrylic_{name}"
    return doc


def variant(name: str) -> dict:
    if name in RUNS3D:
        return variant3d(name)
    doc = copy.deepcopy(load_toml(SPEC))
    cal = doc["calibrate"]
    if name == "a0":
        _paper(doc)
        cal["fit"] = []
    elif name == "bx":
        cal["strains"] = ["axial"]
    elif name == "bR":
        cal["fit"] = ["k_a", "k_b", "R_f"]
    elif name in ("c4k", "b4k"):
        if name == "c4k":
            doc["yarn"] = {"radius": 0.74}
        cal["min_loops"] = 4
        _from(doc, B4)
    elif name == "d":
        for test in doc["test"]:
            test["use"] = "fit"
    elif name in ("b4", "b8", "b10"):
        cal["min_loops"] = int(name[1:])
    elif name == "bfd":
        cal["sensitivities"] = "finite_differences"
    doc["name"] = f"acrylic_{name}"
    return doc


def _value(row: dict) -> str:
    v = f"{row['value']:.4g}"
    if not row["fitted"]:
        return v
    se = row.get("std_error")
    return f"{v}±{se:.2g}" if se is not None else f"{v}(undet.)"


def _rms(t: dict) -> str:
    r = t["rms_strain_error"]
    fmt = lambda v: "  n/a" if v is None else f"{v:.3f}"     # noqa: E731
    return f"{fmt(r['axial'])} {fmt(r['lateral'])}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", default=",".join(RUNS))
    parser.add_argument("--out", default=None)
    parser.add_argument("--breaks", action="store_true",
                        help="also: where the model breaks (each measured value moved alone)")
    args = parser.parse_args()
    print(f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', 'unset')} "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')} "
          f"load average {os.getloadavg()[0]:.1f} (shared machine: absolute times are noisy)")
    print("run  k_a (N/mm)        k_b (N/mm)        R_f (N mm2)        x: axial lateral  "
          "y: axial lateral  ok  time (s)  solves  loops x / y")
    results = {}
    for name in args.runs.split(","):
        try:
            spec = parse_spec(variant(name), SPEC3D if name in RUNS3D else SPEC)
        except ProblemError as err:
            print(f"{name:<4} not run: {err}")
            continue
        t0 = time.perf_counter()
        res = calibrate(spec)
        wall = time.perf_counter() - t0
        results[name] = res
        js = res.to_json()
        p = js["parameters"]
        x, y = js["tests"]
        loops = " / ".join(f"{t['specimen']['courses']}x{t['specimen']['wales']}" for t in js["tests"])
        first = _value(p["contact_rigidity"]) + " (k, N/mm3)" if "contact_rigidity" in p else (
            _value(p["k_a"]))
        second = _value(p["k_b"]) if "k_b" in p else "(3-D)"
        print(f"{name:<4} {first:<17} {second:<17} "
              f"{_value(p['R_f']):<18} {x['use'][:4]} {_rms(x)}  {y['use'][:4]} {_rms(y)}  "
              f"{'yes' if res.success else 'NO ':<3} {wall:8.1f}  {js['timings']['forward_solves']:6d}"
              f"  {loops}", flush=True)
        if args.out:
            res.save(Path(args.out))
    _shapes(results)
    if "b" in results:
        _sensitivity_timing(results["b"])
        if args.breaks:
            _breaks(results["b"])
    return 0


BREAK_FACTORS = {"R_f": np.geomspace(1 / 32, 32, 21), "clamp width": np.geomspace(1 / 32, 32, 21),
                 "loop length": np.geomspace(0.5, 2, 9)}   # each measured value times these, alone


def _outcomes(spec, values: dict, clamp_factor: float = 1.0) -> list:
    """Every test of ``spec`` at ``values`` (the clamp width times ``clamp_factor``)."""
    cal = Calibration(spec)
    for tm in cal.models:
        tm.clamp_width *= clamp_factor
    return [cal.outcome(tm, values, None) for tm in cal.models]


def _breaks(res) -> None:
    """Where the model breaks (issue 40 item 5): from run b's fitted answer, each measured value
    alone times BREAK_FACTORS; per value the best x axial error and the factors at which each
    test is within its targets."""
    print("\nwhere the model breaks: from run b's answer (k_a, k_b held there), one measured "
          "value at a time times each factor")
    print("value (factors)              best x axial (factor)   x within target at   y within "
          "target at")
    doc = copy.deepcopy(load_toml(SPEC))
    for name, factors in BREAK_FACTORS.items():
        rows = []
        for q in factors:
            if name == "R_f":
                outs = _outcomes(res.spec, {**res.values, "R_f": res.values["R_f"] * q})
            elif name == "clamp width":
                outs = _outcomes(res.spec, res.values, q)
            else:
                d = copy.deepcopy(doc)
                d["loop"]["length"] *= q
                outs = _outcomes(parse_spec(d, SPEC), res.values)
            rows.append((q, outs))
        xs = [(o[0].metric.rms_axial, q) for q, o in rows if o[0].metric.rms_axial is not None]
        best = min(xs) if xs else (float("nan"), float("nan"))
        within = [", ".join(f"{q:.3g}" for q, o in rows if o[k].success) or "none"
                  for k in range(2)]
        label = f"{name} ({factors[0]:.3g}..{factors[-1]:.3g}, {len(factors)})"
        print(f"{label:<28} {best[0]:.3f} (x {best[1]:.3g}){'':<9} {within[0]:<20} {within[1]}",
              flush=True)


def _shapes(results: dict) -> None:
    """What a researcher checks first (calibration/checks.py), per run, model (measured)."""
    print("\nchecks (model, measured in brackets): force at 10 % and 30 % axial strain (N), "
          "stiffening 5 -> 45 % (x), wale / course stiffness per width at 10 %")
    show = lambda v: "  n/a" if v is None else f"{v:.3g}"     # noqa: E731
    for name, res in results.items():
        x, y = res.tests
        cx, cy = x.checks, y.checks
        ratio = next(iter(res.checks().values())) or {"model": None, "measured": None}
        print(f"  {name:<4} x F10 {show(cx['model']['force_N']['0.1'])} "
              f"({show(cx['measured']['force_N']['0.1'])}), F30 "
              f"{show(cx['model']['force_N']['0.3'])} ({show(cx['measured']['force_N']['0.3'])}),"
              f" stiffening {show(cx['model']['stiffening'])} "
              f"({show(cx['measured']['stiffening'])}); y F10 "
              f"{show(cy['model']['force_N']['0.1'])} ({show(cy['measured']['force_N']['0.1'])});"
              f" y/x {show(ratio['model'])} ({show(ratio['measured'])})")


def _sensitivity_timing(res) -> None:
    """One Jacobian of run b's fit at its answer, implicit against finite differences."""
    cal = Calibration(res.spec)
    fitted = np.array([res.values[n] for n in cal.names])
    cal.residual(fitted)
    times = {"implicit": [], "finite_differences": []}
    jac = {}
    for _ in range(3):
        for method in times:
            cal.spec = replace(cal.spec, sensitivities=method)
            t0 = time.perf_counter()
            jac[method] = cal.jacobian(fitted)
            times[method].append(time.perf_counter() - t0)
    ti, tf = np.median(times["implicit"]), np.median(times["finite_differences"])
    diff = np.abs(jac["implicit"] - jac["finite_differences"]).max() / np.abs(jac["implicit"]).max()
    print(f"one Jacobian of run b at its answer: implicit {ti:.2f} s, finite differences "
          f"{tf:.2f} s (medians of 3, alternated): ratio fd/implicit {tf / ti:.2f}; largest "
          f"difference {diff:.2e} of the largest entry")


if __name__ == "__main__":
    raise SystemExit(main())
