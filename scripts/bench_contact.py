"""Benchmark yarn contact: the cost of a solve with ``[yarn] radius`` against the same solve
without, in one process, alternating (same-run ratios: timings on a shared machine are noisy),
and the x-stretch reaction curve of a fabric between rigid edges with and without contact.

    OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python scripts/bench_contact.py \
        [--sizes 6 10 30] [--big 100] [--budget 600] [--curve 12] [--strain 0.5] [--plot FILE]

Issue 19's targets: a 30 x 30 diagonal pull with contact <= 3x the time without; 100 x 100 with
contact <= 60 s on 2 cores. A solve is given ``--budget`` seconds ([solver] max_time); one
that runs out is printed as such (its ratio is then a lower bound).
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import time

import numpy as np

RADIUS = 0.15          # 0.015 L: thinner than the jersey's closest non-crossing pieces (0.352)


def _problem(doc: dict, radius: float | None, budget: float):
    from knit_nlp.weft.model.problem import Yarn, parse_problem
    pr = parse_problem(doc, f"<bench {doc.get('name', '')}>")
    solver = dataclasses.replace(pr.solver, max_time=budget)
    return dataclasses.replace(pr, solver=solver, yarn=None if radius is None else Yarn(radius))


def timed_pull(n: int, radius: float | None, budget: float) -> dict:
    """Build and solve the n x n diagonal pull (eq. 28 scaled), with or without contact."""
    from knit_nlp.weft.api import solve
    from knit_nlp.weft.model.cases import diagonal_pull
    from knit_nlp.weft.model.parametrisation import Full
    pr = _problem(diagonal_pull(n), radius, budget)
    t0 = time.perf_counter()
    r = solve(pr, Full())
    row = {"n": n, "contact": radius is not None, "seconds": time.perf_counter() - t0,
           "success": r.success, "status": r.status}
    if r.contact is not None:
        from knit_nlp.weft.output.check import check
        rep = check(r.to_json(), pr)            # the independent checker, outside the timing
        row["checked"] = (f"check: {len(rep.new_crossings)} new crossings, "
                          f"{rep.n_short} gaps below 2r(1-1e-3), smallest "
                          f"{rep.smallest_gap / (2 * radius) if rep.smallest_gap else None}")
        c = r.contact.to_json()
        row.update(active=c["active"], gap_over_2r=c["smallest_gap_over_2r"],
                   new_crossings=c["new_crossings"], solves=c["solves"],
                   nlp_vars=c["contact_nlp"]["n_variables"])
    return row


def cost(sizes: list[int], budget: float, repeats: int) -> None:
    print(f"{'size':>7} {'without s':>10} {'with s':>10} {'ratio':>7}  contact (active, "
          "smallest gap / 2r, new crossings, IPOPT solves, contact NLP variables), status")
    for n in sizes:
        plain, withc = [], []
        for _ in range(repeats):                 # alternate: A, B, A, B ...
            plain.append(timed_pull(n, None, budget))
            withc.append(timed_pull(n, RADIUS, budget))
        a = min(r["seconds"] for r in plain)
        b = min(r["seconds"] for r in withc)
        last = withc[-1]
        ok = "" if last["success"] else f"  NOT CONVERGED ({last['status']}: ratio is a lower bound)"
        print(f"{n:>3}x{n:<3} {a:>10.2f} {b:>10.2f} {b / a:>7.2f}  "
              f"({last.get('active')}, {last.get('gap_over_2r')}, {last.get('new_crossings')}, "
              f"{last.get('solves')}, {last.get('nlp_vars')}){ok}  {last.get('checked', '')}",
              flush=True)


def stretch_doc(n: int) -> dict:
    """An n x n jersey between rigid edges: every course's first start and last end held as
    two rigid bodies; the right one moves along x (WeftParams ``rigid`` 2)."""
    from knit_nlp.weft.model.cases import unclamped
    doc = unclamped(n, n)
    doc.update(name=f"x_stretch_{n}x{n}",
               rigid_clamp=[{"edge": "left", "point": "start"},
                            {"edge": "right", "point": "end", "translation": [0.0, 0.0]}])
    return doc


def curve(n: int, strain: float, steps: int, radius: float | None, budget: float):
    """Strains and the right edge's x force along a warm-started path to ``strain``."""
    from knit_nlp.weft.study import study
    pr = _problem(stretch_doc(n), radius, budget)
    width = n * pr.natural.wale_spacing
    st = study(pr)
    x, rows = None, []
    for e in np.linspace(0.0, strain, steps + 1)[1:]:
        r = st.run(st.params.with_(rigid={2: (e * width, 0.0, 0.0)}), x0=x)
        force = r.rigid_clamps[1].force[0]
        active = None if r.contact is None else r.contact.active
        rows.append((e, force, r.success, active))
        print(f"  strain {e:5.3f}: force {force:9.4g} {pr.units.force}, "
              f"{'ok' if r.success else 'NOT CONVERGED'}"
              + ("" if active is None else f", {active} active contacts"), flush=True)
        if r.success:
            x = r.x
    return pr, rows


def plot_curves(path: str, n: int, curves: dict) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.2), layout="constrained")
    units = None
    for label, (pr, rows) in curves.items():
        units = pr.units
        e = [0.0] + [r[0] * 100 for r in rows if r[2]]
        f = [0.0] + [r[1] for r in rows if r[2]]
        failed = ", ".join(f"{r[0] * 100:g}" for r in rows if not r[2])
        ax.plot(e, f, "o-", ms=4, label=label + (f" (not converged at {failed} %)" if failed
                                                  else ""))
    ax.set_xlabel("course-direction strain [%] (edge displacement / natural width)")
    ax.set_ylabel(f"right edge reaction, x [{units.force}]")
    ax.set_title(f"{n} x {n} jersey stretched along the courses between rigid edges\n"
                 f"(paper's material, loop length L = 10 {units.length}; r: yarn radius "
                 f"[{units.length}])",
                 fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="*", default=[6, 10, 30])
    ap.add_argument("--big", type=int, nargs="*", default=[100],
                    help="sizes solved with contact only (the 60 s target)")
    ap.add_argument("--budget", type=float, default=600.0, help="seconds per solve")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--curve", type=int, default=12, help="fabric of the stretch curve (0: none)")
    ap.add_argument("--strain", type=float, default=0.5)
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--radii", type=float, nargs="+", default=[RADIUS],
                    help="yarn radii of the stretch curves (beside the paper's model)")
    ap.add_argument("--plot", default=None,
                    help="draw the stretch curves to this file (none drawn without it)")
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} at the start; OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')} "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS')} cores={os.cpu_count()}"
          f" radius={RADIUS} budget={args.budget} s")
    if args.sizes:
        cost(args.sizes, args.budget, args.repeats)
    for n in args.big:
        r = timed_pull(n, RADIUS, args.budget)
        print(f"{n}x{n} with contact: {r['seconds']:.1f} s, {r['status']}, active "
              f"{r.get('active')}, new crossings {r.get('new_crossings')}, IPOPT solves "
              f"{r.get('solves')}, contact NLP variables {r.get('nlp_vars')}, "
              f"{r.get('checked')}", flush=True)
    if args.curve:
        curves = {}
        for label, radius in [("without contact (paper's model)", None)] + [
                (f"with contact, r = {r:g}", r) for r in args.radii]:
            print(f"x-stretch {args.curve}x{args.curve}, {label}:")
            t0 = time.perf_counter()
            curves[label] = curve(args.curve, args.strain, args.steps, radius, args.budget)
            print(f"  {time.perf_counter() - t0:.1f} s")
        if args.plot:
            plot_curves(args.plot, args.curve, curves)
            print(f"wrote {args.plot}")


if __name__ == "__main__":
    main()
