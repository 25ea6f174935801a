"""Time one evaluation of the contact NLP's rows, Jacobian and Hessian against the paper's
rows alone, on a diagonal pull with contact slots on random pairs of nearby loops (what every
IPOPT iteration of a contact solve pays several times; docs/contact.md, "Cost (measured)").

    OMP_NUM_THREADS=1 python scripts/bench_contact_rows.py [--size 10] [--slots 2900] [--repeats 20]
"""
from __future__ import annotations

import argparse
import time

import casadi as ca
import numpy as np


def _timed(f: ca.Function, args: tuple, repeats: int) -> float:
    f(*args)
    t0 = time.perf_counter()
    for _ in range(repeats):
        f(*args)
    return (time.perf_counter() - t0) / repeats * 1e3


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=10)
    ap.add_argument("--slots", type=int, default=2900)
    ap.add_argument("--repeats", type=int, default=20)
    a = ap.parse_args(argv)
    from knit_nlp.weft.model.cases import diagonal_pull
    from knit_nlp.weft.model.problem import parse_problem
    from knit_nlp.weft.model.parametrisation import Full
    from knit_nlp.weft.transcription.contact import Slots
    from knit_nlp.weft.transcription.factory import transcribe
    from knit_nlp.weft.transcription.full import build_nlp
    pr = parse_problem(diagonal_pull(a.size), f"pull {a.size}")
    base = build_nlp(pr)
    rng = np.random.default_rng(0)
    n, N = a.slots, pr.n_loops
    kA = rng.integers(0, N, n)
    kB = np.minimum(kA + rng.integers(0, 2 * a.size + 2, n), N - 1)
    t0 = time.perf_counter()
    c = transcribe(pr, Full(), contact=Slots(kA, kB), base=base)
    build = time.perf_counter() - t0
    sA, sB = rng.uniform(0, pr.L, n), rng.uniform(0, pr.L, n)
    pb = base.params.vector()
    x = c.lift_slots(base.x0, sA, sB)
    p = c.parameters(pb, sA, sB, np.ones(n))
    lam = rng.normal(size=c.n_constraints)
    # DM inputs: IPOPT hands CasADi its own arrays; numpy ones would add their conversion
    # (about 3.5 ms at 2,900 slots) to every timing
    x, p, lam, pb = ca.DM(x), ca.DM(p), ca.DM(lam), ca.DM(pb)
    g = ca.Function("g", [c.nlp["x"], c.nlp["p"]], [c.nlp["g"]])
    g_base = ca.Function("g", [base.nlp["x"], base.nlp["p"]], [base.nlp["g"]])
    d = c.nlpsol_options
    print(f"{a.size} x {a.size} pull, {n} slots, {c.n_variables} variables; build {build:.2f} s")
    print(f"  contact NLP g        {_timed(g, (x, p), a.repeats):8.2f} ms")
    print(f"  contact NLP jac_g    {_timed(d['jac_g'], (x, p), a.repeats):8.2f} ms")
    print(f"  contact NLP hess_lag {_timed(d['hess_lag'], (x, p, 1.0, lam), a.repeats):8.2f} ms")
    print(f"  paper's g alone      {_timed(g_base, (x[:base.n_variables], pb), a.repeats):8.2f} ms")


if __name__ == "__main__":
    main()
