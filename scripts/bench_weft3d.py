"""Cost of the 3-D weft model against the paper's model, same run (docs/weft3d.md, "Cost").

    python scripts/bench_weft3d.py [--pull F] [N ...]        (default: F = 0.5, N = 6 10)

For each N: an N x N acrylic stockinette (L = 11.28 mm, R_f = 0.045 N·mm², r = 0.74 mm) with
loop (1, 1)'s start held and H of loop (1, N) pulled by (F·N, F·N) mm, solved by
``knit_nlp.weft.solve`` in the paper's model (no [yarn]) and in 3-D ([yarn] geometry = "3d"):
iterations, build and solve seconds, their ratio, the smallest crossing separation against the
core 2R_c and the number of crossings whose order flipped. Timings are wall-clock on a shared
machine: compare the ratio of one run, not seconds across runs.
"""
from __future__ import annotations

import sys
import time

from knit_nlp.weft.api import solve
from knit_nlp.weft.model.problem import parse_problem

MAX_TIME = 900.0          # s of wall clock per solve


def document(n: int, spatial: bool, pull: float = 0.5) -> dict:
    doc = {"name": f"bench3d_{n}", "fabric": {"courses": n, "wales": n},
           "loop": {"length": 11.28, "harmonics": 3}, "material": {"R_f": 0.045},
           "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                     {"loop": [1, n], "point": "H", "displacement": [pull * n, pull * n]}],
           "solver": {"max_time": MAX_TIME}}
    if spatial:
        doc["yarn"] = {"radius": 0.74, "geometry": "3d", "elevation_modes": 4}
    return doc


def run(n: int, pull: float) -> None:
    rows = {}
    for spatial in (False, True):
        pr = parse_problem(document(n, spatial, pull), f"bench3d_{n}.toml")
        t0 = time.perf_counter()
        res = solve(pr)
        wall = time.perf_counter() - t0
        rows[spatial] = (res, wall)
        extra = ""
        if spatial:
            sp = res.to_json()["spatial"]
            extra = (f"  smallest separation {sp['smallest_separation']:.4f} mm (core "
                     f"{2 * pr.yarn.core_radius:.3f}, touch {2 * pr.yarn.radius:.3f}), flipped "
                     f"{sp['flipped']}, slid off their loop {sp['slid_off_loop']}")
        print(f"{n} x {n} pull {pull * n:g} mm {'3-D   ' if spatial else 'planar'}: {res.status} {res.iterations} it, "
              f"build {res.timings['build_s']:.2f} s, solve {res.report.solve_s:.2f} s, "
              f"wall {wall:.2f} s{extra}", flush=True)
    print(f"{n} x {n} ratio 3-D / planar (wall, same run): {rows[True][1] / rows[False][1]:.1f}",
          flush=True)


if __name__ == "__main__":
    args = sys.argv[1:]
    fraction = 0.5
    if args[:1] == ["--pull"]:
        fraction, args = float(args[1]), args[2:]
    for size in [int(a) for a in args] or [6, 10]:
        run(size, fraction)
