"""Benchmark: the full model on large fabrics, by start and derivatives (issue 14, items 3-4).

For each size and pull (knit_nlp/weft/model/cases.py: the diagonal pull, eq. 28 scaled to the fabric,
and the course pull, left edge held, right edge pulled 25 % of the width), every configuration
runs in its own process so that its peak memory (max RSS) is its own:

- ``casadi``: natural start, CasADi's AD derivatives (the code before issue 14);
- ``closed``: natural start, closed-form Jacobian and Hessian (knit_nlp/weft/transcription/derivatives.py);
- ``multilevel``: the multilevel start (knit_nlp/weft/solving/starts.py: the same pull solved on a fabric
  with half the courses and wales, recursively, and prolonged), closed-form derivatives;
- ``rigid``: the rigid-fit start (start.py) with closed-form derivatives;
- ``closed+soc0`` / ``multilevel+soc0``: the same with IPOPT's ``max_soc = 0``.

The multilevel start's coarse solves are counted in ``start s`` and in the end-to-end time.

Printed per run: IPOPT iterations, objective evaluations, evaluation seconds (IPOPT's
``t_wall_nlp_*``), IPOPT's own seconds (solve minus evaluations), solver set-up, end to end in the
process, peak MB, the energy and its difference from the first configuration's, and every
time's ratio to the first configuration's in the same run. Timings on a shared machine are
noisy: compare ratios within one run.

    python scripts/bench_full_start.py                    # 30 x 30 (about a minute alone)
    python scripts/bench_full_start.py --full-sizes       # 30, 50 and 100 (many minutes)
    python scripts/bench_full_start.py --sizes 50 --pulls diagonal --configs casadi rigid
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))     # knit_nlp from this checkout

from knit_nlp.weft.model.cases import course_pull, diagonal_pull  # noqa: E402

CONFIGS = {"casadi": ("natural", "casadi", {}),
           "closed": ("natural", "closed_form", {}),
           "multilevel": ("multilevel", "closed_form", {}),
           "rigid": ("rigid", "closed_form", {}),
           "closed+soc0": ("natural", "closed_form", {"max_soc": 0}),
           "multilevel+soc0": ("multilevel", "closed_form", {"max_soc": 0})}


PULLS = {"diagonal": diagonal_pull, "course": course_pull}


def run_one(n: int, pull: str, config: str) -> dict:
    """Read, build, set up, start and solve one case in this process; report effort and memory."""
    from knit_nlp.weft.model.parametrisation import Full
    from knit_nlp.weft.model.problem import parse_problem
    from knit_nlp.weft.solving.solve import WeftSolver, start_point
    from knit_nlp.weft.transcription.factory import transcribe
    start, derivatives, ipopt = CONFIGS[config]
    t0 = time.perf_counter()
    pr = parse_problem(PULLS[pull](n), f"<bench {pull} {n}x{n}>")
    wnlp = transcribe(pr, Full(), derivatives=derivatives)     # the derivatives count as build
    t1 = time.perf_counter()
    solver = WeftSolver(wnlp, ipopt=ipopt)
    t2 = time.perf_counter()
    levels: list[str] = []
    x0 = start_point(wnlp, wnlp.p0, start, levels)
    t3 = time.perf_counter()
    rep = solver.once(wnlp.p0, x0)
    stats = solver.solver.stats()
    evals = sum(v for k, v in rep.stats.items() if k.startswith("t_wall_nlp"))
    return {"n": n, "pull": pull, "config": config, "success": rep.success,
            "iterations": rep.iterations, "f_evals": int(stats.get("n_call_nlp_f", 0)),
            "build_s": t1 - t0, "setup_s": t2 - t1, "start_s": t3 - t2, "solve_s": rep.solve_s,
            "eval_s": evals, "ipopt_s": rep.solve_s - evals,
            "profile": {k[7:]: v for k, v in rep.stats.items() if k.startswith("t_wall_nlp")},
            "total_s": time.perf_counter() - t0, "energy": rep.objective,
            "start_violation": solver.violation(x0, wnlp.p0), "levels": levels,
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=None)
    ap.add_argument("--full-sizes", action="store_true", help="sizes 30, 50 and 100")
    ap.add_argument("--pulls", nargs="+", choices=list(PULLS), default=list(PULLS))
    ap.add_argument("--configs", nargs="+", choices=list(CONFIGS), default=list(CONFIGS))
    ap.add_argument("--json", type=Path, help="also write all rows to this file")
    ap.add_argument("--one", nargs=3, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(int(args.one[0]), args.one[1], args.one[2])))
        return
    sizes = args.sizes or ([30, 50, 100] if args.full_sizes else [30])
    rows = []
    print(f"{'case':<16} {'config':<15} {'ok':>2} {'iter':>4} {'f ev':>4} {'eval s':>7} "
          f"{'ipopt s':>7} {'setup s':>7} {'start s':>7} {'total s':>7} {'peak MB':>7} {'energy':>14} "
          f"{'dE':>8}  ratios to first (eval/ipopt/total)", flush=True)
    for n in sizes:
        for pull in args.pulls:
            first = None
            for config in args.configs:
                out = subprocess.run([sys.executable, __file__, "--one", str(n), pull, config],
                                     check=True, capture_output=True, text=True).stdout
                r = json.loads(out.strip().splitlines()[-1])
                rows.append(r)
                first = first or r
                print(f"{pull + f' {n}x{n}':<16} {config:<15} {'y' if r['success'] else 'N':>2} "
                      f"{r['iterations']:>4} {r['f_evals']:>4} {r['eval_s']:>7.2f} {r['ipopt_s']:>7.2f} "
                      f"{r['setup_s']:>7.2f} {r['start_s']:>7.2f} {r['total_s']:>7.2f} {r['peak_mb']:>7.0f} "
                      f"{r['energy']:>14.9g} {r['energy'] - first['energy']:>8.1e}  "
                      f"{r['eval_s'] / first['eval_s']:.2f}/{r['ipopt_s'] / first['ipopt_s']:.2f}/"
                      f"{r['total_s'] / first['total_s']:.2f}", flush=True)
                if r["levels"]:
                    print(f"{'':<16} {'':<15} start: " + "; ".join(r["levels"])
                          + f"; violation at start {r['start_violation']:.3g}", flush=True)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
