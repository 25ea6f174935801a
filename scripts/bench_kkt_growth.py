"""How one factorisation of the full weft model's KKT matrix grows with the fabric (issue 22, item 4).

For each size n, ``cases.diagonal_pull(n)`` is transcribed (full model) and the KKT matrix
K = [[H + 1e-8 I, Jᵀ], [J, −1e-8 I]] is formed at the NLP's start (x0, λ = 0), H the
Lagrangian Hessian IPOPT uses and J the constraint Jacobian; it is then factorised twice by
CasADi's ``Linsol("mumps")``, the MUMPS build IPOPT loads (``nfact`` includes MUMPS's analysis
and ordering). Printed per size: rows, nonzeros, build time, both factorisation times and the
process's peak resident memory so far (build, K and the factorisation). A full solve factorises
this matrix about 12 times in 8 iterations (docs/measurements.md, "IPOPT options"), so the
factorisation time times 12 is a floor for IPOPT's linear algebra at that size. Run the largest
size alone (peak memory): sizes are run in one process, in the order given.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python scripts/bench_kkt_growth.py 50 100 150 200 300
"""
from __future__ import annotations

import resource
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from knit_nlp.weft.model import cases  # noqa: E402
from knit_nlp.weft.model.parametrisation import Full  # noqa: E402
from knit_nlp.weft.model.problem import parse_problem  # noqa: E402
from knit_nlp.weft.solving.solve import WeftSolver  # noqa: E402
from knit_nlp.weft.transcription.factory import transcribe  # noqa: E402

REG = 1e-8                     # diagonal shifts that make K regular, as IPOPT's δ_w, δ_c would


def kkt(n: int) -> tuple[ca.DM, float]:
    """K at the start of the full n × n diagonal pull, and the build time (s)."""
    pr = parse_problem(cases.diagonal_pull(n), f"<diagonal_pull({n})>")
    t0 = time.perf_counter()
    w = transcribe(pr, Full())
    solver = WeftSolver(w).solver
    build = time.perf_counter() - t0
    H = solver.get_function("nlp_hess_l")(w.x0, w.p0, 1.0, np.zeros(w.n_constraints))
    J = solver.get_function("nlp_jac_g")(w.x0, w.p0)[1]
    H = H + H.T - ca.diag(ca.diag(H))
    nx, m = H.shape[0], J.shape[0]
    return ca.blockcat([[H + REG * ca.DM.eye(nx), J.T], [J, -REG * ca.DM.eye(m)]]), build


def main(sizes: list[int]) -> None:
    for n in sizes:
        K, build = kkt(n)
        ls = ca.Linsol("kkt", "mumps", K.sparsity())
        ls.sfact(K)
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            ls.nfact(K)
            times.append(time.perf_counter() - t0)
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6
        print(f"{n} x {n}: rows {K.shape[0]}, nonzeros {K.nnz()}, build {build:.1f} s, "
              f"factorisation {times[0]:.2f} s / {times[1]:.2f} s, peak RSS {peak:.2f} GB",
              flush=True)


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [50, 100, 150])
