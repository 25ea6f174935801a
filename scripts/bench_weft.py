"""Benchmark: build and solve diagonal pulls of growing size; fit how time grows with loops.

Each size runs in its own process so its peak memory (max RSS) is its own. The pull is the
paper's eq. 28 map (``knit_nlp.weft.model.cases.diagonal_pull``), as in problems/diagonal_pull.toml.

    python scripts/bench_weft.py [--sizes 5 10 20 50 100] [--reduced]
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time

import numpy as np

def run_one(n: int, reduced: bool) -> dict:
    from knit_nlp.weft.api import solve
    from knit_nlp.weft.model.cases import diagonal_pull
    from knit_nlp.weft.model.parametrisation import Full, Reduced
    from knit_nlp.weft.model.problem import parse_problem
    t0 = time.perf_counter()
    pr = parse_problem(diagonal_pull(n), f"<bench {n}x{n}>")
    r = solve(pr, Reduced() if reduced else Full())
    t = r.timings
    return {"n": n, "loops": n * n, "success": r.success, "iterations": r.iterations,
            "build_s": t["build_s"], "solve_s": t["solve_s"],
            "total_s": time.perf_counter() - t0, "energy": r.energy.total,
            "n_variables": r.nlp.n_variables, "profile": t["profile"],
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


FULL_SIZES = [5, 10, 20, 50, 100]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[5, 10, 20, 50],
                    help="N x N sizes (default 5 10 20 50: about 15 s)")
    ap.add_argument("--full-sizes", action="store_true",
                    help=f"the sizes of docs/measurements.md {FULL_SIZES} (about a minute and a half)")
    ap.add_argument("--reduced", action="store_true", help="solve the reduced (corner) model")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.full_sizes:
        args.sizes = FULL_SIZES
    if args.one:
        print(json.dumps(run_one(args.one, args.reduced)))
        return
    rows = []
    print(f"{'size':>8} {'loops':>6} {'vars':>7} {'ok':>3} {'iter':>5} {'build s':>8} "
          f"{'solve s':>8} {'total s':>8} {'peak MB':>8}  (hess/jac/f+g seconds)")
    for n in args.sizes:
        cmd = [sys.executable, __file__, "--one", str(n)] + (["--reduced"] if args.reduced else [])
        r = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
        rows.append(r)
        p = r["profile"]
        print(f"{n:>4}x{n:<3} {r['loops']:>6} {r['n_variables']:>7} {'y' if r['success'] else 'N':>3} "
              f"{r['iterations']:>5} {r['build_s']:>8.3f} {r['solve_s']:>8.3f} {r['total_s']:>8.3f} "
              f"{r['peak_mb']:>8.0f}  ({p.get('nlp_hess_l', 0):.3f}/{p.get('nlp_jac_g', 0):.3f}/"
              f"{p.get('nlp_f', 0) + p.get('nlp_g', 0):.3f})", flush=True)
    if len(rows) >= 3:
        big = [r for r in rows if r["loops"] >= 100] or rows
        loops = np.log([r["loops"] for r in big])
        for key in ("build_s", "solve_s", "total_s"):
            slope = np.polyfit(loops, np.log([r[key] for r in big]), 1)[0]
            print(f"time ~ loops^{slope:.2f} for {key} (fit over sizes with >= 100 loops)")


if __name__ == "__main__":
    main()
