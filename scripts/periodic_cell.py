"""The 3-D weft model's loop as a periodic cell pulled along the courses or the wales: the same
physics as the free-edged specimens of ``knit-nlp calibrate`` with no edges (issue 40's
question: is it the specimen's free edges that make the model ~10 times too soft?).

The cell, its energy and its check are the package's (``knit_nlp.weft.model.spatial.periodic``;
``knit-nlp calibrate`` uses it with ``[calibrate] specimen = "periodic"``). The force through
a cell is the pull row's multiplier; per width F / c₀ (courses) or F / w₀ (wales); at a
specimen's real width times the width, the test file's width in clamps times 35.5 mm (66.56 mm
along the courses, 95.87 mm along the wales; docs/real_fabric.md). This script adds levers the
calibration does not offer (a straight yarn's bending reference, k and R_f times a factor)
and checks every node.
With ``--held`` the spacing across the pull is held at its natural value (plane strain, the
limit of clamps that keep a specimen's width) instead of free (uniaxial stress, the cell's
reading in ``calibrate``). ``--friction-estimate MU`` prints what Coulomb friction μ would
add to the force (the cell has none), at the two wraps and at the other pairs: μ × each step's
normal forces × its slides.
With ``--straight`` the cell is first relaxed at zero force (w and c free) and the pull starts
there, its force relative to that state's.

    python scripts/periodic_cell.py [--spec real_fabric/acrylic_3d_source] [--straight]
                                    [--to 0.6] [--step 0.025] [--samples 80] [--reach 2.5]
                                    [--rigidity-factor K] [--bending-factor B] [--held]
                                    [--friction-estimate MU]

Prints one line per strain node and, per direction, ``calibrate``'s checks of the curve at the
test's real width (``calibration.checks``: F at 10 % and 30 %, the stiffness per width at 10 %,
the tangent stiffening from 5 % to 45 %), model beside measured, and its metric
(``calibration.metric``: the RMS axial and lateral strain errors at 2-25 N; n/a where the
curve does not reach 25 N).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from knit_nlp.tomlio import load_toml  # noqa: E402
from knit_nlp.weft.inverse.calibration.checks import outcome_checks  # noqa: E402
from knit_nlp.weft.inverse.calibration.measured import (MeasuredTest,  # noqa: E402
                                                        read_stitch_by_stitch)
from knit_nlp.weft.inverse.calibration.metric import METRIC_FORCES, metric  # noqa: E402
from knit_nlp.weft.inverse.calibration.spec import CLAMP_WIDTH_MM  # noqa: E402
from knit_nlp.weft.model.compression import SoftShell  # noqa: E402
from knit_nlp.weft.model.problem import WeftProblem, parse_problem  # noqa: E402
from knit_nlp.weft.model.spatial.periodic import (PeriodicCell, build_cell,  # noqa: E402
                                                  cell_pairs, check_cell, contact_state,
                                                  natural_state, pair_state, relaxed,
                                                  solve_cell)

TESTS = {"courses": "acrylic_stockinette_x.csv", "wales": "acrylic_stockinette_y.csv"}


def pull(cell: PeriodicCell, R_f: float, strains: np.ndarray, x0: np.ndarray,
         say=print, held: bool = False) -> list[dict]:
    """The cell pulled through ``strains`` (each node from the last), the first from x0 at 0,
    the spacing across free or ``held``; each node checked (:func:`check`)."""
    out, x, last = [], x0, 0.0
    for e in strains:
        sol = solve_cell(cell, (1 + e) * cell.spacing0, R_f, x, held=held)
        if not sol.success:
            say(f"  {cell.direction} {e:+.3f}: {sol.status} ({sol.iterations} it): stop")
            break
        rub = coulomb_per_pull(cell, x, sol.x, (e - last) * cell.spacing0)   # (wraps, others)
        x, last = sol.x, e
        rep = {"x": x, "U": sol.U, "F": sol.F, "iterations": sol.iterations, "rub": rub}
        verdict = check_cell(cell, x)
        rep.update(strain=float(e), lateral=cell.across(x) / cell.across0 - 1, clean=verdict.ok)
        out.append(rep)
        bending = float(cell.energy(x, [0.0, R_f, 0.0]))
        others = float(np.sum(pair_state(cell, x)[1]))
        say(f"  {cell.direction} {e:+.3f}: F {rep['F']:.5g} N per cell, lateral "
            f"{rep['lateral']:+.4f}, U {rep['U']:.6g} N mm (bending {bending:.4g}, wraps "
            f"{rep['U'] - bending - others:.4g}, other pairs {others:.4g}; "
            f"{rep['iterations']} it); {verdict.verdict()}")
    return out


def coulomb_per_pull(cell: PeriodicCell, before: np.ndarray, after: np.ndarray,
                     du: float) -> tuple[float, float]:
    """What Coulomb friction of μ = 1 would add to the force along the pull over a frictionless
    step from ``before`` to ``after`` (travel du), if the yarns slid as they do without it:
    (at the two designed wraps, Σ N̄|Δ| / du with friction.py's F1, F4; at the other pairs,
    Σ N̄ |Δr_t| / du, Δr_t the tangential part of the change of the vector between a pair's two
    material samples), N̄ the step's start's (``periodic.contact_state``, ``pair_state``).
    With friction the yarns slide less; on the clamped specimens the wraps' estimate overstated
    the friction measured (docs/weft3d.md "Friction")."""
    lag = contact_state(cell, before)
    n = lag.normal.size
    sig = after[-2 - 2 * n:-2]
    wraps = float(np.sum(lag.normal * lag.slides(sig[:n], sig[n:])))
    r0, _, push = pair_state(cell, before)
    dr = np.asarray(cell.pair_vectors(after)) - r0
    normal = r0 / np.linalg.norm(r0, axis=0)
    slide = np.linalg.norm(dr - normal * np.einsum("ip,ip->p", dr, normal), axis=0)
    others = float(np.sum(np.where(push > 0, push, 0.0) * slide))
    return wraps / du, others / du


def spec_problem(name: str) -> WeftProblem:
    """The weft problem of calibration spec ``name``'s yarn (its [loop], [material], [yarn] and
    [units], on a 2 × 2 fabric): the yarn's natural loop and law."""
    spec = load_toml(ROOT / "problems" / f"{name}.toml")
    doc = {k: spec[k] for k in ("loop", "material", "yarn", "units") if k in spec}
    doc["fabric"] = {"courses": 2, "wales": 2}
    return parse_problem(doc, f"{name}.toml")


def measured(direction: str) -> MeasuredTest:
    """The measured pull along ``direction`` (problems/real_fabric, stitch-by-stitch's data)."""
    name = TESTS[direction]
    return read_stitch_by_stitch(ROOT / "problems" / "real_fabric" / name, name)


def curve(cell: PeriodicCell, nodes: list[dict], f0: float, width: float) -> tuple[np.ndarray, ...]:
    """(axial strain, force at the real ``width`` (N), lateral strain) from the unloaded
    state on: the force per cell less ``f0``, per mm of the cell's reference width, times
    the width."""
    e = np.array([0.0] + [n["strain"] for n in nodes])
    F = np.array([0.0] + [n["F"] - f0 for n in nodes]) / cell.across0 * width
    lat = np.array([0.0] + [n["lateral"] for n in nodes])
    return e, F, lat


def at_forces(e: np.ndarray, F: np.ndarray, y: np.ndarray, forces) -> np.ndarray:
    """y at the first point of the curve whose force reaches each force (linear between
    nodes), NaN where it never does: the model's side of calibrate's metric."""
    out = np.full(len(forces), np.nan)
    for k, force in enumerate(forces):
        hits = np.flatnonzero(F >= force)
        if hits.size and hits[0] > 0:
            i = int(hits[0])
            out[k] = y[i - 1] + (y[i] - y[i - 1]) * (force - F[i - 1]) / (F[i] - F[i - 1])
    return out


def compare(cell: PeriodicCell, nodes: list[dict], f0: float, test: MeasuredTest) -> dict:
    """calibrate's checks (``checks.outcome_checks``, model beside measured) and its metric
    (``metric.metric`` at METRIC_FORCES: RMS axial and lateral strain errors, None where the
    curve does not reach every force) of the cell's curve at the test's real width."""
    width = test.width_clamps * CLAMP_WIDTH_MM
    e, F, lat = curve(cell, nodes, f0, width)
    checks = outcome_checks((e, F), [(r.axial, r.force) for r in test.runs], width)
    pts = metric(test, METRIC_FORCES, at_forces(e, F, e, METRIC_FORCES),
                 at_forces(e, F, lat, METRIC_FORCES))
    return {"checks": checks, "rms_axial": pts.rms_axial, "rms_lateral": pts.rms_lateral,
            "width_mm": width, "top_N": float(F.max())}


def _show(v: float | None, fmt: str = ".3g") -> str:
    return "n/a" if v is None else f"{v:{fmt}}"


def checks_line(c: dict) -> str:
    """The checks, model (measured), and the metric of a comparison (:func:`compare`)."""
    mo, me = c["checks"]["model"], c["checks"]["measured"]

    def pair(key: str, sub: str | None = None) -> str:
        a, b = (d[key] if sub is None else d[key][sub] for d in (mo, me))
        return f"{_show(a)} ({_show(b)})"
    return (f"model (measured): F(10 %) {pair('force_N', '0.1')} N, F(30 %) "
            f"{pair('force_N', '0.3')} N, K/W(10 %) {pair('stiffness_per_width')} N/mm, "
            f"stiffening 5 -> 45 % {pair('stiffening')}; RMS strain error axial "
            f"{_show(c['rms_axial'], '.4f')}, lateral {_show(c['rms_lateral'], '.4f')}")


def summary(direction: str, seconds: float, nodes: list[dict], spacing0: float, c: dict) -> str:
    """One line: how far and how clean the pull went, the checks model (measured) and the
    metric."""
    dirty = next((n["strain"] for n in nodes if not n["clean"]), None)
    reached = nodes[-1]["strain"] if nodes else 0.0
    clean = "every node clean" if dirty is None else f"not clean from {dirty:.3f}"
    return (f"{direction} ({seconds:.0f} s, reached {reached:.3f} from {spacing0:.4f} mm, {clean}"
            f"; at {c['width_mm']:.1f} mm, up to {c['top_N']:.3g} N), {checks_line(c)}")


def offset_shares(cell: PeriodicCell, nodes: list[dict], reach: float, strain: float = 0.1
                  ) -> str:
    """The other pairs' energy at the node at ``strain`` by the lattice offset between the two
    loops (courses up, wales across; (0, 0): the loop with itself), largest first."""
    near = [n for n in nodes if abs(n["strain"] - strain) < 1e-6]
    if not near:
        return f"{cell.direction}: no node at {100 * strain:g} %"
    energy = pair_state(cell, near[0]["x"])[1]
    _, _, _, di, dj, _ = cell_pairs(cell.natural, cell.law, cell.samples, reach)
    shares: dict[tuple[int, int], float] = {}
    for key, v in zip(zip(di.tolist(), dj.tolist()), energy):
        shares[key] = shares.get(key, 0.0) + float(v)
    total = sum(shares.values())
    top = sorted(shares.items(), key=lambda kv: -kv[1])[:4]
    return (f"{cell.direction}: the other pairs' energy at {100 * strain:g} % ({total:.4g} N mm) "
            f"by offset (courses, wales): "
            + ", ".join(f"({a}, {b}) {100 * v / total:.0f} %" for (a, b), v in top))


def friction_line(direction: str, nodes: list[dict], mu: float) -> str:
    """What Coulomb friction μ would add to the force (``coulomb_per_pull``), as a share of the
    frictionless force, at the wraps and at the other pairs, at the nodes at 5, 10, 30 and
    45 % strain."""
    parts = []
    for e in (0.05, 0.1, 0.3, 0.45):
        near = [n for n in nodes if abs(n["strain"] - e) < 1e-6]
        if near and near[0]["F"] > 0:
            wraps, others = (100 * mu * v / near[0]["F"] for v in near[0]["rub"])
            parts.append(f"at {100 * e:g} %: wraps +{wraps:.1f} %, other pairs +{others:.1f} %")
    return (f"{direction}: Coulomb friction mu = {mu:g} would add about (estimated from the "
            f"frictionless slides and normal forces) {'; '.join(parts) or 'n/a'} of the force")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", default="real_fabric/acrylic_3d_source",
                    help="a calibration spec under problems/ whose [loop], [material] and "
                         "[yarn] give the yarn")
    ap.add_argument("--straight", action="store_true")
    ap.add_argument("--to", type=float, default=0.6, help="the largest strain (the measured "
                    "course pulls end near 60 %%)")
    ap.add_argument("--step", type=float, default=0.025)
    ap.add_argument("--samples", type=int, default=80, help="repulsion samples per loop")
    ap.add_argument("--rigidity-factor", type=float, default=1.0,
                    help="the contact rigidity k times this (a lever, not a fit)")
    ap.add_argument("--bending-factor", type=float, default=1.0, help="R_f times this")
    ap.add_argument("--reach", type=float, default=2.5,
                    help="the other pairs listed: naturally closer than REACH x 2r")
    ap.add_argument("--friction-estimate", type=float, default=0.0, metavar="MU",
                    help="estimate what Coulomb friction mu at the wraps and the other pairs "
                         "would add (the cell has none): mu x normal force x frictionless slide")
    ap.add_argument("--held", action="store_true",
                    help="hold the spacing across the pull (plane strain: clamps that keep the "
                         "width) instead of leaving it free (uniaxial stress)")
    ap.add_argument("--directions", default="courses,wales")
    args = ap.parse_args(argv)
    pr = spec_problem(args.spec)
    shape, law = pr.yarn.natural3d, pr.yarn.shell()
    law = SoftShell(law.radius, law.core_radius, law.rigidity * args.rigidity_factor,
                    law.exponent)
    R_f = pr.R_f * args.bending_factor
    print(f"{args.spec}: natural lattice w = {shape.wale_spacing:.4f} mm, c = "
          f"{shape.course_spacing:.4f} mm; bending from "
          f"{'a straight yarn' if args.straight else 'the natural loop'}; the spacing across "
          f"{'held' if args.held else 'free'}; k = {law.rigidity:g} "
          f"N/mm^3, R_f = {R_f:g} N mm^2")
    strains = np.round(np.arange(args.step, args.to + 1e-9, args.step), 6)
    for direction in args.directions.split(","):
        t0 = time.perf_counter()
        cell = build_cell(shape, law, direction, args.samples, args.straight, args.reach)
        rest = solve_cell(cell, cell.spacing0, R_f, natural_state(shape), free=args.straight)
        if not rest.success:
            print(f"{direction}: the cell at rest did not converge ({rest.status})")
            continue
        x0 = rest.x
        spacing0 = cell.along(x0)
        print(f"{direction}: {cell.pairs} other pairs; at rest F {rest.F:.3g} N, U "
              f"{rest.U:.6g} N mm, lattice ({x0[-2]:.4f}, {x0[-1]:.4f}) mm")
        if args.straight:
            relaxed(cell, x0)
        nodes = pull(cell, R_f, strains, x0, held=args.held)
        c = compare(cell, nodes, rest.F if args.straight else 0.0, measured(direction))
        print(summary(direction, time.perf_counter() - t0, nodes, spacing0, c))
        if args.friction_estimate > 0:
            mu = args.friction_estimate
            print(friction_line(direction, nodes, mu))
            print(offset_shares(cell, nodes, args.reach))
            rubbed = [{**n, "F": n["F"] + mu * sum(n["rub"])} for n in nodes]
            c = compare(cell, rubbed, rest.F if args.straight else 0.0, measured(direction))
            print(summary(f"{direction} + the friction estimate", time.perf_counter() - t0,
                          rubbed, spacing0, c))
    return 0


if __name__ == "__main__":
    sys.exit(main())
