"""A solved weft model as a typed result (the contract of :mod:`knit_nlp.outcome`): energies,
clamp reactions (``reactions``), loops, the result JSON (``to_json``, its only producer) and the
files ``knit-nlp solve`` writes (``save``: the writing and drawing are the output modules'
``plot``, ``path`` and ``export``).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ...jsonio import write_json, write_npz
from ...outcome import Energy, Outcome, describe
from ...provenance import source_record
from ..model.basis import phi
from ..model.centrelines import SAMPLES, natural_centrelines
from ..model.params import WeftParams
from ..model.problem import WeftProblem
from ..solving.blocks import AdaptiveBlock, ContactBlock, WarmStart
from ..solving.solve import Solution, SolveReport
from ..transcription.protocol import WeftNLP
from .export import write_centreline_csv, write_centreline_svg
from .reactions import ClampReaction, LoadResult, RigidClampReaction


@dataclass(repr=False)
class WeftResult(Outcome):
    """A solved weft model (full or reduced) at parameters ``params``.

    The contract (``success``, ``status``: IPOPT's return status, ``message``, ``nit``,
    ``energy``, ``to_json``, ``save``), and SciPy's ``x`` (the NLP's solution vector) and ``fun``
    (the minimised ``total − load_work``). ``model`` is the solved model's name, ``"full"`` or
    ``"reduced"``, as in the JSON and the file names; ``problem.model`` is ``"weft"``.
    """

    nlp: WeftNLP
    report: SolveReport
    params: WeftParams
    build_s: float
    violation: float
    contact: ContactBlock | None = None
    adaptive: AdaptiveBlock | None = None
    warm_start: WarmStart | None = None

    @classmethod
    def of(cls, solution: Solution) -> "WeftResult":
        """The typed result of a forward solve (``Equilibrium.solve``), with its variant's
        blocks (``contact``, ``adaptive``: ``solving.blocks``)."""
        return cls(solution.nlp, solution, solution.params, solution.build_s,
                   solution.violation, solution.contact_block, solution.adaptive)

    @property
    def problem(self) -> WeftProblem:
        return self.nlp.problem

    @property
    def model(self) -> str:
        return self.nlp.model

    @property
    def success(self) -> bool:      # type: ignore[override]
        return self.report.success

    @property
    def status(self) -> str:        # type: ignore[override]
        return self.report.status

    @property
    def message(self) -> str:
        return self.report.detail or describe(self.status, self.problem.solver.max_time)

    @property
    def iterations(self) -> int:
        return self.report.iterations

    @property
    def x(self) -> np.ndarray:
        return self.report.x

    @property
    def fun(self) -> float:
        return self.report.objective

    @cached_property
    def energy(self) -> Energy:
        spring, bending, work = self.nlp.energy(self.x, self.params.vector())
        return Energy(spring + bending, spring, bending, work)

    @property
    def timings(self) -> dict[str, Any]:
        return {"build_s": self.build_s, "solve_s": self.report.solve_s,
                "profile": {k.removeprefix("t_wall_"): v
                            for k, v in sorted(self.report.stats.items())}}

    @property
    def coefficients(self) -> np.ndarray:
        """Loop coefficients (m, n, 2t+2)."""
        return self.nlp.coefficients(self.x)

    @property
    def starts(self) -> np.ndarray:
        """Loop start points (m, n, 2)."""
        return self.nlp.starts(self.x)

    def _points(self) -> np.ndarray:
        """Positions (2, k) of the lifted clamped and loaded points."""
        return self.nlp.special_positions(self.x)

    @cached_property
    def clamps(self) -> list[ClampReaction]:
        pr, lam, pc, table = self.problem, self.report.lam_g, self._points(), self.nlp.clamp_table
        out = []
        for q, (c, sp, rows) in enumerate(zip(pr.clamps, table.clamp_points, table.clamp_rows)):
            force = np.zeros(2)
            if rows.position is not None:
                force[list(rows.dims)] = -lam[rows.position]
            angle = moment = None
            if rows.angle is not None:
                k = (c.loop[0] - 1, c.loop[1] - 1)
                angle = float(phi(c.s, pr.L, pr.t)[0] @ self.coefficients[k])
                moment = float(-lam[rows.angle][0])
            out.append(ClampReaction(q + 1, c.loop, c.point, pc[:, sp].copy(),
                                     self.params.targets[q].copy(),
                                     tuple(d for d, f in zip("xy", c.fix) if f), force,
                                     angle, moment, c.table if c.expanded else None,
                                     c.table))
        return out

    @cached_property
    def rigid_clamps(self) -> list[RigidClampReaction]:
        pc, out, table = self._points(), [], self.nlp.clamp_table
        for q, (rc, idx, rows) in enumerate(zip(self.problem.rigid_clamps, table.rigid_points,
                                                table.rigid_rows)):
            forces = -self.report.lam_g[rows].reshape(2, -1, order="F")
            motion = self.params.rigid[q]
            out.append(RigidClampReaction(q + 1, tuple((lp, label) for lp, label, _ in rc.points),
                                          pc[:, idx].T.copy(), forces.T.copy(), motion[:2].copy(),
                                          float(motion[2]), rc.centre.copy()))
        return out

    @cached_property
    def loads(self) -> list[LoadResult]:
        pc, table = self._points(), self.nlp.clamp_table
        return [LoadResult(q + 1, ld.loop, ld.point, self.params.forces[q].copy(),
                           float(self.params.moments[q]), pc[:, sp].copy(),
                           ld.table if ld.expanded else None)
                for q, (ld, sp) in enumerate(zip(self.problem.loads, table.load_points))]

    def loading_path(self) -> list[tuple[float, "WeftResult"]]:
        """The continuation steps reached, each as (load factor τ, the result at parameters
        natural + τ·(these − natural)); empty after a direct solve. The steps' own iteration
        counts and timings are not kept (they are summed into this result's)."""
        p_nat = WeftParams.natural(self.problem).vector()
        dp = self.params.vector() - p_nat
        return [(tau, WeftResult(self.nlp, SolveReport(True, "Solve_Succeeded", x, lam, np.nan, 0,
                                                       0.0),
                                 WeftParams.from_vector(self.problem, p_nat + tau * dp), 0.0,
                                 np.nan))
                for tau, x, lam in self.report.path]

    def centrelines(self, samples: int = SAMPLES) -> np.ndarray:
        """Sampled deformed centrelines (m, n, samples, 2)."""
        return self.nlp.centrelines(self.x, samples)

    def natural_centrelines(self, samples: int = SAMPLES) -> np.ndarray:
        """Sampled natural centrelines (m, n, samples, 2)."""
        return natural_centrelines(self.problem, samples)

    @cached_property
    def checked(self) -> dict[str, Any]:
        """The answer's own check (``output.check``: new crossings against the natural fabric,
        with a radius gaps below their requirement), made once: the result JSON's ``check``
        block, which the summary and the picture's title also state."""
        from ..model.spatial.state import spatial_samples     # only when told
        from .check import own_check, spatial_own_check
        yarn = self.problem.yarn
        if yarn is not None and yarn.spatial:    # all pairs of pieces in 3-D (docs/weft3d.md)
            return spatial_own_check(self.problem, self.nlp.centrelines3d(
                self.x, spatial_samples(self.problem)))
        return own_check(self.problem, self.coefficients, self.starts)[1]

    @cached_property
    def spatial(self) -> dict[str, Any] | None:
        """The 3-D model's ``spatial`` block (docs/weft3d.md), None for the planar models."""
        spatial = getattr(self.nlp, "spatial_block", None)
        if spatial is None:
            return None
        block = spatial(self.x, self.params.vector(), self.report.friction)
        if getattr(self.nlp, "neighbours", None) is not None:      # rounds3d: other contacts
            block["other_contacts"] = {"listed_pairs": len(self.nlp.neighbours),
                                       "rounds": list(self.nlp.rounds)}
        return block

    def _save_3d(self, stem: Path, deformed: np.ndarray) -> list[Path]:
        """The 3-D model's yarn as tubes of its radius: ``.3d.png`` (oblique and side views,
        the designed crossings' contact points marked), ``.yarn.vtu`` (ParaView) and
        ``.tube.ply`` (Blender), docs/weft3d.md."""
        from .files3d import write_yarn_3d
        from .picture3d import plot_tubes
        radius, touch = self.problem.yarn.radius, self.nlp.contact_points(self.x)
        title = f"{self.problem.name} (3-D): {self.message}; check: {self.checked['verdict']}"
        png = plot_tubes(stem.with_name(stem.name + ".3d.png"), deformed, radius, touch,
                         self.problem.units.length, title)
        return [png, *write_yarn_3d(stem, deformed, radius, touch)]

    def _repr_fields(self) -> dict[str, object]:
        return {"model": self.model, "n_parameters": self.nlp.n_parameters,
                "reactions": [c.reaction.round(6).tolist() for c in self.clamps]}

    def representatives(self) -> dict[str, Any] | None:
        """The reduced model's representative courses and wales (None for the full model), with
        ``asked`` where the clamped ones were added (``transcription.condensed``)."""
        return self.nlp.representatives()

    def to_json(self) -> dict[str, Any]:
        """The result JSON (docs/weft_files.md, "Result JSON")."""
        rep = self.report
        result = {
            "problem": self.problem.name, "model": self.model,
            "success": self.success, "status": self.status, "message": self.message,
            "units": self.problem.units.to_json(),
            "energy": self.energy.to_json(),
            "n_parameters": self.nlp.n_parameters, "n_variables": self.nlp.n_variables,
            "n_constraints": self.nlp.n_constraints, "iterations": rep.iterations,
            "max_constraint_violation": self.violation,
            "timings": self.timings,
            "continuation_steps": rep.continuation_steps, "attempts": rep.attempts,
            "clamps": [c.to_json() for c in self.clamps],
            "loads": [ld.to_json() for ld in self.loads],
            "rigid_clamps": [r.to_json() for r in self.rigid_clamps],
            "loops": {"course_starts": self.starts[:, 0].tolist(),
                      "coefficients": self.coefficients.tolist()},
            "check": self.checked,
        }
        reps = self.representatives()
        if reps is not None:
            result["representatives"] = reps
        if self.spatial is not None:                         # the 3-D model (docs/weft3d.md)
            result["spatial"] = self.spatial
            result["loops"].update(course_starts_z=self.nlp.starts3d(self.x)[:, 0, 2].tolist(),
                                   elevations=self.nlp.elevations(self.x).tolist())
        source = source_record(self.problem.source)
        if source:
            result["source"] = source
        result.update(self.blocks())
        return result

    def blocks(self) -> dict[str, Any]:
        """The result JSON's blocks of the solve's variant, in this order: ``contact`` (``{}``
        for a solve with a yarn radius of an x its equilibrium did not solve), ``adaptive``,
        ``warm_start``."""
        out: dict[str, Any] = {}
        if self.contact is not None:
            out["contact"] = self.contact.to_json()
        elif self.problem.yarn is not None and not self.problem.yarn.spatial:
            out["contact"] = {}
        for name in ("adaptive", "warm_start"):
            block = getattr(self, name)
            if block is not None:
                out[name] = block.to_json()
        return out

    def save(self, out_dir: Path | str, samples: int = SAMPLES, *, colour: str = "course",
             export: Sequence[str] = (), animate: bool = False, yarn: bool = False
             ) -> list[Path]:
        """``DIR/<problem>.<model>.json``, ``.npz`` (s, natural and deformed centrelines,
        coefficients, starts) and ``.png``, as ``knit-nlp solve`` writes them; after a
        continuation also ``.path.csv`` and ``.path.png`` (force against displacement) and, with
        ``animate``, ``.gif``; ``yarn``: the picture draws the yarn with its thickness and the
        active contacts (``[yarn] radius``). ``colour``: "course" or "displacement"; ``export``: any of "csv"
        (``.csv``, rows course, wale, s, x, y) and "svg" (``.svg``)."""
        # matplotlib (about 0.4 s to import) only when pictures are written
        from .path import write_path
        from .plot import animate as animate_frames, plot_solution
        stem = Path(out_dir) / f"{self.problem.name}.{self.model}"

        def out(suffix: str) -> Path:
            return stem.with_name(stem.name + suffix)
        js = write_json(out(".json"), self.to_json())
        s = np.linspace(0.0, self.problem.L, samples)
        natural, deformed = self.natural_centrelines(samples), self.centrelines(samples)
        arrays = {"natural": natural, "deformed": deformed, "coefficients": self.coefficients,
                  "starts": self.starts}
        if hasattr(self.nlp, "centrelines3d"):      # the 3-D model: z as a third coordinate
            arrays.update(natural=self.nlp.natural_centrelines3d(samples),
                          deformed=self.nlp.centrelines3d(self.x, samples),
                          starts=self.nlp.starts3d(self.x), elevations=self.nlp.elevations(self.x))
            natural = arrays["natural"][..., :2]
        paths = [js, write_npz(out(".npz"), s=s, **arrays),
                 plot_solution(out(".png"), self, natural, deformed, colour, yarn)]
        if "csv" in export:
            paths.append(write_centreline_csv(out(".csv"), deformed, s))
        if "svg" in export:
            paths.append(write_centreline_svg(out(".svg"), deformed, self.problem.units.length))
        if hasattr(self.nlp, "centrelines3d"):      # the yarn as tubes: PNG, .vtu, .ply
            paths += self._save_3d(stem, arrays["deformed"])
        paths += write_path(stem, self.problem, self.loading_path())
        steps = self.loading_path()
        if animate and steps:
            frames = [(f"{self.problem.name}: load factor 0", natural)] + [
                (f"{self.problem.name}: load factor {tau:.3g}", r.centrelines(samples))
                for tau, r in steps]
            paths.append(animate_frames(out(".gif"), natural, frames, self.problem.units,
                                        problem=self.problem))
        return paths
