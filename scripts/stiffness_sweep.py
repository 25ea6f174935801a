"""How the spring ratio k_b/k_a and the bending rigidity R_f shape the paper's diagonal pull.

The pull is eq. 28 (problems/wada_fig7.toml) on N x N (default 5): the start of loop (1, 1)
pinned at the origin and H of loop (1, N) moved to the eq. 28 target (for N = 5 exactly
(16.2, 13.9); for other N the same map, the corner-to-H chord stretched 1.883x and turned
25.26 deg, as in problems/diagonal_pull.toml). k_a stays 1. One LoadPath per k_b/k_a value,
its points stepping through the R_f values (material values are NLP parameters, so one build per
path and each point warm-started from the last); the paths run in parallel.

    python scripts/stiffness_sweep.py [--size 5] [--kb 0.01 0.1 1] [--rf 0.25 1 4] [--out results]

Writes ``<out>/stiffness_sweep/{stiffness_sweep.csv, stiffness_sweep.png, summary.json}``: a grid
of small pictures (rows k_b/k_a, columns R_f; deformed loops over the grey natural ones, titled
with the energy and the pulling clamp's reaction) and the table, also printed.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

from knit_nlp.figures import save_figure  # noqa: E402
from knit_nlp.jsonio import write_csv  # noqa: E402
from knit_nlp.studies import add_executor_arguments, run_with_options  # noqa: E402
from knit_nlp.weft.model.cases import diagonal_pull  # noqa: E402
from knit_nlp.weft.model.problem import parse_problem  # noqa: E402
from knit_nlp.studies import LoadPath, point_solution, print_table  # noqa: E402
from knit_nlp.weft.model.centrelines import natural_centrelines  # noqa: E402
from knit_nlp.weft.study import WeftStudy  # noqa: E402

STUDY = "stiffness_sweep"
FIELDS = ("k_b_over_k_a", "R_f", "energy_total", "energy_spring", "energy_bending",
          "reaction_x", "reaction_y", "reaction_norm", "success")


def pull_doc(n: int) -> dict[str, Any]:
    """The eq. 28 pull on an n x n fabric (paper's material; k_b and R_f are varied later)."""
    return diagonal_pull(n)


def build_paths(n: int, kbs: Sequence[float], rfs: Sequence[float]) -> list[LoadPath]:
    """One path per k_b/k_a (k_a = 1), stepping through the R_f values."""
    doc, paths = pull_doc(n), []
    for kb in kbs:
        points = [{"material": {"k_b": float(kb), "R_f": float(rf)}} for rf in rfs]
        paths.append(LoadPath(f"kb{kb:g}", doc, points,
                              labels=[[float(kb), float(rf)] for rf in rfs]))
    return paths


def tabulate(summary: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per point: k_b/k_a, R_f, energies, the pulling clamp's reaction, success."""
    rows = []
    for row in summary["points"]:
        kb, rf = row["label"]
        solved = "energy" in row             # a lost point (timeout, crash) has no values
        f = np.array(row["clamps"][1]["reaction"]) if solved else np.full(2, np.nan)
        e = row["energy"] if solved else {"total": np.nan, "spring": np.nan, "bending": np.nan}
        rows.append({"k_b_over_k_a": kb, "R_f": rf, "energy_total": e["total"],
                     "energy_spring": e["spring"], "energy_bending": e["bending"],
                     "reaction_x": float(f[0]), "reaction_y": float(f[1]),
                     "reaction_norm": float(np.linalg.norm(f)), "success": bool(row["success"])})
    return rows


def draw_grid(path: Path, paths: list[LoadPath], rows: list[dict[str, Any]], cache: Path,
              title: str) -> Path:
    """Rows k_b/k_a, columns R_f: deformed loops (one colour per course) over grey natural ones."""
    study = WeftStudy(parse_problem(paths[0].doc, "<draw>"))
    nat = natural_centrelines(study.problem)
    nr, nc = len(paths), len(paths[0].points)
    fig, axes = plt.subplots(nr, nc, figsize=(3.3 * nc, 3.1 * nr + 0.6), squeeze=False)
    xs = [[point_solution(cache.parent, p, k) for k in range(nc)] for p in paths]
    lines = [[None if x is None else study.nlp.centrelines(x) for x in r] for r in xs]
    every = np.concatenate([nat.reshape(-1, 2)] + [ln.reshape(-1, 2) for r in lines for ln in r
                                                   if ln is not None])
    lo, hi = every.min(axis=0), every.max(axis=0)
    colours = plt.cm.viridis(np.linspace(0.05, 0.85, nat.shape[0]))
    clamps = np.array([c.target for c in study.problem.clamps])
    for r, p in enumerate(paths):
        for k in range(nc):
            ax, row = axes[r, k], rows[r * nc + k]
            ax.add_collection(LineCollection([np.concatenate(list(c)) for c in nat],
                                             colors="0.8", linewidths=0.8))
            if lines[r][k] is not None:
                ax.add_collection(LineCollection([np.concatenate(list(c)) for c in lines[r][k]],
                                                 colors=colours, linewidths=1.1))
            ax.plot(clamps[:, 0], clamps[:, 1], "s", color="crimson", ms=4)
            ax.set_xlim(lo[0] - 1, hi[0] + 1)
            ax.set_ylim(lo[1] - 1, hi[1] + 1)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            flag = "" if row["success"] else "  NOT CONVERGED"
            ax.set_title(f"U = {row['energy_total']:.3g}, |F| = {row['reaction_norm']:.3g}{flag}",
                         fontsize=8.5)
            if k == 0:
                ax.set_ylabel(f"k_b/k_a = {row['k_b_over_k_a']:g}", fontsize=10)
            if r == nr - 1:
                ax.set_xlabel(f"R_f = {row['R_f']:g}", fontsize=10)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def show_table(rows: list[dict[str, Any]]) -> None:
    """The table on one screen."""
    print_table(rows, [("k_b_over_k_a", "kb/ka", "g"), ("R_f", "R_f", "g"),
                       ("energy_total", "U total", ".4f"), ("energy_spring", "U spring", ".4f"),
                       ("energy_bending", "U bend", ".4f"), ("reaction_x", "F_x", ".4f"),
                       ("reaction_y", "F_y", ".4f"), ("reaction_norm", "|F|", ".4f"),
                       ("success", "ok", "")])


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=5, help="N x N fabric (5: the paper's case)")
    ap.add_argument("--kb", type=float, nargs="+", default=[0.01, 0.1, 1.0],
                    help="k_b/k_a values, one row each (k_a = 1; default 0.01 0.1 1)")
    ap.add_argument("--rf", type=float, nargs="+", default=[0.25, 1.0, 4.0],
                    help="R_f values, one column each (default 0.25 1 4)")
    add_executor_arguments(ap)
    ap.add_argument("--out", type=Path, default=Path("results"), help="results root (results)")
    args = ap.parse_args(argv)
    if args.size < 2:
        ap.error("--size must be >= 2")
    return args


def main(argv: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """Run the sweep; write the CSV, the grid PNG and summary.json; print the table."""
    args = parse_args(argv)
    paths = build_paths(args.size, args.kb, args.rf)
    summary = run_with_options(STUDY, paths, args.out, args,
                               prog=Path(__file__).name)
    rows = tabulate(summary)
    out = args.out / STUDY
    write_csv(out / f"{STUDY}.csv", rows, FIELDS)
    target = paths[0].doc["clamp"][1]["position"]
    png = draw_grid(out / f"{STUDY}.png", paths, rows, out / "points",
                    f"{args.size} x {args.size} diagonal pull (eq. 28: H of loop (1, {args.size}) "
                    f"to ({target[0]:.1f}, {target[1]:.1f})), k_a = 1; "
                    f"|F| = reaction at the pulled point")
    show_table(rows)
    print(f"wrote {out / (STUDY + '.csv')}, {png}, {out / 'summary.json'}")
    return rows


if __name__ == "__main__":
    main(sys.argv[1:])
