"""What ``knit-nlp solve`` and ``knit-nlp compare`` print for weft problems."""
from __future__ import annotations

from pathlib import Path

from .comparison import Comparison
from .plausibility import summary_line as implausible
from .results import WeftResult


def solve_summary(r: WeftResult, paths: list[Path]) -> str:
    """A few lines: status, energy, sizes, reactions (a shorthand's clamps as one total), files
    written; every figure with its unit."""
    e, nlp, t, u = r.energy, r.nlp, r.timings, r.problem.units
    lines = [f"{r.problem.name} ({r.model}): {r.status} in {r.iterations} iterations"
             f" (build {t['build_s']:.2f} s, solve {t['solve_s']:.2f} s)",
             f"  energy {e.total:.6g} = spring {e.spring:.6g} + bending {e.bending:.6g};"
             f" load work {e.load_work:.6g} [{u.energy}]",
             f"  {nlp.n_parameters} parameters, {nlp.n_variables} variables, "
             f"{nlp.n_constraints} constraints, max violation {r.violation:.2e} [{u.length}]"]
    reps = r.representatives()
    if reps is not None and "asked" in reps:
        lines.append(f"  representatives {_grid(reps['asked'])} extended to {_grid(reps)}: the "
                     "clamps were dependent with their courses/wales interpolated")
    groups: dict[str, list] = {}
    for c in r.clamps:
        if c.group:
            groups.setdefault(c.group, []).append(c)
            continue
        lines.append(f"  {c.grip} {list(c.loop)} {c.point}: reaction "
                     f"({c.reaction[0]:.4g}, {c.reaction[1]:.4g}) [{u.force}]")
    for group, cs in groups.items():
        f = sum(c.reaction for c in cs)
        lines.append(f"  {group} = clamps {cs[0].number}-{cs[-1].number} ({len(cs)} points, "
                     f"{cs[0].point}): total reaction ({f[0]:.4g}, {f[1]:.4g}) [{u.force}]")
    for rc in r.rigid_clamps:
        lines.append(f"  rigid clamp {rc.number} ({len(rc.points)} points): force "
                     f"({rc.force[0]:.4g}, {rc.force[1]:.4g}) [{u.force}], moment "
                     f"{rc.moment:.4g} [{u.energy}]")
    contact = r.contact
    if contact is not None:
        gap = contact.smallest_gap
        lines.append(f"  yarn contact (r = {contact.radius:g} {u.length}): "
                     f"{contact.active} active, largest force {contact.largest_force:.4g} "
                     f"[{u.force}], smallest gap " + (f"{gap:.6g} [{u.length}] = "
                     f"{contact.smallest_gap_over_2r:.6g} x 2r" if gap is not None
                     else "none within reach") + f", {contact.new_crossings} new crossings")
    listed = getattr(r.nlp, "neighbours", None)               # the 3-D model's rounds
    if listed is not None:
        rounds = r.nlp.rounds
        failed = [x["status"] for x in rounds if x["status"] != "Solve_Succeeded"]
        lines.append(f"  other contacts: {len(listed)} pairs of sample points repel; "
                     f"{len(rounds)} round{'s' * (len(rounds) != 1)} added "
                     f"{sum(x['added'] for x in rounds)} pairs the "
                     "check found closer than 2r" + (f" (the last round's solve failed: "
                                                     f"{failed[0]}; its pairs not kept)"
                                                     if failed else ""))
    friction = (r.spatial or {}).get("friction")               # lagged friction (3-D)
    if friction is not None:
        lines.append(f"  friction: mu = {friction['mu']:g} at the designed crossings, lagged over "
                     f"{friction['load_steps']} load step{'s' * (friction['load_steps'] != 1)}; "
                     f"dissipated {friction['dissipation']:.4g} [{u.energy}]")
    lines.append("  check: " + r.checked["verdict"])
    lines += implausible(r)                     # springs beyond L, folds, loops inside out
    if not r.success:
        why = "; ".join(r.report.attempts) or r.message.removeprefix("not converged: ")
        lines.append("  NOT CONVERGED: " + why)
    lines.append("  wrote " + ", ".join(str(p) for p in paths))
    return "\n".join(lines)


def _grid(reps: dict) -> str:
    """"courses [1, 5], wales [1, 5]" shortened to counts beyond 8 entries."""
    def one(v: list[int]) -> str:
        return str(v) if len(v) <= 8 else f"{len(v)} of {v[0]}..{v[-1]}"
    return f"courses {one(reps['courses'])}, wales {one(reps['wales'])}"


def compare_summary(cmp: Comparison, paths: list[Path]) -> str:
    """One line per model, the distances, the speed ratio and the files written."""
    lines = [f"{cmp.full.problem.name}: full vs reduced"]
    for key, r in cmp.models().items():
        lines.append(f"  {key:<24} {r.status:<18} params {r.nlp.n_parameters:>6}  energy "
                     f"{r.energy.total:.6g} {r.problem.units.energy}  iterations {r.iterations:>4}  build+solve "
                     f"{r.build_s + r.report.solve_s:.3f} s")
    pr = cmp.full.problem
    reps = cmp.representatives
    if reps is not None:
        asked = f" (asked {_grid(reps['asked'])})" if "asked" in reps else ""
        lines.append(f"  reduced grid: {_grid(reps)}{asked} of {pr.courses} courses x "
                     f"{pr.wales} wales")
    lines.append(f"  centreline distance: max {cmp.distance_max:.4g}, rms {cmp.distance_rms:.4g} "
                 f"[{pr.units.length}] = {cmp.distance_rms / pr.L:.3g} loop lengths L "
                 f"(L = {pr.L:.4g})")
    speed = cmp.speedup_reduced
    pace = f"{speed:.1f}x faster" if speed >= 1 else f"{1 / speed:.1f}x slower"
    lines.append(f"  reduced is {pace} than full (build + solve); energy gap (reduced - full) "
                 f"{cmp.energy_gap:.4g}, ratio {cmp.energy_ratio:.4g}")
    if cmp.full_warm_from_reduced is None:
        lines.append("  full model warm-started from the reduced: not solved (--warm solves it)")
    lines.append("  " + cmp.verdict)
    lines += _frontier_lines(cmp)
    lines.append("  wrote " + ", ".join(str(p) for p in paths))
    return "\n".join(lines)


def _frontier_lines(cmp: Comparison) -> list[str]:
    """``--grids``: one line per even grid (accuracy against time) and the fastest within the
    verdict's limits."""
    if not cmp.frontier:
        return []
    pr = cmp.full.problem
    lines = [f"  even grids against the full model (distances in {pr.units.length}, L = {pr.L:.4g}):",
             "    k x k   params  build+solve s  speed-up  rms (L)          max      energy ratio  "
             "within limits"]
    for g in cmp.frontier:
        ok = {True: "yes", False: "no", None: "failed"}[g.ok]
        rms = f"{g.distance_rms:.3g} ({g.distance_rms / pr.L:.2g})"
        lines.append(f"    {g.k:>2} x {g.k:<2} {g.n_parameters:>8}  {g.seconds:>13.3f}  "
                     f"{g.speedup:>7.2f}x  {rms:<16} {g.distance_max:>7.3g}  "
                     f"{g.energy_ratio:>12.4g}  {ok}")
    best = cmp.fastest_ok
    if best is None:
        verdict = "none of these: use the full model"
    elif best.speedup < 1:
        verdict = (f"{best.k} x {best.k}, but it is slower than the full model "
                   f"({best.speedup:.2f}x its speed): use the full model")
    else:
        verdict = f"{best.k} x {best.k}, {best.speedup:.2f}x the full model's speed"
    lines.append(f"  fastest grid within the limits: {verdict}")
    return lines
