"""What ``knit-nlp solve`` prints for jacquard problems."""
from __future__ import annotations

from pathlib import Path

from .result import JacquardResult


def solve_summary(r: JacquardResult, paths: list[Path]) -> str:
    """A few lines for the terminal."""
    p = r.problem
    skew = r.wale_skew()["mean_angle_deg"]
    count = f"{r.steps} steps" if r.solver == "explicit" else f"{r.iterations} iterations"
    return "\n".join([
        f"{p.name}: jacquard {p.wales} x {p.courses}, {r.network.springs.n} springs, "
        f"solver {r.solver}: {'converged' if r.success else 'NOT converged'} ({r.message})",
        f"  {count}, {r.timings['build_s'] + r.timings['solve_s']:.3g} s; "
        f"residual force {r.residual_force:.3g}; "
        f"zero-energy modes {r.network.zero_modes}",
        f"  max |dx| {abs(r.displacement()[:, 0]).max() / p.w:.4g} w; wale skew "
        f"{skew.min():+.3g}..{skew.max():+.3g} deg; max stretch {r.max_stretch():.4f} "
        f"(limit {p.lambda_max:g})",
        *(f"  pull {q['edge']} by {_vec(q['displacement'])} mm: reaction {_vec(q['reaction'])}"
          for q in r.pulls()),
        "  wrote " + ", ".join(str(x) for x in paths),
    ])


def _vec(v) -> str:
    return "(" + ", ".join(f"{c:.4g}" for c in v) + ")"
