"""Benchmark compression with yarn contact (issue 41, item 6): an n x n jersey pushed together by
a fraction of its size, along the courses, along the wales or diagonally, with ``[yarn]
radius``; each solve given ``--budget`` seconds ([solver] max_time). Prints per push the wall
time, the status (converged, or why not), the load steps and contact solves, the active
contacts and the independent check's verdict (output.check, the result's own ``check``).

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python scripts/bench_compression_contact.py \
        [--sizes 4 10] [--push 0.333] [--radius 0.15] [--budget 600] [--kinds course wale diagonal]

The pushes:
- ``course``: every course's first start held in x (course 1's also in y), every course's last
  end moved by −push·(natural width) along x (scripts' and tests' ``cases.course_pull``).
- ``wale``: every wale's first-course start held in y (loop (1, 1)'s also in x), H of every
  loop of the last course moved by −push·(natural height) along y.
- ``diagonal``: loop (1, 1)'s start pinned, H of loop (n, n) moved towards it by push·(width,
  height).
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import time

import numpy as np


def push_doc(n: int, kind: str, push: float) -> dict:
    """The problem document of an n x n jersey pushed together (module docstring)."""
    from knit_nlp.weft.model.cases import _jersey, course_pull, unclamped
    loop = _jersey()
    if kind == "course":
        doc = course_pull(n, -push)
    elif kind == "wale":
        doc = unclamped(n, n)
        clamps = []
        for j in range(1, n + 1):
            clamps.append({"loop": [1, j], "point": "start", "displacement": [0.0, 0.0],
                           "fix": ["x", "y"] if j == 1 else ["y"]})
            clamps.append({"loop": [n, j], "point": "H", "fix": ["y"],
                           "displacement": [0.0, -push * n * loop.course_spacing]})
        doc["clamp"] = clamps
    elif kind == "diagonal":
        doc = unclamped(n, n)
        d = -push * np.array([n * loop.wale_spacing, n * loop.course_spacing])
        doc["clamp"] = [{"loop": [1, 1], "point": "start", "position": [0.0, 0.0]},
                        {"loop": [n, n], "point": "H", "displacement": d.tolist()}]
    else:
        raise ValueError(f"kind must be course, wale or diagonal, got {kind!r}")
    doc["name"] = f"push_{kind}_{n}x{n}"
    return doc


def pushed(n: int, kind: str, push: float, radius: float, budget: float):
    """The pushed fabric as a problem with a yarn radius and a time budget."""
    from knit_nlp.weft.model.problem import Yarn, parse_problem
    pr = parse_problem(push_doc(n, kind, push), f"<bench {kind}>")
    return dataclasses.replace(pr, yarn=Yarn(radius),
                               solver=dataclasses.replace(pr.solver, max_time=budget))


def timed_push(n: int, kind: str, push: float, radius: float, budget: float) -> dict:
    """Solve one push (the NLP's build included) and take the result's own check."""
    from knit_nlp.weft.api import solve
    from knit_nlp.weft.model.parametrisation import Full
    t0 = time.perf_counter()
    res = solve(pushed(n, kind, push, radius, budget), Full())
    seconds = time.perf_counter() - t0
    block, check = res.contact, res.checked
    return {"seconds": seconds, "status": res.status, "message": res.message,
            "steps": res.report.continuation_steps,
            "solves": None if block is None else block.solves,
            "active": None if block is None else block.active,
            "check": check.get("verdict"), "ok": check.get("ok")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[4, 10])
    ap.add_argument("--kinds", nargs="+", default=["course", "wale", "diagonal"])
    ap.add_argument("--push", type=float, default=1 / 3, help="fraction of the fabric's size")
    ap.add_argument("--radius", type=float, default=0.15)
    ap.add_argument("--budget", type=float, default=600.0, help="seconds per solve")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} at the start; cores={os.cpu_count()} "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')} radius={args.radius} "
          f"push={args.push:.3g} budget={args.budget:g} s")
    print("| push | size | seconds | status | load steps | contact solves | active | check |")
    print("|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        for kind in args.kinds:
            r = timed_push(n, kind, args.push, args.radius, args.budget)
            print(f"| {kind} | {n} x {n} | {r['seconds']:.1f} | {r['message']} | {r['steps']} | "
                  f"{r['solves']} | {r['active']} | {r['check']} |", flush=True)


if __name__ == "__main__":
    main()
