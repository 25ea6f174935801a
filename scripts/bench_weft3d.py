"""Cost of the 3-D weft model against the paper's model, same run (docs/weft3d.md, "Cost").

    python scripts/bench_weft3d.py [--pull F] [--max-time S] [--predictor] [--steps K]
                                   [--ipopt NAME=VALUE ...] [--rounds R] [N ...]
                                   (default: F = 0.5, S = 900, K = 3, N = 6 10)

For each N: an N x N acrylic stockinette (L = 11.28 mm, R_f = 0.045 N·mm², r = 0.74 mm) with
loop (1, 1)'s start held and H of loop (1, N) pulled by (F·N, F·N) mm, solved by
``knit_nlp.weft.solve`` in the paper's model (no [yarn]) and in 3-D ([yarn] geometry = "3d"):
iterations, build and solve seconds, their ratio, the smallest crossing separation against the
core 2R_c and the number of crossings whose order flipped; the process's CPU seconds and peak
resident memory (``resource.getrusage``, after each solve: the 3-D line's includes the planar
solve before it), and where the 3-D solve's time went (IPOPT's wall seconds in the Hessian, the
Jacobian, the other evaluations, and the rest: its own linear algebra). Timings are wall-clock
on a shared machine: compare the ratio of one run, not seconds across runs. ``--predictor``:
the 3-D load steps start from the secant predictor (``solve.MODEL_PREDICTOR``, off by default);
``--steps``: exactly K load steps of the 3-D model (``solve.MODEL_CONTINUATION``; without it,
more where a held point moves far, ``solve.MODEL_STEP_MOVE``); ``--ipopt``: an IPOPT option
for the 3-D solves (``solve.MODEL_IPOPT``; repeat it for more; e.g.
``--ipopt mumps_pivot_order=5``; ``--ipopt output_file=log.txt --ipopt file_print_level=6
--ipopt file_append=yes`` writes IPOPT's log of every 3-D solve); ``--rounds``: at most R rounds
of other contacts (``rounds3d.ROUNDS``; 0: the first NLP's answer, for comparing two builds of
one NLP: a round's pairs depend on the answer before it).
"""
from __future__ import annotations

import resource
import sys
import time

from knit_nlp.weft.api import solve
from knit_nlp.weft.solving import solve as solving
from knit_nlp.weft.solving.rounds3d import SpatialEquilibrium
from knit_nlp.weft.model.problem import parse_problem

MAX_TIME = 900.0          # s of wall clock per solve


def document(n: int, spatial: bool, pull: float = 0.5, max_time: float = MAX_TIME) -> dict:
    doc = {"name": f"bench3d_{n}", "fabric": {"courses": n, "wales": n},
           "loop": {"length": 11.28, "harmonics": 3}, "material": {"R_f": 0.045},
           "clamp": [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                     {"loop": [1, n], "point": "H", "displacement": [pull * n, pull * n]}],
           "solver": {"max_time": max_time}}
    if spatial:
        doc["yarn"] = {"radius": 0.74, "geometry": "3d", "elevation_modes": 4}
    return doc


def split(res) -> str:
    """Where a solve's wall time went, per IPOPT iteration (ms)."""
    st, it = res.report.stats, max(res.iterations, 1)
    hess, jac = st.get("t_wall_nlp_hess_l", 0.0), st.get("t_wall_nlp_jac_g", 0.0)
    other = sum(v for k, v in st.items() if k.startswith("t_wall_nlp_")) - hess - jac
    rest = res.report.solve_s - hess - jac - other
    return (f"  per iteration: Hessian {1e3 * hess / it:.1f} ms, Jacobian {1e3 * jac / it:.1f} ms, "
            f"f, g, grad f {1e3 * other / it:.1f} ms, IPOPT's own {1e3 * rest / it:.1f} ms")


def rounds(block: dict) -> str:
    """The rounds of other contacts (docs/weft3d.md): pairs added and status of each."""
    done = block.get("other_contacts", {}).get("rounds", [])
    return ", ".join(f"+{r['added']} {r['status']}" for r in done) or "none"


def run(n: int, pull: float, max_time: float = MAX_TIME) -> None:
    rows = {}
    for spatial in (False, True):
        pr = parse_problem(document(n, spatial, pull, max_time), f"bench3d_{n}.toml")
        t0, c0 = time.perf_counter(), time.process_time()
        res = solve(pr)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        rows[spatial] = (res, wall)
        extra = ""
        if spatial:
            sp = res.to_json()["spatial"]
            extra = (f"  smallest separation {sp['smallest_separation']:.4f} mm (core "
                     f"{2 * pr.yarn.core_radius:.3f}, touch {2 * pr.yarn.radius:.3f}), flipped "
                     f"{sp['flipped']}, slid off their loop {sp['slid_off_loop']}, energy "
                     f"{res.report.objective:.12g}, rounds {rounds(sp)}\n{split(res)}")
        print(f"{n} x {n} pull {pull * n:g} mm {'3-D   ' if spatial else 'planar'}: {res.status} {res.iterations} it, "
              f"build {res.timings['build_s']:.2f} s, solve {res.report.solve_s:.2f} s, "
              f"wall {wall:.2f} s, CPU {cpu:.2f} s, peak memory {peak:.0f} MB{extra}", flush=True)
    print(f"{n} x {n} ratio 3-D / planar (wall, same run): {rows[True][1] / rows[False][1]:.1f}",
          flush=True)


def option_value(text: str) -> int | float | str:
    """An IPOPT option's value from the command line: an integer, a number, else a string."""
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


if __name__ == "__main__":
    args = sys.argv[1:]
    fraction, budget = 0.5, MAX_TIME
    while args[:1] in (["--pull"], ["--max-time"], ["--predictor"], ["--steps"], ["--ipopt"],
                       ["--rounds"]):
        if args[0] == "--predictor":
            solving.MODEL_PREDICTOR.add("full3d")
            args = args[1:]
            continue
        if args[0] == "--pull":
            fraction = float(args[1])
        elif args[0] == "--rounds":
            SpatialEquilibrium.rounds_max = int(args[1])
        elif args[0] == "--steps":
            solving.MODEL_CONTINUATION["full3d"] = int(args[1])
            solving.MODEL_STEP_MOVE.pop("full3d", None)     # exactly K steps
        elif args[0] == "--ipopt":
            name, value = args[1].split("=", 1)
            solving.MODEL_IPOPT.setdefault("full3d", {})[name] = option_value(value)
        else:
            budget = float(args[1])
        args = args[2:]
    for size in [int(a) for a in args] or [6, 10]:
        run(size, fraction, budget)
