"""Least squares over the fitted values, in their logarithms (values stay positive), and the
uncertainty of the answer.

The minimiser is SciPy's trust-region reflective ``least_squares`` with the analytic Jacobian
the caller supplies. Standard errors are the Gauss–Newton ones, σ²(JᵀJ)⁻¹ with J in the values
and σ² = |r|²/(N − k); the residuals of one run along its curve are correlated, so these are
lower bounds (docs/real_fabric.md). A value is *undetermined* (no standard error, a warning)
when JᵀJ in the logarithms, which is scale-free, has a direction with eigenvalue below
``CONDITION_LIMIT`` of the largest and the value takes part in it by more than ``WEAK_SHARE``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import least_squares

CONDITION_LIMIT = 1e10
WEAK_SHARE = 0.1
MAX_EVALUATIONS = 40
# Stop when a step changes the cost by less than FTOL (relative) or the log values by less than
# XTOL. A value the data cannot bound (k_a running to the rigid limit on the course pull) then
# stops the fit after a few steps instead of at MAX_EVALUATIONS; at the answer the cost's
# precision 1e-5 moves a value by about sqrt(1e-5 N)·σ ≈ 0.05 of its standard error (N ≈ 200).
FTOL = 1e-5
XTOL = 1e-6
SPAN = 1e6                  # a fitted value stays within this factor of its starting value
MAX_VALUE = 1e9             # and below the largest number a problem file takes
PENALTY = 1.0               # residual of a strain the model could not reach (strains are ~0.1)
# ``[calibrate] scan = true``: a single fitted value is first tried at its starting value times
# each factor and the least squares starts from the best. The periodic cell's residual in its
# contact rigidity is rough (its path through the jam changes branch: on acrylic_3d_source's
# law RMS 0.085, 0.110, 0.079 at k x 10, 11, 12 where k x 9-15 is otherwise smooth, measured),
# and started at the spec's value the trust region stopped on a bump at k x 5.8 (RMS 0.108)
# where k x 40 gives 0.030.
SCAN_FACTORS = tuple(2.0 ** e for e in range(-3, 7))      # 1/8 ... 64


@dataclass
class FitOutcome:
    """The answer of :func:`fit_log`: values, their standard errors and correlation."""

    success: bool
    status: str
    message: str
    nit: int                            # residual evaluations (each a set of model curves)
    njev: int
    values: np.ndarray
    std_errors: list[float | None]
    correlation: np.ndarray             # NaN where a value is undetermined
    residual: np.ndarray
    warnings: list[str] = field(default_factory=list)
    scan: list[tuple[float, float]] = field(default_factory=list)   # (value, rms) tried first

    @property
    def cost(self) -> float:
        return float(self.residual @ self.residual)


def scan_start(initial: np.ndarray, residual: Callable[[np.ndarray], np.ndarray],
               factors: tuple[float, ...] = SCAN_FACTORS) -> tuple[np.ndarray,
                                                                   list[tuple[float, float]]]:
    """The best of one value's starting value times each factor (``SCAN_FACTORS``), by RMS
    residual, and every (value, RMS) tried."""
    if len(initial) != 1:
        raise ValueError("a scan start is for a single fitted value")
    tried = []
    for f in factors:
        v = initial * f
        r = residual(v)
        tried.append((float(v[0]), float(np.sqrt(np.mean(r ** 2)))))
    best = min(tried, key=lambda t: t[1] if np.isfinite(t[1]) else np.inf)
    return np.array([best[0]]), tried


def fit_log(names: list[str], initial: np.ndarray, residual: Callable[[np.ndarray], np.ndarray],
            jacobian: Callable[[np.ndarray], np.ndarray], scan: bool = False) -> FitOutcome:
    """Minimise |residual(values)|² over log values; ``jacobian`` is d residual / d log value.
    With ``scan`` (one value only) the least squares starts from :func:`scan_start`'s best.

    The unknowns are the logarithms of the values relative to their starts, z = log(θ/θ₀),
    starting at 0, so the trust region's first radius (SciPy: |z₀| scaled by the distances to
    the bounds, 1 when z₀ = 0) is the same whatever the values' units. Over log θ itself it
    grew with |log θ₀|: on the acrylic spec started from run b4's answer (k_a 3.5e4 N/mm, k_b
    0.00623 N/mm, 760 mm) the first step took the undetermined k_a to 2.6e4 times its start
    (with contact, into solves that crawled); now 24.6 times, one residual evaluation fewer
    (tests/test_calibration_model.py::test_the_fits_first_step_does_not_depend_on_the_units)."""
    tried: list[tuple[float, float]] = []
    start = initial
    if scan:
        start, tried = scan_start(initial, residual)
    z0 = np.log(start)
    lower = np.log(initial) - np.log(SPAN) - z0
    upper = np.minimum(np.log(initial) + np.log(SPAN), np.log(MAX_VALUE)) - z0
    result = least_squares(lambda z: residual(np.exp(z0 + z)), np.zeros(len(z0)),
                           jac=lambda z: jacobian(np.exp(z0 + z)), bounds=(lower, upper),
                           method="trf", x_scale=1.0, xtol=XTOL, ftol=FTOL, gtol=1e-10,
                           max_nfev=MAX_EVALUATIONS)
    values = np.exp(z0 + result.x)
    at_bound = [n for n, z, lo, hi in zip(names, result.x, lower, upper)
                if min(z - lo, hi - z) < 1e-6]
    r = residual(values)
    Jz = jacobian(values)
    std, corr, warnings = uncertainty(names, values, r, Jz, initial)
    warnings += [f"{n} stopped at its bound ({SPAN:g} times or 1/{SPAN:g} of its starting value,"
                 f" at most {MAX_VALUE:g})" for n in at_bound]
    ok = bool(result.success) and bool(np.all(np.isfinite(r)))
    status = {-1: "Failed", 0: "Maximum_Evaluations", 1: "Converged_Gradient",
              2: "Converged_Cost", 3: "Converged_Step", 4: "Converged_Cost_And_Step"}.get(
        result.status, str(result.status))
    return FitOutcome(ok, status, str(result.message), int(result.nfev) + len(tried),
                      int(result.njev or 0), values, std, corr, r, warnings, tried)


RAN_AWAY = 1e3             # an undetermined value this far from its start: only a bound is known


def uncertainty(names: list[str], values: np.ndarray, r: np.ndarray, Jz: np.ndarray,
                initial: np.ndarray | None = None) -> tuple[list[float | None], np.ndarray,
                                                            list[str]]:
    """Standard errors, correlation and warnings at a least-squares answer (module doc)."""
    k = len(values)
    A = Jz.T @ Jz
    w, V = np.linalg.eigh(A)
    weak = w <= max(w.max(initial=0.0), 1e-300) / CONDITION_LIMIT
    undetermined = set(np.flatnonzero(np.any(np.abs(V[:, weak]) > WEAK_SHARE, axis=1)))
    keep = [q for q in range(k) if q not in undetermined]
    sigma2 = float(r @ r) / max(len(r) - k, 1)
    std: list[float | None] = [None] * k
    corr = np.full((k, k), np.nan)
    if keep:
        Jv = Jz[:, keep] / values[keep]                      # d r / d value
        cov = sigma2 * np.linalg.inv(Jv.T @ Jv)
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        for a, q in enumerate(keep):
            std[q] = float(se[a])
            for b, p in enumerate(keep):
                corr[q, p] = cov[a, b] / (se[a] * se[b]) if se[a] > 0 and se[b] > 0 else np.nan
    warnings = []
    for q, name in enumerate(names):
        moved = 1.0 if initial is None else values[q] / initial[q]
        if q in undetermined and not 1 / RAN_AWAY < moved < RAN_AWAY:
            warnings.append(f"{name} ran to {values[q]:.4g} ({moved:.3g} times its starting "
                            "value) without the fit improving: the strains stop depending on it "
                            "there, so the data set only a bound on it")
        elif q in undetermined:
            warnings.append(f"{name} is not determined by the data (JᵀJ is singular to relative "
                            f"condition {CONDITION_LIMIT:g} in its direction)")
        elif std[q] is not None and std[q] > values[q]:
            warnings.append(f"{name} is poorly determined: standard error {std[q]:.3g} exceeds "
                            f"the value {values[q]:.3g}")
    return std, corr, warnings
