"""The condensed formulation with every loop representative against the full model, same run.

Issue 22, item 1 asked whether a KKT system with fewer variables helps: the condensed reduced
transcription with every course and wale representative is the full model (same minima,
tested in tests/test_weft_condensed.py) with the loop positions condensed out. Per size and
model: variables, constraints, iterations, build and solve time, IPOPT's function-evaluation
time (``t_wall_nlp_*``) and the energy, on ``cases.diagonal_pull(n)``.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python scripts/bench_condensed_all.py 10 20 30
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from knit_nlp.weft.api import solve  # noqa: E402
from knit_nlp.weft.model import cases  # noqa: E402
from knit_nlp.weft.model.parametrisation import Full, Reduced  # noqa: E402
from knit_nlp.weft.model.problem import parse_problem  # noqa: E402


def main(sizes: list[int]) -> None:
    for n in sizes:
        pr = parse_problem(cases.diagonal_pull(n), f"<diagonal_pull({n})>")
        every = Reduced(tuple(range(1, n + 1)), tuple(range(1, n + 1)))
        for label, par in (("full", Full()), ("condensed, every loop", every)):
            s = solve(pr, par)
            ev = sum(v for k, v in s.report.stats.items() if k.startswith("t_wall_nlp_"))
            print(f"{n}x{n} {label:22s} variables {s.nlp.n_variables} constraints "
                  f"{s.nlp.n_constraints} iterations {s.iterations} build {s.build_s:.2f} s "
                  f"solve {s.report.solve_s:.2f} s evaluations {ev:.2f} s "
                  f"energy {s.energy.total:.6f} converged {s.success}", flush=True)


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [10, 20, 30])
