"""Make problems/fit_example/: synthetic observations and a synthetic photograph.

The three load cases are solved with a KNOWN material (k_a = 1.0, k_b = 0.01, R_f = 1.0, the
paper's values; the case files hold a different starting guess), the H points of every other
loop are observed with Gaussian noise of standard deviation 0.02 (seed 10), and the first case
is rendered as a "photograph" under a known similarity (scale, rotation, shift; y down), with the
exact pixels of four material points written to photo_matches.txt.

    python scripts/make_fit_example.py            # rewrites the files in problems/fit_example/
"""
from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from knit_nlp.weft.solving.solve import Equilibrium  # noqa: E402
from knit_nlp.weft.inverse.overlay import Similarity  # noqa: E402
from knit_nlp.weft.inverse.points import point_function  # noqa: E402
from knit_nlp.weft.model.problem import load_problem  # noqa: E402

TRUTH = {"k_a": 1.0, "k_b": 0.01, "R_f": 1.0}
NOISE = 0.02
SEED = 10
CASES = ("fit_course_pull", "fit_wale_pull", "fit_shear")
OBSERVED = [(i, j) for i in range(2, 11, 2) for j in range(2, 11, 2)]
PHOTO = Similarity(a=18.0 * np.exp(1j * np.radians(8.0)), b=complex(120.0, -560.0))
PHOTO_SIZE = (800, 700)               # width, height in pixels
MATCHES = [((1, 1), "start"), ((10, 1), "H"), ((1, 10), "H"), ((10, 10), "H")]


def true_solution(problem_path: Path):
    """The case solved with the known material values."""
    eq = Equilibrium(load_problem(problem_path))
    p = eq.wnlp.p0.copy()
    for name, v in TRUTH.items():
        eq.wnlp.p.put(p, name, v)
    rep = eq.solve(p)
    assert rep.success, rep.status
    return eq, rep.x


def observe(folder: Path, rng: np.random.Generator) -> list[str]:
    rows = []
    for case in CASES:
        eq, x = true_solution(folder / f"{case}.toml")
        s_h = eq.problem.crossings.s["H"]
        P = np.asarray(point_function(eq.wnlp, [(lp, s_h) for lp in OBSERVED])(x)).T
        P = P + rng.normal(0.0, NOISE, P.shape)
        rows += [f"{case},{i},{j},H,{xy[0]:.6f},{xy[1]:.6f}" for (i, j), xy in zip(OBSERVED, P)]
    return rows


def photograph(folder: Path) -> list[str]:
    """Render the first case (true material) as a picture; return the exact match lines."""
    eq, x = true_solution(folder / f"{CASES[0]}.toml")
    lines = PHOTO.to_pixels(eq.wnlp.centrelines(x, 121))
    w, h = PHOTO_SIZE
    fig = plt.figure(figsize=(w / 100, h / 100), dpi=100)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_facecolor("#d9cdb8")
    for course in lines:
        poly = np.concatenate(list(course))
        ax.plot(poly[:, 0], poly[:, 1], color="#3b2f4a", lw=4.0, solid_capstyle="round")
    ax.set_xlim(-0.5, w - 0.5)
    ax.set_ylim(h - 0.5, -0.5)
    ax.axis("off")
    fig.savefig(folder / "photo.png", dpi=100, facecolor="#d9cdb8")
    plt.close(fig)
    pr = eq.problem
    pts = point_function(eq.wnlp, [(lp, 0.0 if lab == "start" else pr.crossings.s[lab]) for lp, lab in MATCHES])
    px = PHOTO.to_pixels(np.asarray(pts(x)).T)
    return [f"--match {lp[0]},{lp[1]},{lab}={u:.4f},{v:.4f}" for (lp, lab), (u, v) in zip(MATCHES, px)]


def main() -> None:
    folder = ROOT / "problems" / "fit_example"
    rng = np.random.default_rng(SEED)
    header = ["# Synthetic observations, NOT measurements: made by scripts/make_fit_example.py from",
              f"# the three cases solved with the known material k_a = {TRUTH['k_a']}, k_b = {TRUTH['k_b']},"
              f" R_f = {TRUTH['R_f']},",
              f"# then Gaussian noise of standard deviation {NOISE} (seed {SEED}) added to every coordinate.",
              "case,course,wale,point,x,y"]
    (folder / "observations.csv").write_text("\n".join(header + observe(folder, rng)) + "\n")
    matches = photograph(folder)
    t = PHOTO
    (folder / "photo_matches.txt").write_text(
        "# photo.png is synthetic: fit_course_pull solved with the known material, drawn under the\n"
        f"# similarity scale {t.scale:g} px/unit, rotation {np.degrees(t.rotation):g} deg, shift "
        f"({t.b.real:g}, {-t.b.imag:g}) px (pixel = model mapped, y down).\n"
        "# Exact pixels of four material points, as overlay arguments:\n" + "\n".join(matches) + "\n")
    print(f"wrote {folder / 'observations.csv'}, photo.png, photo_matches.txt")


if __name__ == "__main__":
    main()
