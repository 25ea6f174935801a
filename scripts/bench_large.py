"""Large fabrics: full against condensed reduced (corner, even grids, adaptive), in one run.

For each size and pull (diagonal, course): the full model from its default start, then the
condensed reduced model on the corner form, even k × k grids and adaptive representatives
(``[reduction] adaptive``, tolerance 0.1·L, budget 30 % of the full parameters). Per model:
iterations, build and solve time, the solve split into function/derivative evaluations
(IPOPT's ``t_wall_nlp_*``) and IPOPT's own time, parameters, energy, the largest and RMS
centreline distance to the full solution (21 samples per loop), and the speed-up over full
(build + solve, in this process). For the adaptive run also every step's estimate and true RMS
error; its iterations and times include the indicator's solves of the bisected candidate grids
(``adaptive.indicator``), and it is compared with the best of the even grids run here that has
at most its parameters.

    python scripts/bench_large.py                 # 30 x 30 diagonal pull (a few minutes)
    python scripts/bench_large.py --pulls course  # the course pull (slow: docs/measurements.md)
    python scripts/bench_large.py --sizes 50 100 --grids 2 6 --pulls diagonal --skip-adaptive
    python scripts/bench_large.py --nested --skip-adaptive --grids  # what tensor grids can reach

``--nested``: how well each tensor grid can do when solved well (the bound for the adaptive
targets). Every product of the bisection chains {1, n} → {1, n/2, n} → … (5 levels at 30) in
courses and wales, each solved warm-started from the finest already solved grid it contains
(lifted exactly, so the energy cannot rise along a chain); then even k × k grids for k = 2 …
``--nested-even`` warm-started from the previous even grid (lifted by least squares: even grids
are not nested). Only the distances to the full solution are of interest there, not times.

BLAS threads are left as the environment sets them, as for a user's run: measured idle on 2
cores, OPENBLAS_NUM_THREADS=1 slows the full 100 x 100 solve from 14.0 to 18.0 s and leaves the
reduced one unchanged (2.35 against 2.18 s); on a loaded machine set it to 1 (threads that
wait for busy cores made the condensed model's small products up to 100x slower).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from study_reduction import even  # noqa: E402

from knit_nlp.weft.solving.adaptive import bisect, solve_adaptive, solve_grid  # noqa: E402
from knit_nlp.weft.api import solve  # noqa: E402
from knit_nlp.weft.model.cases import course_pull, diagonal_pull  # noqa: E402
from knit_nlp.weft.model.parametrisation import Adaptive, Full, Reduced  # noqa: E402
from knit_nlp.weft.model.problem import parse_problem  # noqa: E402

SAMPLES = 21


def split(stats: dict[str, float], solve_s: float) -> tuple[float, float]:
    """(evaluations s, IPOPT's own s): IPOPT's t_wall_nlp_* statistics, and the rest of the
    solve's wall time."""
    ev = sum(v for k, v in stats.items() if k.startswith("t_wall_nlp"))
    return ev, solve_s - ev


def distances(lines: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    d = np.linalg.norm(lines - ref, axis=-1)
    return float(d.max()), float(np.sqrt(np.mean(d ** 2)))


def row(case: str, model: str, params: int, its: int, build: float, solve_s: float,
        stats: dict, energy: float, err: tuple[float, float], full_time: float | None,
        ok: bool) -> str:
    ev, own = split(stats, solve_s)
    total = build + solve_s
    speed = "" if full_time is None else f"{full_time / total:.2f}x"
    return (f"| {case} | {model} | {params} | {its} | {build:.2f} | {solve_s:.2f} | {ev:.2f} | "
            f"{own:.2f} | {total:.2f} | {speed} | {energy:.5g} | {err[0]:.3g} | {err[1]:.3g} |"
            f"{'' if ok else ' NOT CONVERGED'}")


def grid_row(case: str, label: str, g, full_params: int, ref: np.ndarray) -> str:
    """One row of the --nested table: parameters (% of full), iterations, energy, distances."""
    err = distances(g.lines, ref)
    return (f"| {case} | {label} | {g.cnlp.n_parameters} "
            f"({100 * g.cnlp.n_parameters / full_params:.1f} %) | {g.report.iterations} | "
            f"{g.energy:.5g} | {err[0]:.3g} | {err[1]:.3g} |"
            f"{'' if g.report.success else ' NOT CONVERGED'}")


def nested(case: str, pr, ref: np.ndarray, full_params: int, even_up_to: int) -> None:
    """The --nested tables (module docstring): params, iterations, energy, max and RMS distance
    per grid solved warm along bisection chains and along even grids."""
    chains = []
    for size in (pr.courses, pr.wales):
        chain = [(1, size) if size > 1 else (1,)]
        while bisect(chain[-1]) != chain[-1]:
            chain.append(bisect(chain[-1]))
        chains.append(chain[:5])
    solved = {}
    for a, courses in enumerate(chains[0]):
        for b, wales in enumerate(chains[1]):
            start = max((g for g in solved.values() if set(g.red.courses) <= set(courses)
                         and set(g.red.wales) <= set(wales)),
                        key=lambda g: g.cnlp.n_parameters, default=None)
            g = solve_grid(pr, Reduced(courses, wales), start, SAMPLES)
            solved[a, b] = g
            print(grid_row(case, f"nested courses {len(courses)} x wales {len(wales)}", g,
                           full_params, ref), flush=True)
    prev = None
    for k in range(2, even_up_to + 1):
        g = solve_grid(pr, Reduced(tuple(even(k, pr.courses)), tuple(even(k, pr.wales))), prev,
                       SAMPLES)
        print(grid_row(case, f"even {k}x{k} warm from the previous", g, full_params, ref),
              flush=True)
        prev = g


def run_case(case: str, doc: dict, grids: list[int], adaptive: bool,
             nested_even: int | None = None) -> None:
    pr = parse_problem(doc, f"<{case}>")
    full = solve(pr, Full())
    ref = full.centrelines(SAMPLES)
    print(row(case, "full", full.nlp.n_parameters, full.iterations, full.build_s,
              full.report.solve_s, full.report.stats, full.energy.total, (0.0, 0.0), None,
              full.success), flush=True)
    full_time = full.build_s + full.report.solve_s
    if nested_even is not None:
        print("| case | grid | parameters (% of full) | iterations | energy | max distance | "
              "RMS distance |\n|---|---|---:|---:|---:|---:|---:|", flush=True)
        nested(case, pr, ref, full.nlp.n_parameters, nested_even)
    m, n = pr.courses, pr.wales
    even_errors = []
    for k in grids:
        s = solve(pr, Reduced(tuple(even(k, m)), tuple(even(k, n))))
        err = distances(s.centrelines(SAMPLES), ref)
        even_errors.append((s.nlp.n_parameters, err[1]))
        label = "corner 2x2" if k == 2 else f"even {k}x{k}"
        print(row(case, label, s.nlp.n_parameters, s.iterations, s.build_s, s.report.solve_s,
                  s.report.stats, s.energy.total, err, full_time, s.success), flush=True)
    if not adaptive:
        return
    budget = full.nlp.n_parameters * 3 // 10
    t0 = time.perf_counter()
    run = solve_adaptive(pr, Adaptive(0.1 * pr.L, budget), samples=SAMPLES)
    wall = time.perf_counter() - t0
    last = run.steps[-1]
    err = distances(last.lines, ref)
    spring, bend, _ = run.cnlp.energy(run.report.x, run.cnlp.p0)
    print(row(case, f"adaptive ({len(last.courses)}x{len(last.wales)})", last.n_parameters,
              run.report.iterations, run.build_s, wall - run.build_s, run.report.stats,
              spring + bend, err, full_time, run.report.success), flush=True)
    for q, st in enumerate(run.steps):
        e = distances(st.lines, ref)
        print(f"|   step {q} | courses {list(st.courses)}, wales {list(st.wales)} | "
              f"{st.n_parameters} params, energy {st.energy:.5g}, {st.iterations} it | "
              f"estimate {st.estimate:.3g} | true RMS {e[1]:.3g}, max {e[0]:.3g} |", flush=True)
    fewer = [e for p, e in even_errors if p <= last.n_parameters]
    if fewer:
        print(f"|   adaptive vs best even grid with at most {last.n_parameters} parameters: "
              f"RMS {err[1]:.3g} against {min(fewer):.3g} ({min(fewer) / err[1]:.2f}x lower); "
              f"parameters {100 * last.n_parameters / full.nlp.n_parameters:.1f} % of full |",
              flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[30])
    ap.add_argument("--grids", type=int, nargs="*", default=[2, 4, 6, 8],
                    help="even k x k grids (2 = the corner form)")
    ap.add_argument("--pulls", nargs="*", default=["diagonal"], choices=["diagonal", "course"])
    ap.add_argument("--skip-adaptive", action="store_true")
    ap.add_argument("--nested", action="store_true",
                    help="also the tensor grids along bisection chains, solved warm (docstring)")
    ap.add_argument("--nested-even", type=int, default=16, metavar="K",
                    help="with --nested: even grids 2..K warm-started in turn")
    args = ap.parse_args()
    print("| case | model | parameters | iterations | build s | solve s | evaluations s | "
          "IPOPT own s | build + solve s | speed-up | energy | max distance | RMS distance |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    docs = {"diagonal": diagonal_pull, "course": course_pull}
    for size in args.sizes:
        for pull in args.pulls:
            run_case(f"{pull} {size}x{size}", docs[pull](size), args.grids, not args.skip_adaptive,
                     args.nested_even if args.nested else None)


if __name__ == "__main__":
    main()
