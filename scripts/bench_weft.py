"""Benchmark: build and solve weft pulls of growing size; the split of the time; how it grows.

Each size runs in its own process so its peak memory (max RSS) and CPU time are its own. The
pull is the paper's eq. 28 map (``knit_nlp.weft.model.cases.diagonal_pull``), as in
problems/diagonal_pull.toml, or the course pull. BLAS threads are set (``--threads``, default
1) in every child process before numpy or CasADi load, and printed.

Printed per size: iterations of the final solve, build (transcription, closed-form derivatives,
``nlpsol``), the multilevel start's coarse solves, the final solve split into evaluations
(IPOPT's ``t_wall_nlp_*``) and IPOPT's own time (its linear algebra: MUMPS analysis,
factorisations, solves), wall and CPU end to end in the process, peak MB. With three sizes or
more, the growth exponent of each time against the loops.

    python scripts/bench_weft.py [--sizes 5 10 20 50 100] [--reduced] [--threads 1]
    python scripts/bench_weft.py --sizes 100 150 200 300       # docs/measurements.md, "Scale"
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")


def run_one(n: int, pull: str, reduced: bool) -> dict:
    """Read, build and solve one fabric in this process; report effort, split and memory."""
    sys.path.insert(0, str(ROOT))
    from knit_nlp.weft.api import solve
    from knit_nlp.weft.model.cases import course_pull, diagonal_pull
    from knit_nlp.weft.model.parametrisation import Full, Reduced
    from knit_nlp.weft.model.problem import parse_problem
    t0, c0 = time.perf_counter(), time.process_time()
    pr = parse_problem((diagonal_pull if pull == "diagonal" else course_pull)(n),
                       f"<bench {n}x{n}>")
    r = solve(pr, Reduced() if reduced else Full())
    rep = r.report
    coarse = sum(float(m.group(1)) for a in rep.attempts
                 for m in [re.search(r"multilevel .*, ([0-9.]+) s\)$", a)] if m)
    evals = sum(v for k, v in rep.stats.items() if k.startswith("t_wall_nlp"))
    final = rep.solve_s - coarse
    return {"n": n, "loops": n * n, "success": r.success, "iterations": r.iterations,
            "build_s": r.build_s, "coarse_s": coarse, "eval_s": evals,
            "ipopt_s": final - evals, "solve_s": rep.solve_s,
            "total_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
            "energy": r.energy.total, "n_variables": r.nlp.n_variables,
            "n_constraints": r.nlp.n_constraints, "attempts": rep.attempts,
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


FULL_SIZES = [5, 10, 20, 50, 100]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[5, 10, 20, 50],
                    help="N x N sizes (default 5 10 20 50: about 15 s)")
    ap.add_argument("--full-sizes", action="store_true",
                    help=f"the sizes of docs/measurements.md {FULL_SIZES} (about a minute and a half)")
    ap.add_argument("--pull", choices=["diagonal", "course"], default="diagonal")
    ap.add_argument("--reduced", action="store_true", help="solve the reduced (corner) model")
    ap.add_argument("--threads", type=int, default=1, help="BLAS threads (default 1)")
    ap.add_argument("--json", type=Path, help="also write all rows to this file")
    ap.add_argument("--one", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.full_sizes:
        args.sizes = FULL_SIZES
    if args.one:
        print(json.dumps(run_one(args.one, args.pull, args.reduced)))
        return
    env = {**os.environ, **{v: str(args.threads) for v in THREAD_VARS}}
    print("BLAS threads: " + ", ".join(f"{v}={env[v]}" for v in THREAD_VARS)
          + f"; load average at start {os.getloadavg()[0]:.1f}")
    rows = []
    print(f"{'size':>8} {'loops':>6} {'KKT rows':>9} {'ok':>3} {'iter':>4} {'build s':>8} "
          f"{'coarse s':>8} {'eval s':>7} {'IPOPT s':>8} {'wall s':>8} {'CPU s':>7} {'peak MB':>8}"
          f" {'energy':>14}", flush=True)
    for n in args.sizes:
        cmd = [sys.executable, __file__, "--one", str(n), "--pull", args.pull] + (
            ["--reduced"] if args.reduced else [])
        r = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True,
                                      env=env).stdout.strip().splitlines()[-1])
        rows.append(r)
        print(f"{n:>4}x{n:<3} {r['loops']:>6} {r['n_variables'] + r['n_constraints']:>9} "
              f"{'y' if r['success'] else 'N':>3} {r['iterations']:>4} {r['build_s']:>8.2f} "
              f"{r['coarse_s']:>8.2f} {r['eval_s']:>7.2f} {r['ipopt_s']:>8.2f} "
              f"{r['total_s']:>8.2f} {r['cpu_s']:>7.2f} {r['peak_mb']:>8.0f} "
              f"{r['energy']:>14.9g}", flush=True)
    print(f"load average at end {os.getloadavg()[0]:.1f}")
    big = [r for r in rows if r["loops"] >= 100]
    if len(big) >= 3:
        import numpy as np
        loops = np.log([r["loops"] for r in big])
        for key in ("build_s", "coarse_s", "eval_s", "ipopt_s", "total_s", "cpu_s", "peak_mb"):
            values = [max(r[key], 1e-9) for r in big]
            slope = np.polyfit(loops, np.log(values), 1)[0]
            print(f"{key} ~ loops^{slope:.2f} (fit over sizes with >= 100 loops)")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
