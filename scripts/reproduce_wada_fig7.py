"""The paper's Fig. 7 (eq. 28) with point clamps, beside the same pull with rigid line clamps.

Left: problems/wada_fig7.toml as the paper states it: 5 x 5, t = 3, k_a = 1, k_b = 0.01,
R_f = 1, x11(0) = y11(0) = 0 and H of loop (1, 5) at (16.2, 13.9); nothing else is held.

Right: the paper (sec. 4.3) blames its mismatch with the photograph on the clamps: the real
fabric was gripped along lines, the model at two points. Here each pinned point becomes a rigid
jaw along the bottom edge: the fixed jaw holds the ``start`` of loops (1, 1) .. (1, g), never
moving (so the corner point is still at the origin); the moving jaw holds ``H`` of loops
(1, n-g+1) .. (1, n) and is translated (no rotation) by (16.2, 13.9) - H0 of loop (1, 5), so
that point still reaches (16.2, 13.9). g = ``--grip`` (default 2: each jaw one wale wide).
The right panel also shows the point-clamp solution dashed, for comparison.

    python scripts/reproduce_wada_fig7.py [--grip 2] [--out results]

Writes ``<out>/wada_fig7/{wada_fig7.png, comparison.json}`` and prints energies, reactions and
the largest and RMS distances between the two solutions' centrelines.
"""
from __future__ import annotations

import argparse
import copy
import sys
from pathlib import Path
from typing import Any, Sequence

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402

from knit_nlp.figures import save_figure  # noqa: E402
from knit_nlp.jsonio import write_json  # noqa: E402
from knit_nlp.problems import resolve  # noqa: E402
from knit_nlp.tomlio import load_toml  # noqa: E402
from knit_nlp.weft.model.problem import parse_problem  # noqa: E402
from knit_nlp.weft.api import solve as solve_problem  # noqa: E402
from knit_nlp.weft.output.results import WeftResult as Solved  # noqa: E402
from knit_nlp.weft.model.centrelines import natural_centrelines  # noqa: E402

STUDY = "wada_fig7"


def point_doc() -> dict[str, Any]:
    """problems/wada_fig7.toml as a dict."""
    return load_toml(resolve("wada_fig7"))


def line_doc(doc: dict[str, Any], grip: int) -> dict[str, Any]:
    """The same pull with the two point clamps replaced by rigid jaws of ``grip`` points each."""
    fixed, moving = doc["clamp"]
    n = doc["fabric"]["wales"]
    pr = parse_problem(doc, "<wada_fig7>")
    target = np.array(moving["position"])
    h0 = pr.natural_position(tuple(moving["loop"]), pr.crossings.s[moving["point"]])
    origin = pr.natural_position(tuple(fixed["loop"]), 0.0)
    if not np.allclose(origin, fixed["position"]):
        raise ValueError("the fixed clamp is expected at its natural position")
    out = copy.deepcopy(doc)
    del out["clamp"]
    out["name"] = "wada_fig7_line"
    out["description"] = f"eq. 28 with rigid jaws of {grip} points along the bottom edge"
    out["rigid_clamp"] = [
        {"points": [{"loop": [1, j], "point": "start"} for j in range(1, grip + 1)]},
        {"points": [{"loop": [1, j], "point": moving["point"]} for j in range(n - grip + 1, n + 1)],
         "translation": (target - h0).tolist()}]
    return out


def lines(s: Solved, samples: int = 81) -> np.ndarray:
    """Deformed centrelines (m, n, S, 2)."""
    return s.centrelines(samples)


def held_points(s: Solved) -> tuple[np.ndarray, np.ndarray]:
    """Positions and reactions of every held point (point clamps and rigid-jaw points)."""
    pos = [c.position for c in s.clamps]
    force = [c.reaction for c in s.clamps]
    for rc in s.rigid_clamps:
        pos += list(rc.positions)
        force += list(rc.reactions)
    return np.array(pos).reshape(-1, 2), np.array(force).reshape(-1, 2)


def draw_panel(ax, s: Solved, nat: np.ndarray, title: str, ghost: np.ndarray | None,
               fscale: float) -> None:
    """Fig. 7 style: natural loops faint, each course one coloured yarn, held points marked,
    reaction arrows; an optional dashed ghost (the other solution)."""
    ax.add_collection(LineCollection([np.concatenate(list(c)) for c in nat], colors="0.82",
                                     linewidths=0.9))
    if ghost is not None:
        ax.add_collection(LineCollection([np.concatenate(list(c)) for c in ghost], colors="k",
                                         linewidths=0.7, linestyles="--", alpha=0.6))
    deformed = lines(s)
    colours = plt.cm.tab10(np.arange(deformed.shape[0]) % 10)
    for i, course in enumerate(deformed):
        ax.plot(*np.concatenate(list(course)).T, color=colours[i], lw=1.8, label=f"course {i + 1}")
    pos, force = held_points(s)
    ax.plot(pos[:, 0], pos[:, 1], "s", color="crimson", ms=6, zorder=5, label="held point")
    ax.quiver(pos[:, 0], pos[:, 1], force[:, 0] * fscale, force[:, 1] * fscale, angles="xy",
              scale_units="xy", scale=1, color="crimson", width=0.005, zorder=6)
    if len(s.rigid_clamps):
        for rc in s.rigid_clamps:
            p = rc.positions
            ax.plot(p[:, 0], p[:, 1], "-", color="crimson", lw=4, alpha=0.5, solid_capstyle="round")
    e = s.energy
    ok = "converged" if s.success else "NOT CONVERGED"
    ax.set_title(f"{title}\nU = {e.total:.4f} (spring {e.spring:.4f}, bending "
                 f"{e.bending:.4f}), {ok}", fontsize=9.5)
    ax.set_aspect("equal")
    ax.set_xlabel(f"x [{s.problem.units.length}]")
    ax.set_ylabel(f"y [{s.problem.units.length}]")
    ax.grid(alpha=0.2)


def plot(path: Path, point: Solved, line: Solved, nat: np.ndarray, grip: int) -> Path:
    """Both solutions side by side on the same axes limits."""
    both = np.concatenate([nat.reshape(-1, 2), lines(point).reshape(-1, 2),
                           lines(line).reshape(-1, 2)])
    lo, hi = both.min(axis=0) - 1.0, both.max(axis=0) + 1.0
    fmax = max(np.abs(held_points(point)[1]).max(), np.abs(held_points(line)[1]).max())
    fscale = 0.12 * (hi - lo).max() / fmax
    tips = np.concatenate([pos + fscale * f for pos, f in (held_points(point), held_points(line))])
    lo, hi = np.minimum(lo, tips.min(axis=0) - 0.3), np.maximum(hi, tips.max(axis=0) + 0.3)
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.6))
    draw_panel(axes[0], point, nat, "point clamps (the paper's eq. 28, Fig. 7)", None, fscale)
    draw_panel(axes[1], line, nat, f"rigid line clamps ({grip} points per jaw); "
               "dashed: point-clamp solution", lines(point), fscale)
    for ax in axes:
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
    axes[0].legend(fontsize=8, loc="upper left")
    fig.suptitle(f"5 x 5 plain knit, k_a = 1, k_b = 0.01, R_f = 1; H of loop (1, 5) at "
                 f"(16.2, 13.9); arrows: reactions (largest {fmax:.3g}); grey: natural",
                 fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    save_figure(fig, path, dpi=110)
    plt.close(fig)
    return path


def compare(point: Solved, line: Solved) -> dict[str, Any]:
    """Energies, reactions at the pulled side, and distances between the two centrelines."""
    d = np.linalg.norm(lines(point) - lines(line), axis=-1)
    fixed, moved = line.rigid_clamps
    return {"point_clamps": {"success": point.success, "energy": point.energy.to_json(),
                             "pull_reaction": point.clamps[1].reaction.tolist(),
                             "fixed_reaction": point.clamps[0].reaction.tolist()},
            "line_clamps": {"success": line.success, "energy": line.energy.to_json(),
                            "pull_force": moved.force.tolist(), "pull_moment": moved.moment,
                            "fixed_force": fixed.force.tolist(), "fixed_moment": fixed.moment,
                            "translation": moved.translation.tolist()},
            "centreline_distance": {"max": float(d.max()), "rms": float(np.sqrt(np.mean(d ** 2))),
                                    "argmax_loop": [int(v) + 1 for v in
                                                    np.unravel_index(d.max(axis=-1).argmax(),
                                                                     d.shape[:2])]}}


def print_comparison(c: dict[str, Any]) -> None:
    """A short printed comparison."""
    p, q, d = c["point_clamps"], c["line_clamps"], c["centreline_distance"]
    print(f"{'':<14}{'ok':>4} {'U total':>9} {'U spring':>9} {'U bend':>9}   pulling-side reaction")
    for name, r, f in (("point clamps", p, p["pull_reaction"]),
                       ("line clamps", q, q["pull_force"])):
        e = r["energy"]
        extra = f", moment {q['pull_moment']:.4f}" if r is q else ""
        print(f"{name:<14}{'y' if r['success'] else 'NO':>4} {e['total']:>9.4f} {e['spring']:>9.4f}"
              f" {e['bending']:>9.4f}   ({f[0]:.4f}, {f[1]:.4f}), "
              f"|F| {np.linalg.norm(f):.4f}{extra}")
    print(f"centreline distance point vs line clamps: max {d['max']:.3f} (loop "
          f"{tuple(d['argmax_loop'])}), RMS {d['rms']:.3f}  [loop length 10, wale spacing 2.24]")


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--grip", type=int, default=2,
                    help="points per rigid jaw along the bottom edge (1 or 2; default 2)")
    ap.add_argument("--out", type=Path, default=Path("results"), help="results root (results)")
    args = ap.parse_args(argv)
    if not 1 <= args.grip <= 2:
        # with 3 the jaws share loop (1, 3): its start held, its H moved 15 units, farther than
        # the yarn between them (s_H = 6.4) reaches, so the problem is infeasible
        ap.error("--grip must be 1 or 2 on the 5 x 5 fabric (3 is infeasible)")
    return args


def main(argv: Sequence[str] | None = None) -> dict[str, Any]:
    """Solve both, draw them, write comparison.json and print the comparison."""
    args = parse_args(argv)
    doc = point_doc()
    point = solve_problem(parse_problem(doc, "wada_fig7"))
    ldoc = line_doc(doc, args.grip)
    line = solve_problem(parse_problem(ldoc, "wada_fig7_line"))
    out = args.out / STUDY
    png = plot(out / f"{STUDY}.png", point, line, natural_centrelines(point.problem, 81), args.grip)
    comp = compare(point, line)
    comp["grip"] = args.grip
    comp["line_problem"] = ldoc
    write_json(out / "comparison.json", comp)
    print_comparison(comp)
    print(f"wrote {png}, {out / 'comparison.json'}")
    return comp


if __name__ == "__main__":
    main(sys.argv[1:])
