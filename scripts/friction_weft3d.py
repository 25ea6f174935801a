"""Does friction at the crossings matter? An estimate from frictionless 3-D pulls (issue 39).

The 3-D weft model's designed crossings are frictionless sliding contacts (docs/weft3d.md,
S5-S7): each one's material coordinates s_upper, s_lower on its two yarns are unknowns and its
normal force N follows the compression law. Between two recorded nodes k, k + 1 of a pull, a
Coulomb friction coefficient mu at every crossing would dissipate about

    D_k = mu * sum_c  N_c^(k+1/2) * slip_c,   slip_c = sqrt(ds_upper^2 + ds_lower^2)

(the two yarns' slides through the contact, taken perpendicular: the crossings' yarns meet at
large angles; N at the step's midpoint by the trapezoid rule), against the work the clamp does,
W_k = F^(k+1/2) * du. The script prints D/W at mu = 1 per step and in total: with acrylic on
acrylic mu of a few tenths, a total D/W at mu = 1 of order one or more says friction would
change the curve by tens of per cent (lagged per load step, IPC-style, it would enter as an
energy of that size), and of order 0.01 that it would not. The other contacts (the repulsion
pairs) would rub too; they are left out, so D is the crossings' share only.

The specimen, yarn and steps are scripts/physics_weft3d.py's (6 x 6 acrylic, stitch-by-stitch's
soft-shell law, steps of 2.5 % strain, each warm-started from the last):

    OMP_NUM_THREADS=1 python scripts/friction_weft3d.py [--size 6] [--to 0.3] [--direction courses]

With ``--mu MU`` it measures the friction that is built ([yarn] friction, docs/weft3d.md
"Friction"): the same specimen pulled along one load path (``WeftSolver.continuation``, steps of
2.5 %, friction lagged per step) with friction MU and without, in the same run; it prints the
force at every step, the force at 10 % and 30 % and the stiffening K(45 %)/K(5 %):

    OMP_NUM_THREADS=1 python scripts/friction_weft3d.py --mu 0.3 --direction courses --to 0.475
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from physics_weft3d import BASE, STEP, doc_of  # noqa: E402

from knit_nlp.weft.inverse.calibration.curve import SpecimenModel  # noqa: E402
from knit_nlp.weft.inverse.calibration.specimen import PULLED, build_specimen  # noqa: E402
from knit_nlp.weft.model.parametrisation import Full  # noqa: E402
from knit_nlp.weft.model.params import WeftParams  # noqa: E402
from knit_nlp.weft.solving.variants import equilibrium  # noqa: E402


def crossing_states(sm: SpecimenModel, material: dict[str, float], us: np.ndarray,
                    xs: list[np.ndarray]) -> list[dict[str, np.ndarray]]:
    """Each node's crossings: material coordinates on both yarns and normal force (N)."""
    out = []
    for u, x in zip(us, xs):
        block = sm.eq.wnlp.spatial_block(x, sm.params(material, u))
        rows = block["crossings"]
        out.append({k: np.array([r[k] for r in rows]) for k in ("s_upper", "s_lower", "force")})
    return out


def dissipation(states: list[dict[str, np.ndarray]], us: np.ndarray,
                force: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step: the crossings' dissipation at mu = 1 (N mm) and the clamp's work (N mm)."""
    d, w = [], []
    for a, b, du, f in zip(states[:-1], states[1:], np.diff(us), 0.5 * (force[:-1] + force[1:])):
        slip = np.hypot(b["s_upper"] - a["s_upper"], b["s_lower"] - a["s_lower"])
        d.append(float(np.sum(0.5 * (np.abs(a["force"]) + np.abs(b["force"])) * slip)))
        w.append(float(f * du))
    return np.array(d), np.array(w)


def run(direction: str, size: int, to: float, max_time: float) -> dict[str, Any]:
    BASE["solver"]["max_time"] = max_time
    doc = doc_of("3d")
    sp = build_specimen(doc, "<friction>", direction, size, size, f"friction_{direction}")
    sm = SpecimenModel(sp)
    t0 = time.perf_counter()
    strains = np.round(np.arange(STEP, to + 1e-9, STEP), 4)
    c = sm.pull_to(doc["material"], strains)
    states = crossing_states(sm, doc["material"], c.u, c.xs)
    d, w = dissipation(states, c.u, c.force)
    strain = c.u / sp.gauge
    print(f"{direction}, {size} x {size}: reached {strain[-1]:.3f} ({c.reason or 'complete'}), "
          f"{time.perf_counter() - t0:.0f} s")
    print("| step (strain) | clamp work W (N mm) | crossings' D at mu = 1 (N mm) | D / W |"
          " largest crossing N (N) | mean slip (mm) |")
    print("|---|---|---|---|---|---|")
    for k in range(d.size):
        slip = np.hypot(states[k + 1]["s_upper"] - states[k]["s_upper"],
                        states[k + 1]["s_lower"] - states[k]["s_lower"])
        print(f"| {strain[k]:.3f}-{strain[k + 1]:.3f} | {w[k]:.4g} | {d[k]:.4g} | "
              f"{d[k] / w[k] if w[k] > 0 else float('nan'):.3g} | "
              f"{np.max(np.abs(states[k + 1]['force'])):.4g} | {np.mean(slip):.4g} |")
    total = float(d.sum() / w.sum()) if w.sum() > 0 else float("nan")
    print(f"total: W {w.sum():.4g} N mm, D(mu = 1) {d.sum():.4g} N mm, D / W {total:.3g}")
    return {"direction": direction, "size": size, "strain": strain.tolist(),
            "force_N": c.force.tolist(), "work_Nmm": w.tolist(), "dissipation_mu1_Nmm": d.tolist(),
            "ratio_total": total, "reason": c.reason}


def path_with_friction(direction: str, size: int, to: float, mu: float,
                       max_time: float, step: float = STEP) -> dict[str, Any]:
    """The specimen pulled to strain ``to`` along one load path of ``step`` strain steps with
    friction ``mu`` (lagged per step): the force along the pull at every step reached, the
    clamp's work (trapezoid) and the path's dissipation."""
    BASE["solver"]["max_time"] = max_time
    doc = doc_of("3d")
    doc["yarn"] = {**doc["yarn"], "friction": mu}
    sp = build_specimen(doc, "<friction>", direction, size, size, f"friction_{direction}")
    eq = equilibrium(sp.problem, Full())
    eq.rounds_max, eq.refute = 0, False     # one load path, as the frictionless pulls above
    rows = eq.nlp.clamp_table.rigid_rows[PULLED - 1]
    rows = np.arange(rows.start, rows.stop).reshape(-1, 2)[:, sp.axis]
    p = WeftParams.of(sp.problem).with_(rigid={PULLED: sp.translation(to * sp.gauge)}).vector()
    t0 = time.perf_counter()
    eq.solver.start_clock()
    rep = eq.solver.continuation(p, eq.nlp.x0, int(round(to / step)))
    strain = [0.0] + [tau * to for tau, _, _ in rep.path]
    force = [0.0] + [float(-np.sum(lam[rows])) for _, _, lam in rep.path]
    path = rep.friction
    dis = None if path is None else path.earlier + path.last
    print(f"mu {mu}: {rep.status}, reached {strain[-1]:.4f}, {rep.iterations} it, "
          f"{time.perf_counter() - t0:.0f} s, dissipation {dis}", flush=True)
    work = float(np.trapezoid(force, np.array(strain) * sp.gauge))
    return {"mu": mu, "step": step, "strain": strain, "force_N": force, "status": rep.status,
            "dissipation_Nmm": dis, "work_Nmm": work, "wall_s": time.perf_counter() - t0,
            "iterations": rep.iterations, "pitch_width_mm": sp.pitch_width, "gauge_mm": sp.gauge}


def compare(runs: list[dict[str, Any]]) -> None:
    """Force at 10 % and 30 %, K(45 %)/K(5 %) (K: central differences over +-2.5 %) per run."""
    def at(r: dict[str, Any], e: float) -> float:
        return float(np.interp(e, r["strain"], r["force_N"])) if r["strain"][-1] >= e - 1e-9 \
            else float("nan")
    print("| mu | step | F(10 %) N | F(30 %) N | K(45 %)/K(5 %) | reached | W (N mm) | D / W |"
          " IPOPT it | wall s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in runs:
        k = [(at(r, e + STEP) - at(r, e - STEP)) / (2 * STEP) for e in (0.05, 0.45)]
        ratio = (r["dissipation_Nmm"] or 0.0) / r["work_Nmm"]
        print(f"| {r['mu']} | {r['step']} | {at(r, 0.1):.4g} | {at(r, 0.3):.4g} | "
              f"{k[1] / k[0]:.3g} | {r['strain'][-1]:.3f} | {r['work_Nmm']:.4g} | {ratio:.3g} | "
              f"{r['iterations']} | {r['wall_s']:.0f} |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=6)
    ap.add_argument("--to", type=float, default=0.3, help="largest strain")
    ap.add_argument("--direction", choices=("courses", "wales", "both"), default="both")
    ap.add_argument("--max-time", type=float, default=120.0, help="wall seconds per step")
    ap.add_argument("--out", default="results")
    ap.add_argument("--mu", type=float, default=None,
                    help="the built friction: one load path with this mu and one without")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    dirs = ("courses", "wales") if args.direction == "both" else (args.direction,)
    if args.mu is not None:
        runs = [path_with_friction(d, args.size, args.to, mu, args.max_time, step)
                for d in dirs for mu, step in ((0.0, STEP), (args.mu, STEP),
                                               (args.mu, STEP / 2))]
        compare(runs)
        (out / "friction_weft3d_built.json").write_text(json.dumps(runs, indent=1))
        return 0
    res = [run(d, args.size, args.to, args.max_time) for d in dirs]
    (out / "friction_weft3d.json").write_text(json.dumps(res, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
