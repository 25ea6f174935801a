"""The natural 3-D loop of the acrylic stockinette (docs/weft3d.md, "Natural 3-D shape").

    python scripts/figure_natural3d.py [OUT.png]     (default docs/natural3d.png)

Two courses of two loops, L = 11.28 mm, r = 0.74 mm, q = 4: the plan view with the paper's
natural loop for comparison, the designed crossings of the projections marked by which yarn
is over and the two wraps (the interlock contacts) marked with their natural separation h0;
and the side view (z against the material coordinate s) of one loop.
"""
from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from knit_nlp.weft.model.problem import parse_problem  # noqa: E402
from knit_nlp.weft.model.spatial.natural3d import PAIRS, WRAPS  # noqa: E402

DOC = {"fabric": {"courses": 2, "wales": 2}, "loop": {"length": 11.28},
       "yarn": {"radius": 0.74, "geometry": "3d", "elevation_modes": 4}}


def main(out: Path) -> None:
    pr = parse_problem(DOC, "natural3d.toml")
    sh = pr.yarn.natural3d
    s = np.linspace(0.0, sh.length, 400)
    xyz, flat = sh.xyz(s), pr.natural.xy(s)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 5))
    colours = ("tab:blue", "tab:orange")
    for i in range(2):
        for j in range(2):
            start = sh.starts(2, 2)[i, j]
            label = f"course {i + 1} (3-D, projected)" if j == 0 else None
            ax1.plot(start[0] + xyz[:, 0], start[1] + xyz[:, 1], color=colours[i], lw=2,
                     label=label)
            ax1.plot(start[0] + flat[:, 0], start[1] + flat[:, 1], color="grey", lw=0.8,
                     ls="--", label="the paper's natural loop" if (i, j) == (0, 0) else None)
    up = sh.xyz(sh.cross_upper) + [0.0, sh.course_spacing, 0.0]
    for k, (u, lo, order) in enumerate(PAIRS):
        marker = "^" if order > 0 else "v"
        ax1.plot(*up[k, :2], marker, color="k", ms=9,
                 label=("crossing, upper course over" if order > 0 else
                        "crossing, upper course under") if k < 2 else None)
        ax1.annotate(f"{u}/{lo}", up[k, :2], textcoords="offset points", xytext=(6, 4))
    wu = sh.xyz(sh.s_upper) + [0.0, sh.course_spacing, 0.0]
    wl = sh.xyz(sh.s_lower)
    for k, name in enumerate(WRAPS):
        ax1.plot(*np.stack([wu[k, :2], wl[k, :2]]).T, "-o", color="tab:red", ms=5,
                 label="wrap contact: closest points" if k == 0 else None)
        ax1.annotate(f"h0 = {sh.h0[k]:.2f}", wl[k, :2], textcoords="offset points",
                     xytext=(4, -14), color="tab:red", fontsize=8)
    ax1.set_aspect("equal")
    ax1.set_xlabel("x (mm)")
    ax1.set_ylabel("y (mm)")
    ax1.set_title(f"plan view: lattice {sh.wale_spacing:.2f} x {sh.course_spacing:.2f} mm "
                  f"(projection RMS {sh.projection_rms:.2f} mm from the paper's loop)", fontsize=9)
    ax1.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2)
    ax2.plot(s, xyz[:, 2], color="k", lw=2, label="z(s), one loop")
    for k, (u, lo, order) in enumerate(PAIRS):
        su, sl = sh.cross_upper[k], sh.cross_lower[k]
        ax2.plot(su, xyz[np.searchsorted(s, su), 2], "^" if order > 0 else "v",
                 color=colours[1], ms=9, label="crossing, as the upper loop" if k == 0 else None)
        ax2.plot(sl, xyz[np.searchsorted(s, sl), 2], "o", color=colours[0], ms=7,
                 label="crossing, as the lower loop" if k == 0 else None)
        ax2.annotate(u, (su, xyz[np.searchsorted(s, su), 2]), textcoords="offset points",
                     xytext=(5, -12))
        ax2.annotate(lo, (sl, xyz[np.searchsorted(s, sl), 2]), textcoords="offset points",
                     xytext=(5, 5))
    ax2.set_xlabel("material coordinate s (mm)")
    ax2.set_ylabel("z (mm), +z = technical face")
    ax2.set_title(f"side view: legs in front, head and sinker loops behind (2r = {2 * sh.radius:.2f} mm)")
    ax2.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=3)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/natural3d.png"))
