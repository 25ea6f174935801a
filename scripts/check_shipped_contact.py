"""Issue 19's first target on every shipped weft problem: solved with a yarn radius, no new
crossing and no gap below 2r·(1 − 1e-3), judged by the independent checker
(``knit_nlp.weft.output.check``: 200 samples per loop, crossings counted against the natural
fabric), not by the solver's own contact block. A 3-D problem (``[yarn] geometry = "3d"``)
is solved in 3-D and judged by its independent all-pairs 3-D check (flipped designed crossings
in the "new crossings" column, pairs of loops inside the hard core in "short gaps").

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python scripts/check_shipped_contact.py \
        [--names diagonal_pull wada_fig7] [--radius 0.015] [--budget 900] [--out DIR]

Each problem is solved as ``knit-nlp solve`` solves it (its clamps, loads and continuation)
with ``[yarn] radius`` = its own radius if it has one, else ``--radius`` loop lengths, given
``--budget`` seconds ([solver] max_time); control files are solved as forward problems at
their initial grip (``knit-nlp control`` with a radius is checked in docs/contact.md). Printed
per problem: seconds, solver status, active contacts, smallest gap / 2r, and the checker's
new crossings, short gaps and verdict; without the radius, the checker's new crossings of the
paper's model on the same problem. ``--out DIR``: each result with a radius is saved there as
``knit-nlp solve FILE --yarn`` saves it (JSON, NPZ, the picture with the yarn's thickness).
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import time


def _weft_names() -> list[str]:
    from knit_nlp.problems import named_problems
    return [name for name, model, _ in named_problems() if model == "weft"]


def check_one(name: str, radius_l: float, budget: float, out: str | None = None) -> dict:
    """Solve one shipped problem with and without a radius; the checker's verdict of both."""
    from knit_nlp.problems import resolve
    from knit_nlp.weft.api import solve
    from knit_nlp.weft.model.parametrisation import Full
    from knit_nlp.tomlio import load_toml
    from knit_nlp.weft.inverse.spec import strip_control_keys
    from knit_nlp.weft.model.problem import Yarn, parse_problem
    from knit_nlp.weft.output.check import check
    path = resolve(name)
    pr = parse_problem(strip_control_keys(load_toml(path)), path)
    pr = dataclasses.replace(pr, solver=dataclasses.replace(pr.solver, max_time=budget))
    r = pr.yarn.radius if pr.yarn is not None else radius_l * pr.L
    with_r = dataclasses.replace(pr, yarn=Yarn(r))
    paper = solve(dataclasses.replace(pr, yarn=None), Full())
    before = check(paper.to_json(), with_r)
    if pr.yarn is not None and pr.yarn.spatial:       # the 3-D model, judged by its own check
        return _spatial_row(name, pr, len(before.new_crossings), out)
    t0 = time.perf_counter()
    res = solve(with_r, Full())
    seconds = time.perf_counter() - t0
    after = check(res.to_json(), with_r)
    if out is not None:
        res.save(out, yarn=True)
    block = res.blocks().get("contact", {})
    return {"name": name, "radius": r, "seconds": seconds, "success": res.success,
            "status": res.status, "active": block.get("active"),
            "gap_over_2r": block.get("smallest_gap_over_2r"),
            "paper_new_crossings": len(before.new_crossings),
            "new_crossings": len(after.new_crossings), "short_gaps": after.n_short,
            "clean": res.success and after.ok}


def _spatial_row(name: str, pr, paper_new: int, out: str | None) -> dict:
    """A 3-D problem solved in 3-D (not as a planar contact problem of its radius), judged by
    the independent all-pairs 3-D check its result carries: 'new crossings' are designed
    crossings flipped, 'short gaps' pairs of loops inside the hard core 2R_c."""
    from knit_nlp.weft.api import solve
    t0 = time.perf_counter()
    res = solve(pr)
    seconds = time.perf_counter() - t0
    if out is not None:
        res.save(out)
    chk = res.checked
    return {"name": name, "radius": pr.yarn.radius, "seconds": seconds, "success": res.success,
            "status": res.status, "active": None, "gap_over_2r": None,
            "paper_new_crossings": paper_new, "new_crossings": int(chk.get("flipped", 0)),
            "short_gaps": int(chk.get("inside_core_count", 0)),
            "clean": res.success and bool(chk.get("ok"))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--names", nargs="*", help="shipped weft problems (default: all)")
    ap.add_argument("--radius", type=float, default=0.015,
                    help="radius in loop lengths where a problem has none (default 0.015)")
    ap.add_argument("--budget", type=float, default=900.0, help="seconds per contact solve")
    ap.add_argument("--out", help="save each result with a radius in this folder")
    args = ap.parse_args()
    threads = {v: os.environ.get(v, "unset") for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
    print(f"threads {threads}; cores {os.cpu_count()}; load average {os.getloadavg()[0]:.2f}")
    print(f"{'problem':24} {'r':>7} {'seconds':>8} {'active':>6} {'gap/2r':>8} "
          f"{'paper new crossings':>19} {'new crossings':>13} {'short gaps':>10}  verdict")
    for name in args.names or _weft_names():
        row = check_one(name, args.radius, args.budget, args.out)
        gap = "-" if row["gap_over_2r"] is None else f"{row['gap_over_2r']:.5f}"
        verdict = "clean" if row["clean"] else (
            "VIOLATIONS" if row["success"] else f"NOT CONVERGED ({row['status']})")
        print(f"{name:24} {row['radius']:7.4g} {row['seconds']:8.1f} {row['active'] or 0:6d} "
              f"{gap:>8} {row['paper_new_crossings']:19d} {row['new_crossings']:13d} "
              f"{row['short_gaps']:10d}  {verdict}", flush=True)
    print(f"load average at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
