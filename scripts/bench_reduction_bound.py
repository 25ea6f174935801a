"""How much faster can a reduced parametrisation be than the full model? A measurement.

Issue 3 asks for the reduced 10 x 10 model to solve at least 5x faster than the full one. Every
IPOPT iteration of either model evaluates every loop's position integrals and their first and
second derivatives (each loop's shape is distinct, whatever parametrises it), so a reduced
model can save only the rest: IPOPT's own linear algebra. This script measures, in one run:

- the full model and the shipped reduced model (``transcribe(problem, Reduced())``, the
  condensed model with hand-assembled derivatives): solve time, iterations, and the time spent
  in function evaluations (IPOPT's ``t_wall_nlp_*``);
- the paper's literal condensed form written here with CasADi's AD: the only variables are the
  reduced parameters z and the course starts (the paper's 48 for 10 x 10), loop starts chained
  along the courses, no lifted points, exact Hessian by CasADi; and the same with IPOPT's
  limited-memory Hessian;
- the bound: full solve time / full function-evaluation time, the speed-up a reduced model
  would reach if its derivatives cost what the full model's do and its linear algebra were free.

Point clamps only (no loads, rigid clamps or clamp angles). Best of three solves each, one core.

    OMP_NUM_THREADS=1 python scripts/bench_reduction_bound.py [--sizes 10 30]
"""
from __future__ import annotations

import argparse
import time

import casadi as ca
import numpy as np

from knit_nlp.ipopt import ipopt_options
from knit_nlp.weft.model.basis import n_coeffs
from knit_nlp.weft.model.cases import course_pull, diagonal_pull
from knit_nlp.weft.model.energy import bending_energy, spring_pair_energy
from knit_nlp.weft.model.kinematics import loop_displacements
from knit_nlp.weft.model.parametrisation import Full, Reduced
from knit_nlp.weft.model.problem import WeftProblem, parse_problem
from knit_nlp.weft.solving.solve import WeftSolver
from knit_nlp.weft.transcription.factory import transcribe
from knit_nlp.weft.transcription.reduction import course_maps, n_reduced
from knit_nlp.weft.transcription.rows import eval_points, special_points


def reduction_matrix(pr: WeftProblem) -> np.ndarray:
    """The corner form's map as one dense T, vec(coeffs) = T·z (coeffs 2t+2 × N by loop)."""
    red = Reduced().resolve(pr.courses, pr.wales)
    n, nc = pr.wales, n_coeffs(pr.t)
    T = np.zeros((nc * pr.n_loops, n_reduced(red, pr.t)))
    for i, cm in enumerate(course_maps(pr, red)):
        T[i * n * nc:(i + 1) * n * nc, cm.cols] = cm.T.reshape(n * nc, -1)
    return T


def condensed_nlp(pr: WeftProblem) -> tuple[dict, np.ndarray]:
    """The reduced model with only z and the course starts as variables (paper's count)."""
    m, n, N, nc = pr.courses, pr.wales, pr.n_loops, n_coeffs(pr.t)
    T = reduction_matrix(pr)
    specials = special_points(pr)[0]
    evals = eval_points(pr, specials)
    col, P = {s: q for q, s in enumerate(evals)}, len(evals)
    z, X0 = ca.MX.sym("z", T.shape[1]), ca.MX.sym("X0", 2, m)
    A = ca.reshape(ca.mtimes(ca.DM(T), z), nc, N)
    D = loop_displacements(pr.L, pr.t, np.array(evals), pr.quadrature_nodes).map(N, "serial")(A)
    course, wale = np.divmod(np.arange(N), n)
    first = (course[:, None] == np.arange(m)[None, :]).T.astype(float)            # m x N
    before = ((course[:, None] == course[None, :]) & (wale[:, None] < wale[None, :]))
    ends = D[:, (np.arange(N) * P + col[pr.L]).tolist()]
    starts = ca.mtimes(X0, ca.DM(first)) + ca.mtimes(ends, ca.DM(before.astype(float)))

    def at(s: float, loops: np.ndarray) -> ca.MX:
        return starts[:, loops.tolist()] + D[:, (loops * P + col[s]).tolist()]

    up, low, c = np.arange(n, N), np.arange(0, N - n), pr.crossings
    pair, k = spring_pair_energy().map(N - n), ca.DM([pr.k_a, pr.k_b])
    f = (ca.sum2(pair(at(c.s["E"], low) - at(c.s["B"], up), ca.DM(c.rest_left),
                      ca.DM(c.frame_left), k))
         + ca.sum2(pair(at(c.s["H"], low) - at(c.s["R"], up), ca.DM(c.rest_right),
                        ca.DM(c.frame_right), k))
         + ca.sum2(bending_energy(pr.L, pr.t).map(N)(A, ca.DM(pr.natural.coeffs), pr.R_f)))
    g = []
    for cl in pr.clamps:
        pos = at(cl.s, np.array([(cl.loop[0] - 1) * n + cl.loop[1] - 1]))
        g += [pos[d] - cl.target[d] for d in range(2) if cl.fix[d]]
    natural = np.broadcast_to(pr.natural.coeffs, (N, nc)).ravel()
    z0, *_ = np.linalg.lstsq(T, natural, rcond=None)
    x0 = np.concatenate([z0, pr.natural_starts()[:, 0, :].T.ravel(order="F")])
    return {"x": ca.vertcat(z, ca.vec(X0)), "f": f, "g": ca.vertcat(*g)}, x0


def best_of(solve, repeats: int = 3) -> tuple[float, int, float, float, str]:
    """(solve s, iterations, function-evaluation s, objective, status), fastest of repeats."""
    runs = [solve() for _ in range(repeats)]
    return min(runs, key=lambda r: r[0])


def shipped(pr: WeftProblem, reduced: bool):
    """A solve of the shipped NLP (full, or the condensed reduced model), and its number of
    variables."""
    w = transcribe(pr, Reduced() if reduced else Full())
    solver = WeftSolver(w)

    def run():
        r = solver.once(w.p0, w.x0)
        return r.solve_s, r.iterations, sum(r.stats.values()), r.objective, r.status
    return run, w.n_variables


def condensed(pr: WeftProblem, hessian: str):
    """A solve of the condensed reduced NLP, and its number of variables."""
    nlp, x0 = condensed_nlp(pr)
    solver = ca.nlpsol("condensed", "ipopt", nlp, ipopt_options(
        pr.solver.tol, 1000, mumps_scaling=0, mumps_permuting_scaling=0,
        hessian_approximation=hessian))

    def run():
        t0 = time.perf_counter()
        sol = solver(x0=x0, lbg=0, ubg=0)
        st = solver.stats()
        evals = sum(v for k, v in st.items() if k.startswith("t_wall_nlp"))
        return (time.perf_counter() - t0, int(st["iter_count"]), evals, float(sol["f"]),
                str(st["return_status"]))
    return run, nlp["x"].numel()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[10])
    ap.add_argument("--limited-memory", action="store_true",
                    help="also the condensed model with IPOPT's limited-memory Hessian (1000 "
                    "iterations, best of three: minutes; left out so the default takes < 1 min)")
    args = ap.parse_args()
    print("| case | model | variables | iterations | solve s | evaluations s | energy | status |")
    print("|---|---|---:|---:|---:|---:|---:|---|")
    for size in args.sizes:
        for label, doc in (("diagonal", diagonal_pull(size)), ("course", course_pull(size))):
            pr = parse_problem(doc, f"{label}.toml")
            rows = {"full": shipped(pr, False), "reduced (shipped, condensed)": shipped(pr, True),
                    "reduced, paper's form, CasADi exact Hessian": condensed(pr, "exact")}
            if args.limited_memory:
                rows["reduced, paper's form, limited-memory"] = condensed(pr, "limited-memory")
            full = None
            for name, (run, n_variables) in rows.items():
                t, it, ev, obj, status = best_of(run)
                full = full or (t, ev)
                print(f"| {label} {size} x {size} | {name} | {n_variables} | {it} | {t:.4f} | "
                      f"{ev:.4f} | {obj:.6g} | {status} |", flush=True)
            print(f"| {label} {size} x {size} | bound: full solve / full evaluations | | | "
                  f"{full[0] / full[1]:.2f}x | | | |", flush=True)


if __name__ == "__main__":
    main()
