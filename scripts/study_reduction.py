"""Error and speed of the interpolation reduction against the full model.

For each fabric size and pull, the full model is solved once, then the reduced model with the
paper's corner form (2 x 2 representatives), even 3 x 3, 4 x 4 and 6 x 6 grids, and grids refined
near the clamps (the paper's own suggestion). Prints a table and writes CSV and a plot of
centreline error against parameter count and against time.

    python scripts/study_reduction.py [--sizes 10] [--full-sizes] [--out results/study_reduction]

The default (10 x 10) takes well under a minute; ``--full-sizes`` adds 30 x 30, docs/measurements.md's
table (many minutes: the reduced course pulls at 30 x 30 take hundreds of iterations).
"""
from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from knit_nlp.figures import save_figure  # noqa: E402
from knit_nlp.jsonio import write_csv  # noqa: E402
from knit_nlp.units import Units  # noqa: E402
from knit_nlp.weft.api import solve  # noqa: E402
from knit_nlp.weft.model.parametrisation import spread  # noqa: E402
from knit_nlp.weft.model.cases import course_pull, diagonal_pull  # noqa: E402
from knit_nlp.weft.model.parametrisation import Full, Reduced  # noqa: E402
from knit_nlp.weft.model.problem import parse_problem  # noqa: E402


def even(count: int, n: int) -> list[int]:
    """``count`` representatives spread evenly over 1..n (``parametrisation.spread``)."""
    return list(spread(count, n))


def refined(n: int, near: list[int], count: int = 4) -> list[int]:
    """An even grid plus each clamped index and its neighbours."""
    reps = set(even(count, n))
    for k in near:
        reps.update(v for v in (k - 1, k, k + 1) if 1 <= v <= n)
    return sorted(reps)


def grids(doc: dict) -> list[tuple[str, list[int], list[int]]]:
    m, n = doc["fabric"]["courses"], doc["fabric"]["wales"]
    clamps = doc["clamp"]
    ci = sorted({c["loop"][0] for c in clamps})
    cj = sorted({c["loop"][1] for c in clamps})
    out = [("corner 2x2", even(2, m), even(2, n))]
    out += [(f"even {k}x{k}", even(k, m), even(k, n)) for k in (3, 4, 6)]
    out.append(("refined near clamps", refined(m, ci if len(ci) < m else [], 4),
                refined(n, cj if len(cj) < n else [], 4)))
    return out


FULL_SIZES = [10, 30]


def run_case(case: str, doc: dict) -> list[dict]:
    pr = parse_problem(doc, f"<{case}>")
    models = [("full", Full())] + [(f"{label} ({len(c)}x{len(w)})", Reduced(tuple(c), tuple(w)))
                                   for label, c, w in grids(doc)]
    rows, lines = [], None
    for k, (label, param) in enumerate(models, start=1):
        print(f"  [{k}/{len(models)}] {case}: solving {label} ...", end="\r", flush=True)
        r = solve(pr, param)
        dist = np.zeros(1) if lines is None else np.linalg.norm(r.centrelines() - lines, axis=-1)
        lines = r.centrelines() if lines is None else lines
        rows.append({"case": case, "model": label, "n_parameters": r.nlp.n_parameters,
                     "success": r.success, "energy": r.energy.total, "iterations": r.iterations,
                     "time_s": r.build_s + r.report.solve_s, "max_dist": float(dist.max()),
                     "rms_dist": float(np.sqrt(np.mean(dist ** 2)))})
    return rows


def plot(rows: list[dict], path: Path) -> None:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    for case in dict.fromkeys(r["case"] for r in rows):
        red = [r for r in rows if r["case"] == case and r["model"] != "full"]
        full = next(r for r in rows if r["case"] == case and r["model"] == "full")
        for ax, key in zip(axes, ("n_parameters", "time_s")):
            line, = ax.plot([r[key] for r in red], [r["max_dist"] for r in red], "o-", label=case)
            ax.axvline(full[key], color=line.get_color(), ls=":", lw=1)
    for ax, label in zip(axes, ("parameters (dotted: full model)", "build + solve time, s (dotted: full)")):
        ax.set_xscale("log")
        ax.set_yscale("symlog", linthresh=1e-3)
        ax.set_xlabel(label)
        ax.set_ylabel(f"largest centreline distance to the full model [{Units().length}]")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Interpolation reduction: error against size and time")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10],
                    help="fabric sizes N (N x N; default 10, under a minute)")
    ap.add_argument("--full-sizes", action="store_true",
                    help=f"the sizes of docs/measurements.md {FULL_SIZES} (many minutes)")
    ap.add_argument("--out", type=Path, default=Path("results/study_reduction"))
    args = ap.parse_args(argv)
    if args.full_sizes:
        args.sizes = FULL_SIZES
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in args.sizes:
        for case, doc in ((f"diagonal {n}x{n}", diagonal_pull(n)), (f"course {n}x{n}", course_pull(n))):
            new = run_case(case, doc)
            rows += new
            for r in new:
                print(f"{r['case']:<16} {r['model']:<30} params {r['n_parameters']:>6}  "
                      f"{'ok ' if r['success'] else 'FAIL'} energy {r['energy']:>10.5g}  "
                      f"it {r['iterations']:>4}  time {r['time_s']:>7.3f} s  "
                      f"max dist {r['max_dist']:>8.4g}  rms {r['rms_dist']:>8.4g}", flush=True)
    write_csv(args.out / "study_reduction.csv", rows)
    plot(rows, args.out / "study_reduction.png")
    print(f"wrote {args.out / 'study_reduction.csv'} and {args.out / 'study_reduction.png'}")


if __name__ == "__main__":
    main()
