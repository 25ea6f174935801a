"""Error and speed of the interpolation reduction against the full model.

For each fabric size and pull, the full model is solved once, then the reduced model with the
paper's corner form (2 x 2 representatives), even 3 x 3, 4 x 4 and 6 x 6 grids, and grids refined
near the clamps (the paper's own suggestion). Prints a table and writes CSV and a plot of
centreline error against parameter count and against time.

    python scripts/study_reduction.py [--sizes 10 30] [--out results/study_reduction]
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_weft import diagonal_pull_doc  # noqa: E402

from knit_nlp.figures import save_figure  # noqa: E402
from knit_nlp.study import write_csv  # noqa: E402
from knit_nlp.weft.natural import natural_loop, preset_coeffs  # noqa: E402
from knit_nlp.weft.problem import parse_problem  # noqa: E402
from knit_nlp.weft.run import solve_problem  # noqa: E402


def course_pull_doc(n: int, strain: float = 0.25) -> dict:
    """Left edge held in x (course 1 also in y), right edge pulled by ``strain`` along x."""
    w = natural_loop(preset_coeffs("jersey", 3), 10.0, 3).wale_spacing
    clamps = []
    for i in range(1, n + 1):
        clamps.append({"loop": [i, 1], "point": "start", "displacement": [0.0, 0.0],
                       "fix": ["x", "y"] if i == 1 else ["x"]})
        clamps.append({"loop": [i, n], "point": "end", "displacement": [strain * n * w, 0.0],
                       "fix": ["x"]})
    return {"name": f"course_pull_{n}x{n}", "fabric": {"courses": n, "wales": n}, "clamp": clamps}


def even(count: int, n: int) -> list[int]:
    """``count`` representatives spread evenly over 1..n."""
    return sorted(set(int(round(v)) for v in np.linspace(1, n, min(count, n))))


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


def run_case(case: str, doc: dict) -> list[dict]:
    full = solve_problem(parse_problem(f"<{case}>", doc))
    ft = full.result["timings"]
    rows = [{"case": case, "model": "full", "n_parameters": full.result["n_parameters"],
             "success": full.report.success, "energy": full.result["energy"]["total"],
             "iterations": full.result["iterations"], "time_s": ft["build_s"] + ft["solve_s"],
             "max_dist": 0.0, "rms_dist": 0.0}]
    lines = full.lines()
    for label, courses, wales in grids(doc):
        d = dict(doc, reduction={"representative_courses": courses, "representative_wales": wales})
        red = solve_problem(parse_problem(f"<{case} {label}>", d), reduced=True)
        dist = np.linalg.norm(red.lines() - lines, axis=-1)
        rt = red.result["timings"]
        rows.append({"case": case, "model": f"{label} ({len(courses)}x{len(wales)})",
                     "n_parameters": red.result["n_parameters"], "success": red.report.success,
                     "energy": red.result["energy"]["total"], "iterations": red.result["iterations"],
                     "time_s": rt["build_s"] + rt["solve_s"], "max_dist": float(dist.max()),
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
        ax.set_ylabel("largest centreline distance to the full model")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Interpolation reduction: error against size and time")
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 30])
    ap.add_argument("--out", type=Path, default=Path("results/study_reduction"))
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for n in args.sizes:
        for case, doc in ((f"diagonal {n}x{n}", diagonal_pull_doc(n)), (f"course {n}x{n}", course_pull_doc(n))):
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
