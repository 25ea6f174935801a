"""A lower bound on the cost of yarn contact solved as gap rows in IPOPT: the contact NLP solved
once with its answer's active set given in advance (an oracle), against the package's solve
with contact and the solve without, in one process (same-run ratios).

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python scripts/bound_contact.py [--sizes 10 30]

For each n x n diagonal pull (``bench_contact``'s problem, r = 0.15):

1. the solve without contact (a ``WeftStudy`` built and run, the NLP's build included: what
   ``weft.api.solve`` in ``bench_contact.py`` does);
2. the package's solve with contact (a ``WeftStudy``: load steps and rounds, the same
   build included), which lists the active contacts of its answer (``ContactSolver.touching``);
3. the oracle: a fresh contact NLP with a slot for exactly those contacts (their material
   points, sides and required gaps), solved once by IPOPT at the target, (a) from the natural
   fabric, (b) from the paper's solution without contact (its solve counted). No pair search,
   no load step, no round: no method that builds the same rows and lets IPOPT solve them can
   do with less. The oracle's answer is checked against the package's (largest difference in
   the decision vector) and by the independent checker (new crossings, gaps below 2r).

The build of the oracle's contact NLP is counted; the build of the paper's NLP is not (the
package's solve with contact pays it once, as the solve without does).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_contact as bc  # noqa: E402  (the same problem and radius)


def _solve(n: int, radius: float | None, budget: float):
    """The pull solved by the package (with its NLP build): the study, result and seconds."""
    from knit_nlp.weft.model.cases import diagonal_pull
    from knit_nlp.weft.model.parametrisation import Full
    from knit_nlp.weft.study import WeftStudy
    pr = bc._problem(diagonal_pull(n), radius, budget)
    t0 = time.perf_counter()
    st = WeftStudy(pr, Full())
    res = st.run()
    return st, res, time.perf_counter() - t0


def oracle(n: int, contacts, budget: float, start: str) -> dict:
    """One IPOPT solve of a new contact NLP holding a slot for each of ``contacts`` (Pairs), at
    the pull's target, from ``start`` ("natural" or "paper": the paper's solution, whose solve
    is counted)."""
    from knit_nlp.weft.model.cases import diagonal_pull
    from knit_nlp.weft.solving.solve import DEFAULT_START, SolveReport, start_point
    from knit_nlp.weft.output.check import check
    from knit_nlp.weft.study import WeftStudy
    st = WeftStudy(bc._problem(diagonal_pull(n), bc.RADIUS, budget))
    base, c, p = st.nlp, st.contact, st.params.vector()
    c.deadline = time.perf_counter() + budget
    t0 = time.perf_counter()
    x = base.x0
    paper_its = 0
    if start == "paper":
        rep = st.solver.once(p, start_point(base, p, DEFAULT_START, []))
        x, paper_its = rep.x, rep.iterations
    spent = SolveReport(False, "", base.x0, np.zeros(base.n_constraints), np.nan, 0, 0.0)
    rep, _ = c.solve_once(p, x, contacts, None, spent, [], "oracle")
    seconds = time.perf_counter() - t0
    xb = rep.x[:base.n_variables]
    # the independent checker (output/check.py) on the oracle's state, as a result of the
    # paper's NLP (the contact variables dropped, as the package's solve reports it)
    on_base = SolveReport(rep.success, rep.status, xb, rep.lam_g[:base.n_constraints],
                          rep.objective, rep.iterations, rep.solve_s)
    checked = check(st.result(on_base, st.params).to_json(), st.nlp.problem)
    return {"seconds": seconds, "iterations": rep.iterations, "paper_iterations": paper_its,
            "status": rep.status, "x": xb, "objective": rep.objective,
            "new_crossings": len(checked.new_crossings), "short": checked.n_short}


def bound(n: int, budget: float) -> None:
    _, _, plain = _solve(n, None, budget)
    st, res, withc = _solve(n, bc.RADIUS, budget)
    if not res.success:
        print(f"{n}x{n}: the solve with contact did not converge ({res.status}): no answer, "
              f"no active set, no bound")
        return
    pairs = st.contact.last.pairs
    contacts = pairs.select(st.contact.touching())
    print(f"{n}x{n}: without contact {plain:.2f} s; with contact {withc:.2f} s "
          f"({withc / plain:.1f} x), {len(pairs):,} pairs in its last solve, "
          f"{len(contacts)} active, objective {res.fun:.6g}", flush=True)
    for start in ("natural", "paper"):
        o = oracle(n, contacts, budget, start)
        its = (f"{o['paper_iterations']} + {o['iterations']}" if start == "paper"
               else f"{o['iterations']}")
        where = "the paper's solution" if start == "paper" else "the natural fabric"
        print(f"  oracle from {where}: "
              f"{o['seconds']:.2f} s ({o['seconds'] / plain:.1f} x the solve without), "
              f"{its} IPOPT iterations, {o['status']}, objective {o['objective']:.6g}, "
              f"largest difference from the package's answer {np.max(np.abs(o['x'] - res.x)):.2g}; "
              f"checker: {o['new_crossings']} pairs of loops with new crossings, "
              f"{o['short']} gaps below 2r(1-1e-3)", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 30])
    ap.add_argument("--budget", type=float, default=1200.0)
    a = ap.parse_args()
    for n in a.sizes:
        bound(n, a.budget)


if __name__ == "__main__":
    main()
