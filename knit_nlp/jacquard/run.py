"""``knit-nlp solve`` for jacquard problems: validate, solve, write JSON + picture, summarise."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ProblemError, quoted
from ..jsonio import write_json
from .explicit import solve_explicit
from .problem import JacquardProblem, parse_problem
from .render import render
from .result import JacquardResult
from .static import solve_static

SOLVERS = ("static", "explicit")
ZERO_MODE_TREATMENT = ("each floating component of the spring graph has its centroid held at "
                       "its natural centroid (what the explicit dynamics conserves)")


def solve(problem: JacquardProblem, solver: str | None = None) -> JacquardResult:
    """Solve with ``solver`` (``static`` | ``explicit``), default the problem's own method."""
    method = problem.solver.method if solver is None else solver
    if method not in SOLVERS:
        raise ProblemError(problem.source or "<api>", "solver", "method",
                           f"must be one of {', '.join(SOLVERS)}; got {quoted(method)}")
    if method == "explicit":
        return solve_explicit(problem)
    return solve_static(problem)


def result_dict(r: JacquardResult) -> dict[str, Any]:
    """The result JSON (docs/jacquard.md, "Result JSON")."""
    p, net = r.problem, r.network
    skew = r.wale_skew()
    return {
        "problem": p.name, "model": "jacquard", "solver": r.solver,
        "success": r.success, "status": r.status,
        "residual_force": r.residual_force,
        "steps": r.steps, "iterations": r.iterations, "constraints": r.constraints,
        "timings": r.timings,
        "energy": r.energy,
        "max_stretch": r.max_stretch(), "lambda_max": p.lambda_max,
        "min_order_gap": r.min_order_gap(),
        "zero_modes": {"count": net.zero_modes, "floating_components": len(net.floating),
                       "treatment": ZERO_MODE_TREATMENT if r.solver == "static" else
                       "none needed: floating components keep their momentum (zero)"},
        "wales": p.wales, "courses": p.courses, "w_mm": p.w, "h_mm": p.h,
        "boundary": p.boundary, "n_particles": p.n_particles, "n_springs": net.springs.n,
        "particles": {"index": "j*M + i", "natural": net.natural, "final": r.positions},
        "skew": skew,
    }


def summary(r: JacquardResult, json_path: Path) -> str:
    """A few lines for the terminal."""
    p = r.problem
    skew = r.wale_skew()["mean_angle_deg"]
    count = f"{r.steps} steps" if r.solver == "explicit" else f"{r.iterations} IPOPT iterations"
    return "\n".join([
        f"{p.name}: jacquard {p.wales} x {p.courses}, {r.network.springs.n} springs, "
        f"solver {r.solver}: {'converged' if r.success else 'NOT converged'} ({r.status})",
        f"  {count}, {sum(r.timings.values()):.3g} s; residual force {r.residual_force:.3g}; "
        f"zero-energy modes {r.network.zero_modes}",
        f"  max |dx| {abs(r.displacement()[:, 0]).max() / p.w:.4g} w; wale skew "
        f"{skew.min():+.3g}..{skew.max():+.3g} deg; max stretch {r.max_stretch():.4f} "
        f"(limit {p.lambda_max:g})",
        f"  wrote {json_path}",
    ])


def solve_file(path: Path, doc: dict, out_dir: Path, *, solver: str | None = None,
               svg: bool = False) -> int:
    """The CLI entry: 0 on success, 1 if the solver did not converge (results still written)."""
    problem = parse_problem(doc, path)
    result = solve(problem, solver)
    with np.errstate(over="ignore", invalid="ignore"):   # a diverged run: NaN summaries (null)
        json_path = write_json(Path(out_dir) / f"{problem.name}.jacquard.json",
                               result_dict(result))
        render(problem, result.network.natural, result.positions,
               Path(out_dir) / f"{problem.name}.jacquard.png", result.solver, svg=svg)
        print(summary(result, json_path))
    return 0 if result.success else 1
