"""Benchmark the answer's own check (issue 41, item 1: at most 10 % of the solve and 500 MB): the
n x n diagonal pull (eq. 28 scaled) solved in the paper's model, then its own check
(``WeftResult.checked``: crossings against the natural fabric), both timed in one process, and
the check repeated (its k-d tree and natural tables then warm), with the peak RSS of the
process (the solve's, mostly) and of the check alone: the same state checked in a fresh Python
process (``knit-nlp check``'s work: imports, natural tables, crossings), its wall time and
peak RSS.

    OMP_NUM_THREADS=1 python scripts/bench_check.py [--size 100] [--repeats 2] [--radius R]

``--radius R`` judges the same answer at a yarn radius as ``knit-nlp check --problem`` with
``[yarn] radius = R`` would (the paper's folded answer then has millions of short gaps: a
slow, pathological case, docs/contact.md).
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

FRESH = """
import sys, time
import numpy as np
t0 = time.perf_counter()
from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.output.check import check_state
state = np.load(sys.argv[2])
n = int(sys.argv[1])
report = check_state(parse_problem(diagonal_pull(n), "pull"), state["coefficients"],
                     state["starts"])
# VmHWM: this process's peak (ru_maxrss would carry the parent's over fork and exec)
peak = [int(line.split()[1]) for line in open("/proc/self/status")
        if line.startswith("VmHWM")][0]
print(f"{time.perf_counter() - t0:.2f} s, peak RSS {peak / 1024:.0f} MB: {report.verdict()}")
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--radius", type=float, default=None)
    args = ap.parse_args()
    from knit_nlp.weft.api import solve
    from knit_nlp.weft.model.cases import diagonal_pull
    from knit_nlp.weft.model.parametrisation import Full
    from knit_nlp.weft.model.problem import Yarn, parse_problem
    from knit_nlp.weft.output.check import check_state
    n = args.size
    pr = parse_problem(diagonal_pull(n), f"<bench {n}x{n}>")
    print(f"load average {os.getloadavg()[0]:.2f} at the start; cores={os.cpu_count()}")
    t0 = time.perf_counter()
    res = solve(pr, Full())
    solved = time.perf_counter() - t0
    t0 = time.perf_counter()
    block = res.checked
    checked = time.perf_counter() - t0
    print(f"{n} x {n}: solve (build included) {solved:.2f} s, {res.status}; own check "
          f"{checked:.2f} s = {100 * checked / solved:.1f} % of it: {block['verdict']}")
    judged = pr if args.radius is None else dataclasses.replace(pr, yarn=Yarn(args.radius))
    for k in range(args.repeats):
        t0 = time.perf_counter()
        check_state(judged, res.coefficients, res.starts, places=False)
        print(f"  check again ({k + 1}, r = {args.radius}): {time.perf_counter() - t0:.2f} s")
    print(f"peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB "
          "(this process: the solve and the checks)")
    if args.radius is None:
        with tempfile.TemporaryDirectory() as tmp:
            state = Path(tmp) / "state.npz"
            import numpy as np
            np.savez(state, coefficients=res.coefficients, starts=res.starts)
            out = subprocess.run([sys.executable, "-c", FRESH, str(n), str(state)],
                                 capture_output=True, text=True, check=True).stdout
        print(f"  the check in a fresh process (imports included): {out.strip()}")


if __name__ == "__main__":
    main()
