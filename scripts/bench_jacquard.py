"""Benchmark: static (CasADi/IPOPT) against the paper's explicit midpoint solver.

For 50 x 50 and 100 x 100 repeats of a thick/thin/net diamond motif (problems/jacquard_bench_100
tiled or cut), solve statically, then run the explicit solver until its residual force (largest
net spring force on a free particle) is at most the static one; print both times and the ratio.
Then the static solver alone on 500 x 500.

    .venv/bin/python scripts/bench_jacquard.py [--sizes 10] [--static-only 100]
                                               [--max-steps 400000] [--full-sizes]

The defaults take under a minute; ``--full-sizes`` runs docs/jacquard.md's benchmark
(``--sizes 50 100 --static-only 500``: the explicit solver alone runs for tens of minutes).
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from knit_nlp.jacquard import load_problem, solve_explicit, solve_static
from knit_nlp.jacquard.problem import JacquardProblem, JacquardSystem

BASE = Path(__file__).resolve().parent.parent / "problems" / "jacquard_bench_100.toml"


def resized(p: JacquardProblem, size: int) -> JacquardProblem:
    """The bench motif tiled (or cut) to ``size`` x ``size``."""
    reps = -(-size // p.wales)
    systems = tuple(JacquardSystem(s.name, np.tile(s.codes, (reps, reps))[:size, :size],
                                   s.span, s.stiffness, s.pretension) for s in p.systems)
    return JacquardProblem(**{**p.__dict__, "wales": size, "courses": size, "systems": systems,
                              "name": f"bench_{size}"})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[10])
    ap.add_argument("--static-only", type=int, nargs="*", default=[100])
    ap.add_argument("--max-steps", type=int, default=400_000)
    ap.add_argument("--full-sizes", action="store_true",
                    help="docs/jacquard.md's sizes: --sizes 50 100 --static-only 500 (tens of minutes)")
    args = ap.parse_args()
    if args.full_sizes:
        args.sizes, args.static_only = [50, 100], [500]
    base = load_problem(BASE)
    for size in args.sizes:
        print(f"{size} x {size}: static, then explicit to the same residual ...", flush=True)
        p = resized(base, size)
        st = solve_static(p)
        t_static = sum(st.timings.values())
        target = max(st.residual_force, 1e-12)
        ex = solve_explicit(p, force_tol=target, max_steps=args.max_steps)
        t_explicit = sum(ex.timings.values())
        gap = np.max(np.abs(st.positions - ex.positions)) / p.w
        bound = "" if ex.success else ">= "     # explicit stopped at the step limit first
        print(f"{size} x {size}: static {t_static:.2f} s (build {st.timings['build_s']:.2f} s, "
              f"{st.iterations} it, {st.status}, residual {st.residual_force:.2e}); explicit "
              f"{t_explicit:.2f} s ({ex.steps} steps, {ex.status}, residual "
              f"{ex.residual_force:.2e}); ratio explicit/static {bound}"
              f"{t_explicit / t_static:.1f}; max |x_static - x_explicit| = {gap:.2e} w",
              flush=True)
    for size in args.static_only:
        p = resized(base, size)
        t0 = time.perf_counter()
        st = solve_static(p)
        print(f"{size} x {size} static: {time.perf_counter() - t0:.2f} s (build "
              f"{st.timings['build_s']:.2f} s, solve {st.timings['solve_s']:.2f} s, "
              f"{st.iterations} it, {st.status}, residual {st.residual_force:.2e})", flush=True)


if __name__ == "__main__":
    main()
