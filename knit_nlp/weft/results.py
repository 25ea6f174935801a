"""Reading a solved NLP: the contract's result JSON and the sampled centrelines (NPZ)."""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..jsonio import write_json
from .basis import n_coeffs, phi
from .nlp import WeftNLP
from .problem import WeftProblem
from .quadrature import positions
from .solve import SolveReport


def clamp_reactions(wnlp: WeftNLP, lam_g: np.ndarray) -> list[tuple[np.ndarray, float | None]]:
    """(force, moment) the clamps apply to the fabric: minus the constraint multipliers.

    CasADi's multipliers make ∇f + Jᵀλ = 0 with rows g = P − target, so the clamp's force on
    the fabric, which balances the elastic force −∂U/∂P, is −λ.
    """
    out = []
    for q, c in enumerate(wnlp.problem.clamps):
        force = np.zeros(2)
        name = f"clamp{q}_pos"
        if name in wnlp.g.blocks:
            force[[d for d in range(2) if c.fix[d]]] = -lam_g[wnlp.g.slice(name)]
        moment = None
        if c.angle is not None:
            moment = float(-lam_g[wnlp.g.slice(f"clamp{q}_angle")][0])
        out.append((force, moment))
    return out


def rigid_clamp_results(wnlp: WeftNLP, x: np.ndarray, lam_g: np.ndarray,
                        p: np.ndarray) -> list[dict[str, Any]]:
    """Per rigid clamp: its points' positions and reactions, the total force, and the moment of
    the reactions about the moved centre."""
    out = []
    pc = wnlp.special_positions(x)
    par = wnlp.p.get(p, "rigid")
    for q, (rc, idx) in enumerate(zip(wnlp.problem.rigid_clamps, wnlp.rigid_points)):
        forces = -lam_g[wnlp.g.slice(f"rigid{q}")].reshape(2, -1, order="F")
        pos = pc[:, idx]
        centre = rc.centre + par[:2, q]
        arm = pos - centre[:, None]
        out.append({"points": [{"loop": list(lp), "point": label, "position": pos[:, k].tolist(),
                                "reaction": forces[:, k].tolist()}
                               for k, (lp, label, _) in enumerate(rc.points)],
                    "translation": par[:2, q].tolist(), "rotation": float(par[2, q]),
                    "centre": rc.centre.tolist(), "force": forces.sum(axis=1).tolist(),
                    "moment": float(np.sum(arm[0] * forces[1] - arm[1] * forces[0]))})
    return out


def result_dict(wnlp: WeftNLP, rep: SolveReport, violation: float, build_s: float,
                extra: dict[str, Any] | None = None, p: np.ndarray | None = None) -> dict[str, Any]:
    """The contract's result JSON (spec/problem_files.md) plus documented extensions, for a
    solution at parameters ``p`` (the problem's own by default)."""
    pr = wnlp.problem
    p = wnlp.p0 if p is None else p
    spring, bending, work = (float(v) for v in wnlp.energy(rep.x, p))
    coeffs, starts = wnlp.coefficients(rep.x), wnlp.starts(rep.x)
    pc = wnlp.special_positions(rep.x)
    clamps = []
    targets = wnlp.p.get(p, "targets")
    for q_c, (c, q, (force, moment)) in enumerate(zip(pr.clamps, wnlp.clamp_points,
                                                       clamp_reactions(wnlp, rep.lam_g))):
        entry: dict[str, Any] = {"loop": list(c.loop), "point": c.point,
                                 "position": pc[:, q].tolist(), "reaction": force.tolist(),
                                 "target": targets[:, q_c].tolist(),
                                 "fix": [d for d, f in zip("xy", c.fix) if f]}
        if c.angle is not None:
            k = (c.loop[0] - 1, c.loop[1] - 1)
            entry["angle"] = float(phi(c.s, pr.L, pr.t)[0] @ coeffs[k])
            entry["reaction_moment"] = moment
        clamps.append(entry)
    result = {
        "problem": pr.name, "model": "reduced" if wnlp.reduced else "full",
        "success": rep.success, "status": rep.status,
        "energy": {"total": spring + bending, "spring": spring, "bending": bending,
                   "load_work": work},
        "n_parameters": wnlp.n_parameters, "n_variables": wnlp.n_variables,
        "n_constraints": wnlp.n_constraints, "iterations": rep.iterations,
        "max_constraint_violation": violation,
        "timings": {"build_s": build_s, "solve_s": rep.solve_s,
                    "profile": {k.removeprefix("t_wall_"): v for k, v in sorted(rep.stats.items())}},
        "continuation_steps": rep.continuation_steps, "attempts": rep.attempts,
        "clamps": clamps,
        "loads": [{"loop": list(ld.loop), "point": ld.point, "force": ld.force.tolist(),
                   "moment": ld.moment, "position": pc[:, q].tolist()}
                  for ld, q in zip(pr.loads, wnlp.load_points)],
        "rigid_clamps": rigid_clamp_results(wnlp, rep.x, rep.lam_g, p),
        "loops": {"course_starts": starts[:, 0].tolist(), "coefficients": coeffs.tolist()},
    }
    result.update(extra or {})
    return result


def centrelines(coeffs: np.ndarray, starts: np.ndarray, L: float, t: int,
                samples: int = 61) -> tuple[np.ndarray, np.ndarray]:
    """Sampled centrelines (m, n, samples, 2) of every loop and the s-values used."""
    m, n = coeffs.shape[:2]
    s = np.linspace(0.0, L, samples)
    disp = positions(coeffs.reshape(m * n, n_coeffs(t)), s, L, t).reshape(m, n, samples, 2)
    return disp + starts[:, :, None, :], s


def natural_centrelines(pr: WeftProblem, samples: int = 61) -> np.ndarray:
    """Sampled centrelines (m, n, samples, 2) of the natural configuration."""
    coeffs = np.broadcast_to(pr.natural.coeffs, (pr.courses, pr.wales, n_coeffs(pr.t)))
    return centrelines(coeffs, pr.natural_starts(), pr.L, pr.t, samples)[0]


def solution_centrelines(wnlp: WeftNLP, x: np.ndarray, samples: int = 61) -> np.ndarray:
    """Sampled centrelines (m, n, samples, 2) of a solution vector."""
    pr = wnlp.problem
    return centrelines(wnlp.coefficients(x), wnlp.starts(x), pr.L, pr.t, samples)[0]


def write_arrays(path: Path, wnlp: WeftNLP, x: np.ndarray, natural: np.ndarray,
                 deformed: np.ndarray) -> Path:
    """NPZ beside the JSON: s, natural and deformed centrelines, coefficients, starts."""
    s = np.linspace(0.0, wnlp.problem.L, deformed.shape[2])
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, s=s, natural=natural, deformed=deformed,
                        coefficients=wnlp.coefficients(x), starts=wnlp.starts(x))
    return path


def write_result(out_dir: Path, wnlp: WeftNLP, result: dict[str, Any]) -> Path:
    """``DIR/<problem>.<model>.json``."""
    return write_json(out_dir / f"{wnlp.problem.name}.{result['model']}.json", result)
