"""Entry points behind ``knit-nlp solve`` and ``knit-nlp compare`` for weft problems."""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..jsonio import write_json
from .adaptive import solve_adaptive
from .condensed import CondensedNLP, build_condensed
from .nlp import WeftNLP, build_nlp
from .plot import plot_overlay, plot_solution
from .problem import WeftProblem, parse_problem
from .results import (natural_centrelines, result_dict, solution_centrelines, write_arrays,
                      write_result)
from .solve import SolveReport, WeftSolver, solve


@dataclass
class Solved:
    """One solved model: the NLP, the solver report and the result JSON."""

    wnlp: WeftNLP | CondensedNLP
    report: SolveReport
    result: dict[str, Any]

    def lines(self, samples: int = 61) -> np.ndarray:
        """Sampled centrelines (m, n, samples, 2) of the solution."""
        return solution_centrelines(self.wnlp, self.report.x, samples)


def solve_problem(pr: WeftProblem, reduced: bool = False, continuation: int | None = None,
                  start: Solved | None = None, extra: dict[str, Any] | None = None) -> Solved:
    """Build and solve one model of a problem, from the natural state or from another solved
    model's loops (lifted into this one); time the build (assembly + solver setup). The reduced
    model is the condensed one (``condensed``), adaptive when the problem asks for it."""
    if reduced and start is None and pr.reduction is not None and pr.reduction.adaptive:
        run = solve_adaptive(pr, continuation=continuation)
        viol = WeftSolver(run.cnlp).violation(run.report.x, run.cnlp.p0)
        adaptive = {"adaptive": {"steps": [st.as_dict() for st in run.steps],
                                 "estimate": run.steps[-1].estimate}}
        return Solved(run.cnlp, run.report, result_dict(run.cnlp, run.report, viol, run.build_s,
                                                        {**adaptive, **(extra or {})}))
    t0 = time.perf_counter()
    wnlp = build_condensed(pr) if reduced else build_nlp(pr)
    solver = WeftSolver(wnlp)
    build_s = time.perf_counter() - t0
    x0 = None if start is None else wnlp.lift(start.wnlp.coefficients(start.report.x),
                                               start.wnlp.starts(start.report.x))
    rep = solve(wnlp, solver, x0=x0, continuation=continuation)
    viol = solver.violation(rep.x, wnlp.p0)
    return Solved(wnlp, rep, result_dict(wnlp, rep, viol, build_s, extra))


def solve_warm_from_reduced(pr: WeftProblem, continuation: int | None = None) -> tuple[Solved, Solved]:
    """Solve the reduced model, lift its solution, and start the full model from it."""
    red = solve_problem(pr, reduced=True, continuation=continuation)
    warm = {"warm_start": {"from": "reduced", "reduced_success": red.report.success,
                           "reduced_iterations": red.report.iterations,
                           "reduced_solve_s": red.report.solve_s}}
    return red, solve_problem(pr, continuation=continuation, start=red, extra=warm)


def _summary(s: Solved, paths: list[Path]) -> str:
    r = s.result
    e = r["energy"]
    lines = [f"{r['problem']} ({r['model']}): {r['status']} in {r['iterations']} iterations"
             f" (build {r['timings']['build_s']:.2f} s, solve {r['timings']['solve_s']:.2f} s)",
             f"  energy {e['total']:.6g} = spring {e['spring']:.6g} + bending {e['bending']:.6g};"
             f" load work {e['load_work']:.6g}",
             f"  {r['n_parameters']} parameters, {r['n_variables']} variables, "
             f"{r['n_constraints']} constraints, max violation {r['max_constraint_violation']:.2e}"]
    for c in r["clamps"]:
        lines.append(f"  clamp {c['loop']} {c['point']}: reaction "
                     f"({c['reaction'][0]:.4g}, {c['reaction'][1]:.4g})")
    for k, rc in enumerate(r["rigid_clamps"]):
        lines.append(f"  rigid clamp {k + 1} ({len(rc['points'])} points): force "
                     f"({rc['force'][0]:.4g}, {rc['force'][1]:.4g}), moment {rc['moment']:.4g}")
    if not r["success"]:
        lines.append("  NOT CONVERGED: " + "; ".join(r["attempts"]))
    lines.append("  wrote " + ", ".join(str(p) for p in paths))
    return "\n".join(lines)


def write_outputs(out: Path, s: Solved) -> list[Path]:
    """JSON, NPZ and PNG of one solved model."""
    pr = s.wnlp.problem
    stem = out / f"{pr.name}.{s.result['model']}"
    js = write_result(out, s.wnlp, s.result)
    natural, deformed = natural_centrelines(pr), s.lines()
    npz = write_arrays(stem.parent / f"{stem.name}.npz", s.wnlp, s.report.x, natural, deformed)
    title = (f"{pr.name} ({s.result['model']}): E = {s.result['energy']['total']:.4g}, "
             f"{'converged' if s.report.success else 'NOT CONVERGED'}")
    held = s.result["clamps"] + [pt for rc in s.result["rigid_clamps"] for pt in rc["points"]]
    png = plot_solution(stem.parent / f"{stem.name}.png", natural, deformed, held, title)
    return [js, npz, png]


def solve_file(path: Path, doc: dict[str, Any], out: Path, reduced: bool | None = None,
               continuation: int | None = None, warm_from_reduced: bool = False) -> int:
    """``knit-nlp solve`` for a weft problem; exit code 0 converged, 1 not converged."""
    pr = parse_problem(path, doc)
    use_reduced = (pr.reduction is not None) if reduced is None else reduced
    if warm_from_reduced and use_reduced:
        from ..errors import ProblemError
        raise ProblemError(path, "", "", "--warm-from-reduced starts the full model: add --full")
    if warm_from_reduced:
        _, solved = solve_warm_from_reduced(pr, continuation)
    else:
        solved = solve_problem(pr, reduced=use_reduced, continuation=continuation)
    print(_summary(solved, write_outputs(out, solved)))
    return 0 if solved.report.success else 1


def compare(pr: WeftProblem, samples: int = 61) -> dict[str, Any]:
    """Full and reduced models side by side; the full model also warm-started from the reduced."""
    full = solve_problem(pr)
    red, warm = solve_warm_from_reduced(pr)
    dist = np.linalg.norm(full.lines(samples) - red.lines(samples), axis=-1)
    models = {}
    for key, s in (("full", full), ("reduced", red), ("full_warm_from_reduced", warm)):
        r = s.result
        models[key] = {k: r[k] for k in ("success", "status", "n_parameters", "n_variables",
                                         "n_constraints", "iterations", "energy", "timings")}
    return {"problem": pr.name, "models": models,
            "distance": {"max": float(dist.max()), "rms": float(np.sqrt(np.mean(dist ** 2))),
                         "samples_per_loop": samples},
            "energy_gap": red.result["energy"]["total"] - full.result["energy"]["total"],
            **({"adaptive": {"estimate": red.result["adaptive"]["estimate"],
                             "true_rms": float(np.sqrt(np.mean(dist ** 2))),
                             "steps": red.result["adaptive"]["steps"]}}
               if "adaptive" in red.result else {}),
            "speedup_reduced": (full.result["timings"]["build_s"] + full.result["timings"]["solve_s"])
            / (red.result["timings"]["build_s"] + red.result["timings"]["solve_s"]),
            "_solved": (full, red, warm)}


def compare_file(path: Path, doc: dict[str, Any], out: Path) -> int:
    """``knit-nlp compare``: write ``<problem>.compare.json`` and an overlay PNG."""
    pr = parse_problem(path, doc)
    cmp = compare(pr)
    full, red, _ = cmp.pop("_solved")
    js = write_json(out / f"{pr.name}.compare.json", cmp)
    png = plot_overlay(out / f"{pr.name}.compare.png", full.lines(), red.lines(),
                       f"{pr.name}: full (black) vs reduced, max distance "
                       f"{cmp['distance']['max']:.3g}")
    m = cmp["models"]
    print(f"{pr.name}: full vs reduced")
    for key in m:
        r = m[key]
        print(f"  {key:<24} {r['status']:<18} params {r['n_parameters']:>6}  energy "
              f"{r['energy']['total']:.6g}  iterations {r['iterations']:>4}  build+solve "
              f"{r['timings']['build_s'] + r['timings']['solve_s']:.3f} s")
    print(f"  centreline distance: max {cmp['distance']['max']:.4g}, rms {cmp['distance']['rms']:.4g}")
    speed = cmp["speedup_reduced"]
    pace = f"{speed:.1f}x faster" if speed >= 1 else f"{1 / speed:.1f}x slower"
    print(f"  reduced is {pace} than full (build + solve); energy gap (reduced - full) "
          f"{cmp['energy_gap']:.4g}")
    print(f"  wrote {js}, {png}")
    ok = all(r["success"] for r in m.values())
    return 0 if ok else 1
