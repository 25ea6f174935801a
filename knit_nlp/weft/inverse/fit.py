"""Identification of material values from observed points (docs/inverse.md, "Identification").

Every load case is a forward problem in equilibrium with the same material values θ (any of
k_a, k_b, R_f; eqs. 6-12). The residual stacks model minus observed positions over all cases;
Levenberg–Marquardt (Gauss–Newton with damping) runs on log θ, so values stay positive. The
Jacobian dP/dθ = (dP/dx)(dx/dθ) comes from the implicit-function theorem on each case's KKT
system (one factorization per case and iteration; ``equilibrium``), and each case is re-solved
by its own built IPOPT instance, warm-started from the linear prediction.

Standard errors: σ²(JᵀJ)⁻¹ with σ² = |r|²/(N − k), J in the values themselves. A value is
reported undetermined (``std_error`` None and a warning) when JᵀJ (in log θ, so scale-free)
has relative condition above ``condition_limit`` and the value takes part in the weak
direction (with fewer residuals than values JᵀJ is singular, so some always do), or when its
standard error exceeds the value. With N ≤ k residuals σ² cannot be estimated and no value
gets a standard error (never a number from a faked degree of freedom).
"""
from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any, Sequence

import casadi as ca
import numpy as np

from ...errors import ProblemError
from ...jsonio import write_json
from ...outcome import Energy, Outcome
from ..model.params import MATERIAL
from ..model.problem import WeftProblem
from ..output.results import WeftResult
from ..solving.solve import Equilibrium, SolveReport
from .forward import equilibrium_for
from .observations import Observation
from ..model.centrelines import natural_centrelines
from .plot import plot_fit
from .points import point_function, point_jacobian

CONVERGED = "Converged"


@dataclass
class FitOptions:
    max_iter: int = 50
    step_tol: float = 1e-10            # on the step in log θ
    condition_limit: float = 1e10      # relative condition of JᵀJ above which a direction is weak
    weak_share: float = 0.1            # a value with |component| above this in a weak direction


@dataclass
class _Case:
    name: str
    eq: Equilibrium
    points: ca.Function
    observed: np.ndarray               # (P, 2)
    x: np.ndarray | None = None
    lam: np.ndarray | None = None


@dataclass(repr=False)
class FitResult(Outcome):
    """The fitted material values as a result (the contract of :mod:`knit_nlp.outcome`:
    ``nit`` the Levenberg–Marquardt iterations, ``energy`` the load cases' stored energies
    summed at the fitted values), its JSON (``to_json``, the contract's ``fit.json`` plus
    ``warnings``) and files (``save``: ``<name>.fit.json``, ``<name>.fit.png``)."""

    success: bool
    status: str
    iterations: int
    names: list[str]
    values: np.ndarray
    initial: np.ndarray
    std_errors: list[float | None]
    warnings: list[str]
    residuals: dict[str, np.ndarray]   # per case, (P, 2) model minus observed
    fitted: dict[str, np.ndarray]      # per case, (P, 2) model positions
    solutions: dict[str, np.ndarray]   # per case, the decision vector
    cases: list[_Case] = field(repr=False, default_factory=list)
    timings: dict[str, float] = field(default_factory=dict)
    energy: Energy = Energy(float("nan"), float("nan"))
    files: dict[str, str] = field(default_factory=dict)   # case -> its problem file (JSON)

    name: str = ""                     # the output name (default: fit_name of the cases)

    def _name(self) -> str:
        return self.name or fit_name([c.name for c in self.cases])

    def to_json(self) -> dict[str, Any]:
        return fit_json(self)

    def save(self, out_dir: Path | str) -> list[Path]:
        """``DIR/<name>.fit.json`` and ``DIR/<name>.fit.png`` (per case: the natural and the
        fitted equilibrium with its grips, observed and fitted points); ``name`` defaults to
        :func:`fit_name` of the load cases, so fits of other cases never overwrite these."""
        out, result, name = Path(out_dir), self.to_json(), self._name()
        js = write_json(out / f"{name}.fit.json", result)
        panels = [(c.name, self.case_result(c), natural_centrelines(c.eq.wnlp.problem),
                   c.eq.wnlp.centrelines(c.x), c.observed, self.fitted[c.name])
                  for c in self.cases if c.x is not None]
        title = (f"fit of {', '.join(self.names)}: {result['status']}, rms residual "
                 f"{result['rms_residual']:.3g} {panels[0][1].problem.units.length}"
                 if result["rms_residual"] is not None and panels else f"fit: {result['status']}")
        return [js, plot_fit(out / f"{name}.fit.png", panels, title, self.checks)]

    @cached_property
    def checks(self) -> dict[str, dict[str, Any]]:
        """Per load case with an equilibrium, its own check at the fitted values (the result
        JSON's ``check`` block, ``WeftResult.checked``), made once: the fit JSON's ``check``,
        the summary and the picture's panel titles say it."""
        return {c.name: self.case_result(c).checked for c in self.cases if c.x is not None}

    def case_result(self, c: _Case) -> WeftResult:
        """A load case's equilibrium at the fitted values, as a solve's result (its clamps and
        reactions, for the picture)."""
        wnlp = c.eq.wnlp
        p = wnlp.p0.copy()
        for n, v in zip(self.names, self.values):
            wnlp.p.put(p, n, v)
        report = SolveReport(True, "Solve_Succeeded", c.x, c.lam, float("nan"), 0, 0.0)
        return WeftResult.of(c.eq.solution(report, p))


NAME_CHARS = 60       # a fit's default name joins its cases' names up to this length


def fit_name(cases: Sequence[str]) -> str:
    """The default output name of a fit: its load cases' names joined by "+" (in the order
    given), or, when that is longer than NAME_CHARS, the first case's name, how many more and
    a short hash of them all, so two fits of different cases never share a name."""
    joined = "+".join(cases)
    if len(joined) <= NAME_CHARS:
        return joined or "fit"
    digest = hashlib.sha256("\0".join(cases).encode()).hexdigest()[:8]
    return f"{cases[0][:NAME_CHARS - 20]}+{len(cases) - 1}_more_{digest}"


class Fitter:
    """The least-squares problem over the chosen material values (one forward build per case)."""

    def __init__(self, problems: Sequence[WeftProblem], observations: Sequence[Observation],
                 params: Sequence[str] = MATERIAL, options: FitOptions | None = None) -> None:
        self.names = list(params)
        self.opts = options or FitOptions()
        self.cases = []
        for pr in problems:
            obs = [o for o in observations if o.case == pr.name]
            if not obs:
                continue
            refuse_springs_in_3d(pr, self.names)
            eq = equilibrium_for(pr)
            fn = point_jacobian(point_function(eq.wnlp, [(o.loop, o.s) for o in obs]))
            self.cases.append(_Case(pr.name, eq, fn, np.array([o.xy for o in obs])))
        first = self.cases[0].eq.wnlp
        self.initial = np.array([float(first.p.get(first.p0, n)[0, 0]) for n in self.names])

    def _params(self, case: _Case, values: np.ndarray) -> np.ndarray:
        p = case.eq.wnlp.p0.copy()
        for name, v in zip(self.names, values):
            case.eq.wnlp.p.put(p, name, v)
        return p

    def _dp(self, case: _Case) -> np.ndarray:
        pl = case.eq.wnlp.p
        E = np.zeros((pl.size, len(self.names)))
        for k, name in enumerate(self.names):
            E[pl.slice(name).start, k] = 1.0
        return E

    def solve_cases(self, values: np.ndarray, steps: dict[str, np.ndarray] | None = None) -> bool:
        """Every case in equilibrium at ``values`` (warm starts from ``steps``: predicted x)."""
        for c in self.cases:
            x0 = None if c.x is None else (steps or {}).get(c.name, c.x)
            rep = c.eq.solve(self._params(c, values), x0=x0)
            if not rep.success:
                return False
            c.x, c.lam = rep.x, rep.lam_g
        return True

    def residual(self) -> np.ndarray:
        return np.concatenate([(self.positions(c) - c.observed).ravel() for c in self.cases])

    def positions(self, c: _Case) -> np.ndarray:
        return np.asarray(c.points(c.x)[0]).T

    def jacobian(self, values: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """d(residual)/d(values) and each case's dx/d(values)."""
        rows, dxs = [], {}
        for c in self.cases:
            dx, _ = c.eq.sensitivity(c.x, c.lam, self._params(c, values), self._dp(c))
            dxs[c.name] = dx
            JP = np.asarray(c.points(c.x)[1] @ ca.DM(dx))          # vec(2 × P) column-major
            rows.append(JP)                                          # = (P, 2) row-major ravel
        return np.vstack(rows), dxs

    def run(self) -> FitResult:
        t0 = time.perf_counter()
        v = self.initial.copy()
        if not self.solve_cases(v):
            return self._answer(False, "a case has no equilibrium at the initial values", 0, v, t0)
        r = self.residual()
        mu, status, it = 1e-3, "Maximum_Iterations", 0
        for it in range(1, self.opts.max_iter + 1):
            Jv, dxs = self.jacobian(v)
            J = Jv * v                                               # d r / d log θ
            A, g = J.T @ J, J.T @ r
            d = -np.linalg.lstsq(A + mu * np.diag(np.diag(A)), g, rcond=1e-14)[0]
            d = d * min(1.0, 1.0 / max(np.abs(d).max(), 1e-300))    # at most a factor e per step
            if np.abs(d).max() <= self.opts.step_tol:
                status = CONVERGED
                break
            trial = v * np.exp(d)
            saved = [(c.x, c.lam) for c in self.cases]
            pred = {c.name: c.x + dxs[c.name] @ (trial - v) for c in self.cases}
            if self.solve_cases(trial, pred) and (rt := self.residual()) @ rt < r @ r:
                v, r, mu = trial, rt, max(mu / 10, 1e-12)
                continue
            for c, (x, lam) in zip(self.cases, saved):
                c.x, c.lam = x, lam
            mu *= 10
            if mu > 1e10:
                status = "No_Decrease"
                break
        return self._answer(status == CONVERGED, status, it, v, t0)

    def _answer(self, ok: bool, status: str, it: int, v: np.ndarray, t0: float) -> FitResult:
        std, warnings = self._std_errors(v) if ok else ([None] * len(v), [])
        fitted = {c.name: self.positions(c) for c in self.cases if c.x is not None}
        return FitResult(ok, status, it, self.names, v, self.initial, std, warnings,
                         {c.name: fitted[c.name] - c.observed for c in self.cases if c.name in fitted},
                         fitted, {c.name: c.x for c in self.cases}, self.cases,
                         {"total_s": time.perf_counter() - t0 + sum(c.eq.build_s for c in self.cases)},
                         self._energy(v))

    def _energy(self, v: np.ndarray) -> Energy:
        """The cases' stored energies summed at values v (NaN where a case has no solution)."""
        terms = np.array([c.eq.wnlp.energy(c.x, self._params(c, v)) if c.x is not None
                          else (np.nan,) * 3 for c in self.cases]).sum(axis=0)
        spring, bending, work = (float(t) for t in terms)
        return Energy(spring + bending, spring, bending, work)

    def _scale_free(self) -> bool:
        """Whether scaling every material value leaves every case's equilibrium unchanged:
        all of them are fitted and no case has a load (the energy is linear in the values, so
        displacement-only clamps fix the shape by the values' ratios alone)."""
        return set(MATERIAL) <= set(self.names) and not any(c.eq.problem.loads for c in self.cases)

    def _std_errors(self, v: np.ndarray) -> tuple[list[float | None], list[str]]:
        """σ²(JᵀJ)⁻¹ over the determined values; the others None, with a warning each. With
        no more residuals than values σ² cannot be estimated: every standard error is None."""
        Jv, _ = self.jacobian(v)
        r = self.residual()
        undetermined = weak_values(Jv * v, self.opts)
        dof = len(r) - len(v)
        keep = [k for k in range(len(v)) if k not in undetermined]
        std: list[float | None] = [None] * len(v)
        if keep and dof > 0:
            cov = float(r @ r) / dof * np.linalg.inv(Jv[:, keep].T @ Jv[:, keep])
            for q, k in enumerate(keep):
                std[k] = float(np.sqrt(max(cov[q, q], 0.0)))
        warnings = []
        scale_free = self._scale_free()
        for k, name in enumerate(self.names):
            if k in undetermined and scale_free:
                warnings.append(f"{name} is not determined by the data: only ratios can be "
                                "identified with displacement-only clamps: add a force or fit "
                                "ratios with --params (leave one of "
                                f"{', '.join(MATERIAL)} out: it keeps its file value)")
            elif k in undetermined:
                warnings.append(f"{name} is not determined by the data (JᵀJ is singular to "
                                f"relative condition {self.opts.condition_limit:g} in its direction)")
            elif dof <= 0:
                warnings.append(f"{name} is not determined by the data ({len(r)} observed "
                                f"coordinates for {len(v)} values leave no degree of freedom "
                                f"to estimate its error; observe more points)")
            elif std[k] is not None and std[k] > v[k]:
                warnings.append(f"{name} is not determined by the data (standard error "
                                f"{std[k]:.3g} exceeds the value {v[k]:.3g})")
                std[k] = None
        return std, warnings


def refuse_springs_in_3d(pr: WeftProblem, names: Sequence[str]) -> None:
    """A 3-D load case without the paper's crossing springs has no k_a, k_b (its crossings are
    contacts, docs/weft3d.md): fitting them is refused in one line rather than reported as
    undetermined values the data cannot see."""
    springs = [n for n in names if n in ("k_a", "k_b")]
    if springs and pr.yarn is not None and pr.yarn.spatial and not pr.yarn.crossing_springs:
        raise ProblemError(pr.source, "yarn", "crossing_springs",
                           f"fit of {', '.join(springs)}: the 3-D model's crossings are contacts, "
                           "not the paper's springs; fit R_f only (--params R_f) or set "
                           "crossing_springs = true")


def weak_values(J: np.ndarray, opts: FitOptions) -> set[int]:
    """Columns of J (residuals by values, in log θ) taking part, with a component above
    ``weak_share``, in a weak direction of JᵀJ: an eigenvalue below the largest over
    ``condition_limit``, or one of its null directions (JᵀJ has rank at most the number of
    rows of J, whatever the rounding of its eigenvalues)."""
    w, V = np.linalg.eigh(J.T @ J)                           # ascending
    weak = w <= max(w.max(initial=0.0), 1e-300) / opts.condition_limit
    weak[:max(J.shape[1] - J.shape[0], 0)] = True            # fewer residuals than values
    return set(np.nonzero(np.any(np.abs(V[:, weak]) > opts.weak_share, axis=1))[0])


def fit(problems: Sequence[WeftProblem], observations: Sequence[Observation],
        params: Sequence[str] = MATERIAL, options: FitOptions | None = None) -> FitResult:
    """Fit material values (Python API behind ``knit-nlp fit``)."""
    return Fitter(problems, observations, params, options).run()


def fit_json(ans: FitResult) -> dict[str, Any]:
    """The contract's ``fit.json`` (written as ``<name>.fit.json``; plus ``message``, ``energy``,
    ``warnings``, ``check`` (per load case, its equilibrium's own check at the fitted values)
    and, when known, ``cases_files``)."""
    res = {k: np.linalg.norm(r, axis=1) for k, r in ans.residuals.items()}
    allres = np.concatenate(list(res.values())) if res else np.zeros(0)
    return {"success": ans.success, "status": ans.status, "message": ans.message,
            "energy": ans.energy.to_json(), "iterations": ans.iterations,
            "n_observations": int(allres.size),
            "parameters": {n: {"value": float(v), "std_error": s, "initial": float(i)}
                           for n, v, s, i in zip(ans.names, ans.values, ans.std_errors, ans.initial)},
            "rms_residual": float(np.sqrt(np.mean(allres ** 2))) if allres.size else None,
            "cases": [{"case": k, "rms_residual": float(np.sqrt(np.mean(d ** 2))),
                       "max_residual": float(d.max())} for k, d in res.items()],
            "warnings": ans.warnings, "timings": ans.timings, "check": ans.checks,
            **({"cases_files": ans.files} if ans.files else {})}
