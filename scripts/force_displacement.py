"""Uniaxial pulls of a plain-knit fabric: reaction force and energy against displacement.

Three loading paths, each warm-started step by step and run in parallel by ``run_study``:

- ``course``: a rigid (line) clamp holds the ``start`` of loop (i, 1) of every course i, fixed;
  a second one holds the ``end`` of loop (i, n) of every course and is translated by [d, 0].
  Strain = d / (n w), w the wale spacing (n w = natural distance between the two lines).
- ``wale``: a line clamp holds the ``start`` of every bottom-course loop (1, j), fixed; another
  holds the ``start`` of every top-course loop (m, j) and is translated by [0, d].
  Strain = d / ((m - 1) c), c the course spacing.
- ``diagonal``: point clamps as in problems/diagonal_pull.toml: the ``start`` of loop (1, 1)
  pinned at its natural place, ``H`` of loop (1, n) moved along the direction of the paper's
  eq. 28 pull (H's natural position to its eq. 28 target, the corner-to-H chord stretched
  1.883x and turned 25.26 deg). Strain = chord elongation |P - O| / |P0 - O| - 1 with O the
  pinned corner and P the pulled point.

Reported force: the pulling clamp's reaction (force on the fabric) along the pull direction.

    python scripts/force_displacement.py [--size 6] [--steps 12] [--max-strain 0.4] [--out results]
                                         [--animate]

Writes ``<out>/force_displacement/{course,wale,diagonal}.csv``, ``force_displacement.png``
(curves), ``shapes.png`` (each pull's loops at the largest strain) and ``summary.json`` (plus the
per-point cache in ``points/``); with ``--animate`` also ``<direction>.gif``, each pull's
loading path.
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
from knit_nlp.units import Units  # noqa: E402
from knit_nlp.weft.model.cases import diagonal_pull, unclamped  # noqa: E402
from knit_nlp.weft.model.problem import WeftProblem, parse_problem  # noqa: E402
from knit_nlp.studies import LoadPath, point_solution, print_table  # noqa: E402
from knit_nlp.weft.model.centrelines import natural_centrelines  # noqa: E402
from knit_nlp.weft.study import WeftStudy, animate_points  # noqa: E402

STUDY = "force_displacement"
DIRECTIONS = ("course", "wale", "diagonal")
LENGTH, FORCE, ENERGY = Units().length, Units().force, Units().energy   # the paper's, unnamed
FIELDS = ("displacement", "strain", "reaction", "energy_total", "energy_spring",
          "energy_bending", "success")


def natural(m: int, n: int) -> WeftProblem:
    """The parsed clamp-free problem (for natural positions and spacings)."""
    return parse_problem(unclamped(m, n), "<natural>")


def course_doc(m: int, n: int) -> dict[str, Any]:
    """Left line clamp (starts of (i, 1)) fixed; right line clamp (ends of (i, n)) to move."""
    doc = unclamped(m, n)
    doc["rigid_clamp"] = [
        {"points": [{"loop": [i, 1], "point": "start"} for i in range(1, m + 1)]},
        {"points": [{"loop": [i, n], "point": "end"} for i in range(1, m + 1)]}]
    return doc


def wale_doc(m: int, n: int) -> dict[str, Any]:
    """Bottom line clamp (starts of (1, j)) fixed; top line clamp (starts of (m, j)) to move."""
    doc = unclamped(m, n)
    doc["rigid_clamp"] = [
        {"points": [{"loop": [1, j], "point": "start"} for j in range(1, n + 1)]},
        {"points": [{"loop": [m, j], "point": "start"} for j in range(1, n + 1)]}]
    return doc


def diagonal_geometry(m: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Natural position of H of loop (1, n) and the unit direction of the eq. 28 pull."""
    pr = natural(m, n)
    h0 = pr.natural_position((1, n), pr.crossings.s["H"])
    u = np.array(diagonal_pull(n, m)["clamp"][1]["position"]) - h0
    return h0, u / np.linalg.norm(u)


def diagonal_doc(m: int, n: int) -> dict[str, Any]:
    """Corner (1, 1) start pinned; H of loop (1, n) pinned at its natural place (moved later)."""
    doc = unclamped(m, n)
    doc["clamp"] = [{"loop": [1, 1], "point": "start", "displacement": [0.0, 0.0]},
                    {"loop": [1, n], "point": "H", "displacement": [0.0, 0.0]}]
    return doc


def diagonal_displacement(h0: np.ndarray, u: np.ndarray, strain: float) -> float:
    """d >= 0 with |h0 + d u| = (1 + strain) |h0| (the corner is at the origin)."""
    r = (1.0 + strain) * np.linalg.norm(h0)
    b = float(h0 @ u)
    return -b + np.sqrt(b * b - (h0 @ h0 - r * r))


def build_paths(m: int, n: int, steps: int, max_strain: float,
                directions: Sequence[str] = DIRECTIONS) -> dict[str, tuple[LoadPath, dict]]:
    """Per direction: its LoadPath and a dict of displacements, strains and the pull unit."""
    pr = natural(m, n)
    w, c = pr.natural.wale_spacing, pr.natural.course_spacing
    strains = np.linspace(max_strain / steps, max_strain, steps)
    out: dict[str, tuple[LoadPath, dict]] = {}
    for name in directions:
        if name == "course":
            d, u, doc = strains * n * w, np.array([1.0, 0.0]), course_doc(m, n)
            points = [{"rigid": {"2": [di, 0.0, 0.0]}} for di in d]
        elif name == "wale":
            d, u, doc = strains * (m - 1) * c, np.array([0.0, 1.0]), wale_doc(m, n)
            points = [{"rigid": {"2": [0.0, di, 0.0]}} for di in d]
        else:
            h0, u = diagonal_geometry(m, n)
            d = np.array([diagonal_displacement(h0, u, e) for e in strains])
            doc = diagonal_doc(m, n)
            points = [{"displacements": {"2": (di * u).tolist()}} for di in d]
        out[name] = (LoadPath(name, doc, points,
                              labels=[float(e) for e in strains]),
                     {"d": d, "strain": strains, "u": u})
    return out


def reaction_along(row: dict[str, Any], name: str, u: np.ndarray) -> float:
    """The pulling clamp's reaction (force on the fabric) projected on the pull direction."""
    f = row["rigid_clamps"][1]["force"] if name != "diagonal" else row["clamps"][1]["reaction"]
    return float(np.dot(f, u))


def tabulate(summary: dict[str, Any],
             built: dict[str, tuple[LoadPath, dict]]) -> dict[str, list[dict[str, Any]]]:
    """Per direction: rows of displacement, strain, reaction along the pull, energies, success."""
    tables: dict[str, list[dict[str, Any]]] = {name: [] for name in built}
    meta = {name: m for name, (_, m) in built.items()}
    direction = {lp.name: name for name, (lp, _) in built.items()}
    for row in summary["points"]:
        name, k = direction[row["path"]], row["index"]
        solved = "energy" in row             # a lost point (timeout, crash) has no values
        e = row["energy"] if solved else {"total": np.nan, "spring": np.nan, "bending": np.nan}
        tables[name].append({"displacement": float(meta[name]["d"][k]),
                             "strain": float(meta[name]["strain"][k]),
                             "reaction": reaction_along(row, name, meta[name]["u"]) if solved
                             else np.nan,
                             "energy_total": e["total"], "energy_spring": e["spring"],
                             "energy_bending": e["bending"], "success": bool(row["success"])})
    return tables


def plot(path: Path, tables: dict[str, list[dict[str, Any]]], title: str) -> Path:
    """Reaction along the pull (left) and stored energy (right) against displacement."""
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    colours = {"course": "tab:blue", "wale": "tab:orange", "diagonal": "tab:green"}
    for name, rows in tables.items():
        good = [r for r in rows if r["success"]]
        d = [0.0] + [r["displacement"] for r in good]
        col = colours.get(name, None)
        ax1.plot(d, [0.0] + [r["reaction"] for r in good], "o-", color=col, ms=4, label=name)
        ax2.plot(d, [0.0] + [r["energy_total"] for r in good], "o-", color=col, ms=4,
                 label=f"{name} total")
        ax2.plot(d, [0.0] + [r["energy_bending"] for r in good], ":", color=col,
                 label=f"{name} bending")
        bad = [r["displacement"] for r in rows if not r["success"]]
        for ax in (ax1, ax2):   # failed solves: a cross on the axis, their values are not shown
            ax.plot(bad, [0.0] * len(bad), "x", color=col, ms=10, mew=2)
    ax1.set(xlabel=f"displacement of the pulling clamp [{LENGTH}]",
            ylabel=f"reaction along the pull [{FORCE}]", title="force - displacement")
    ax2.set(xlabel=f"displacement of the pulling clamp [{LENGTH}]",
            ylabel=f"stored energy [{ENERGY}]",
            title="energy (solid: total, dotted: bending)")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def last_lines(path: LoadPath, cache: Path) -> tuple[np.ndarray, np.ndarray | None, WeftStudy]:
    """Natural and deformed centrelines (m, n, S, 2) of a path's last point (None: no result)."""
    study = WeftStudy(parse_problem(path.doc, f"<{path.name}>"))
    x = point_solution(cache.parent, path, len(path.points) - 1)
    deformed = None if x is None else study.nlp.centrelines(x)
    return natural_centrelines(study.problem), deformed, study


def held_positions(path: LoadPath, study: WeftStudy) -> np.ndarray:
    """Where the held points are at the path's last point (from the point's parameters)."""
    pr, point = study.problem, path.points[-1]
    if pr.rigid_clamps:
        out = []
        for q, rc in enumerate(pr.rigid_clamps):
            move = np.array(point.get("rigid", {}).get(str(q + 1), [0.0, 0.0, 0.0])[:2])
            out += [pr.natural_position(lp, s) + move for lp, _, s in rc.points]
        return np.array(out)
    disp = point.get("displacements", {})
    return np.array([pr.natural_position(c.loop, c.s) + np.array(disp.get(str(q + 1), [0.0, 0.0]))
                     for q, c in enumerate(pr.clamps)])


def plot_shapes(path: Path, paths: list[LoadPath], cache: Path, strain: float,
                converged: list[bool]) -> Path:
    """Each pull's loops at the largest strain (one colour per course) over the natural ones."""
    fig, axes = plt.subplots(1, len(paths), figsize=(4.6 * len(paths), 4.6), squeeze=False)
    for ax, lp, ok in zip(axes[0], paths, converged):
        nat, deformed, study = last_lines(lp, cache)
        colours = plt.cm.viridis(np.linspace(0.05, 0.85, nat.shape[0]))
        ax.add_collection(LineCollection([np.concatenate(list(c)) for c in nat], colors="0.8",
                                         linewidths=0.8))
        if deformed is not None:
            ax.add_collection(LineCollection([np.concatenate(list(c)) for c in deformed],
                                             colors=colours, linewidths=1.2))
        held = held_positions(lp, study)
        ax.plot(held[:, 0], held[:, 1], "s", color="crimson", ms=4)
        ax.autoscale()
        ax.set_aspect("equal")
        ax.margins(0.05)
        flag = "" if ok else ", NOT CONVERGED"
        ax.set_title(f"{lp.name.split('-')[0]} pull, strain {strain:g}{flag} "
                     "(squares: held points)", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, dpi=100)
    plt.close(fig)
    return path


def show_table(tables: dict[str, list[dict[str, Any]]]) -> None:
    """One screen: per direction and step, strain, displacement, reaction, energies, success."""
    print_table([{"pull": name, **r} for name, rows in tables.items() for r in rows],
                [("pull", "pull", ""), ("strain", "strain", ".3f"), ("displacement", "disp", ".3f"),
                 ("reaction", "reaction", ".4f"), ("energy_total", "U total", ".4f"),
                 ("energy_spring", "U spring", ".4f"), ("energy_bending", "U bend", ".4f"),
                 ("success", "ok", "")])


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, nargs="+", default=[6], metavar="N",
                    help="fabric size: N (N x N) or COURSES WALES (default 6)")
    ap.add_argument("--steps", type=int, default=12, help="displacement steps per pull (12)")
    ap.add_argument("--max-strain", type=float, default=0.4, help="largest strain (0.4)")
    ap.add_argument("--directions", nargs="+", choices=DIRECTIONS, default=list(DIRECTIONS))
    add_executor_arguments(ap)
    ap.add_argument("--out", type=Path, default=Path("results"), help="results root (results)")
    ap.add_argument("--animate", action="store_true", help="also a GIF of each loading path")
    args = ap.parse_args(argv)
    if len(args.size) not in (1, 2) or min(args.size) < 2:
        ap.error("--size takes N or COURSES WALES, each >= 2")
    return args


def main(argv: Sequence[str] | None = None) -> dict[str, list[dict[str, Any]]]:
    """Run the three pulls; write CSVs, the PNG and summary.json; print the table."""
    args = parse_args(argv)
    m, n = (args.size * 2)[:2]
    built = build_paths(m, n, args.steps, args.max_strain, args.directions)
    summary = run_with_options(STUDY, [p for p, _ in built.values()], args.out, args,
                               prog=Path(__file__).name)
    tables = tabulate(summary, built)
    out = args.out / STUDY
    for name, rows in tables.items():
        write_csv(out / f"{name}.csv", rows, FIELDS)
    png = plot(out / f"{STUDY}.png", tables,
               f"{m} x {n} plain knit, k_a = 1, k_b = 0.01, R_f = 1: course/wale pulls with line "
               f"clamps, diagonal with point clamps (x on the axis: not converged)")
    shapes = plot_shapes(out / "shapes.png", [p for p, _ in built.values()], out / "points",
                         args.max_strain, [rows[-1]["success"] for rows in tables.values()])
    show_table(tables)
    if args.animate:
        for name, (lp, _) in built.items():
            frames = [(f"{name}: {label}", point_solution(out, lp, k))
                      for k, label in enumerate(lp.labels)]
            gif = animate_points(out / f"{name}.gif", parse_problem(lp.doc, f"<{name}>"), frames)
            print(f"wrote {gif}")
    print(f"wrote {out}/{{{','.join(tables)}}}.csv, {png}, {shapes}, {out / 'summary.json'}")
    return tables


if __name__ == "__main__":
    main(sys.argv[1:])
