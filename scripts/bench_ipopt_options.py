"""Benchmark: IPOPT options on the full weft model's diagonal pull (issue 22 item 1).

For each size n, the pull ``knit_nlp.weft.model.cases.diagonal_pull(n)`` is built once (full
model, closed-form derivatives) and its multilevel start computed once with the current
options; then every configuration below solves the fine problem from that same start, each run
right next to a run of the reference (the first configuration, the current defaults), the
order of the pair alternating from round to round: on a shared machine the load drifts within
minutes, so only a pair's ratio is compared, and the median of the rounds' ratios is
printed. A configuration is the current defaults (``WeftSolver``: ``mumps_scaling = 0``,
``mumps_permuting_scaling = 0``, ``MODEL_IPOPT["full"]``) plus the options it names.

Printed per configuration: median wall seconds of the solve, IPOPT iterations, KKT
factorisations and those with the wrong inertia (read from IPOPT's output file at
``file_print_level = 6``, where the MUMPS interface reports each), the median seconds in the
linear solver (``StdAugSystemSolverMultiSolve`` of ``print_timing_statistics``: MUMPS's
analysis, factorisations and solves), the status and the energy, and the median ratio to the
reference. ``--end-to-end`` times the multilevel start too (the coarse solves then use the
configuration's options).

    OMP_NUM_THREADS=1 python scripts/bench_ipopt_options.py                  # n = 50, 100
    python scripts/bench_ipopt_options.py --sizes 50 --rounds 1 --configs default amf
"""
from __future__ import annotations

import argparse
import os
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))     # knit_nlp from this checkout

from knit_nlp.weft.model.cases import diagonal_pull  # noqa: E402
from knit_nlp.weft.model.parametrisation import Full  # noqa: E402
from knit_nlp.weft.model.problem import parse_problem  # noqa: E402
from knit_nlp.weft.solving import solve as weft_solve  # noqa: E402
from knit_nlp.weft.solving.solve import WeftSolver, start_point  # noqa: E402
from knit_nlp.weft.transcription.factory import transcribe  # noqa: E402

CONFIGS: dict[str, dict] = {
    "default": {},
    "amd": {"mumps_pivot_order": 0},
    "amf": {"mumps_pivot_order": 2},
    "pord": {"mumps_pivot_order": 4},
    "metis": {"mumps_pivot_order": 5},
    "qamd": {"mumps_pivot_order": 6},
    "mem100": {"mumps_mem_percent": 100},
    "pivtol1e-8": {"mumps_pivtol": 1e-8},
    "pivtol1e-4": {"mumps_pivtol": 1e-4},
    "fhp1e-4": {"first_hessian_perturbation": 1e-4},
    "fhp10": {"first_hessian_perturbation": 10.0},
    "perturb_cd": {"perturb_always_cd": "yes"},
    # after a perturbed iteration IPOPT tries delta_w = 0, then last * perturb_dec_fact (1/3),
    # then * perturb_inc_fact (8): keeping the last delta_w saves the middle trial
    "dec0.9": {"perturb_dec_fact": 0.9},
    "inc2": {"perturb_inc_fact": 2.0},
    "negcurv0": {"neg_curv_test_tol": 1e-12},
    # no least-squares estimate of the constraint multipliers at the start (one factorisation)
    "cmi0": {"constr_mult_init_max": 0.0},
    "noscale": {"nlp_scaling_method": "none"},
    "brf0": {"bound_relax_factor": 0.0},
    "relax_fixed": {"fixed_variable_treatment": "relax_bounds"},
    "adaptive": {"mu_strategy": "adaptive"},
    "lss_none": {"linear_system_scaling": "none"},
}
# measured once and left out of the default list: another minimum at 50 x 50 after 206 and 79
# iterations
SLOW = {"negcurv0", "cmi0"}
# level 6: MUMPS's interface reports every factorisation and every wrong inertia
FILE_OPTIONS = {"file_print_level": 6, "print_timing_statistics": "yes"}
FACTORISED = "Number of doubles for MUMPS to hold factorization"
WRONG_INERTIA = "Factorization failed with retval = 2"
# the linear solver's wall seconds (MUMPS's analysis, factorisations and solves together: the
# MUMPS interface books no separate LinearSystemFactorization time)
LINEAR_S = re.compile(r"StdAugSystemSolverMultiSolve\.*:\s*\S+\s*\(sys:\s*\S+\s*wall:\s*(\S+)\)")


def read_log(path: str) -> dict[str, float]:
    """Factorisations, factorisations with the wrong inertia (each followed by a larger
    Hessian perturbation) and the linear solver's wall seconds from one IPOPT output file."""
    text = Path(path).read_text(errors="replace")
    linear = LINEAR_S.search(text)
    return {"factorisations": text.count(FACTORISED), "wrong_inertia": text.count(WRONG_INERTIA),
            "linear_s": float(linear.group(1)) if linear else float("nan")}


def run(wnlp, x0, opts: dict, end_to_end: bool) -> dict:
    """One solve with ``opts`` on top of the defaults, logged to a temporary file."""
    with tempfile.NamedTemporaryFile(suffix=".ipopt.log", delete=False) as f:
        log = f.name
    try:
        t0 = time.perf_counter()
        if end_to_end:
            x0 = start_point(wnlp, wnlp.p0, "multilevel")
        solver = WeftSolver(wnlp, verbose=None,
                            ipopt={**opts, **FILE_OPTIONS, "output_file": log})
        rep = solver.once(wnlp.p0, x0)
        wall = time.perf_counter() - t0
        return {"wall": wall, "iterations": rep.iterations, "status": rep.status,
                "energy": rep.objective, **read_log(log)}
    finally:
        os.unlink(log)


def bench(n: int, configs: list[str], rounds: int, end_to_end: bool) -> None:
    """Build the n x n diagonal pull, start it once, time every configuration ``rounds`` times."""
    t0 = time.perf_counter()
    wnlp = transcribe(parse_problem(diagonal_pull(n), f"<diagonal_pull {n}>"), Full())
    t1 = time.perf_counter()
    x0 = start_point(wnlp, wnlp.p0, "multilevel")
    print(f"\n## {n} x {n} diagonal pull: {wnlp.n_variables} variables, "
          f"{wnlp.n_constraints} constraints; build {t1 - t0:.1f} s, multilevel start "
          f"{time.perf_counter() - t1:.1f} s", flush=True)
    ref, others = configs[0], configs[1:] or configs[:1]
    runs: dict[str, list[dict]] = {c: [] for c in configs}
    ratios: dict[str, list[float]] = {c: [] for c in configs}
    for r in range(rounds):
        for i, c in enumerate(others):
            # A/B next to each other, the order alternating: the load drifts within minutes
            pair = (ref, c) if (r + i) % 2 == 0 else (c, ref)
            done = {k: timed(wnlp, x0, k, end_to_end, r) for k in pair}
            for k, res in done.items():
                runs[k].append(res)
            ratios[c].append(done[c]["wall"] / done[ref]["wall"])
    table(runs, ratios, configs)


def timed(wnlp, x0, config: str, end_to_end: bool, r: int) -> dict:
    """One run of ``config``; its options also reach the coarse solves of ``--end-to-end``."""
    full_defaults = dict(weft_solve.MODEL_IPOPT["full"])
    weft_solve.MODEL_IPOPT["full"] = {**full_defaults, **CONFIGS[config]}
    try:
        res = run(wnlp, x0, CONFIGS[config], end_to_end)
    finally:
        weft_solve.MODEL_IPOPT["full"] = full_defaults
    print(f"  round {r + 1} {config:16s} {res['wall']:7.2f} s  {res['iterations']:3d} it "
          f"{res['factorisations']:>4} fact", file=sys.stderr, flush=True)
    return res


def table(runs: dict[str, list[dict]], ratios: dict[str, list[float]],
          configs: list[str]) -> None:
    """The markdown table: medians, effort, median of the paired ratios to the reference."""
    print(f"| option ({configs[0]} = reference) | wall s (median) | ratio (median of pairs) | "
          "iterations | factorisations | wrong inertia | linear solver s (median) | status | "
          "energy |")
    print("|---|---|---|---|---|---|---|---|---|")
    for c in configs:
        rs = runs[c]
        wall = statistics.median(r["wall"] for r in rs)
        lin = statistics.median(r["linear_s"] for r in rs)
        ratio = f"{statistics.median(ratios[c]):.2f}" if ratios[c] else "1"
        opt = ", ".join(f"{k} = {v}" for k, v in CONFIGS[c].items()) or "current defaults"
        print(f"| {c}: {opt} | {wall:.2f} | {ratio} | {rs[0]['iterations']} | "
              f"{rs[0]['factorisations']} | {rs[0]['wrong_inertia']} | {lin:.2f} | "
              f"{rs[0]['status']} | {rs[0]['energy']:.6g} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[50, 100])
    ap.add_argument("--configs", nargs="+", default=[c for c in CONFIGS if c not in SLOW],
                    choices=list(CONFIGS),
                    help="the first is the reference of the ratios (default: all but "
                         f"{', '.join(sorted(SLOW))})")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--end-to-end", action="store_true",
                    help="time the multilevel start with each configuration too")
    args = ap.parse_args()
    print(f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS', '(unset)')} "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', '(unset)')} "
          f"cores={os.cpu_count()} rounds={args.rounds}; command: {' '.join(sys.argv)}")
    for n in args.sizes:
        bench(n, args.configs, args.rounds, args.end_to_end)


if __name__ == "__main__":
    main()
