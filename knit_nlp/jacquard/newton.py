"""Newton's method for the static equilibrium without active constraints (docs/jacquard.md,
"Static solver").

Minimises the same energy as the IPOPT formulation of static.py,

    E(x) = sum_s 1/2 k_s (|d_s| - l0_s)+^2 + 1/2 eps |x - x_natural|^2,   d = B x + c,

over the positions of the particles the boundary does not hold (held ones stay at their
natural or pulled places). For rope springs E is C1 and convex with a piecewise smooth
Hessian ``B^T blockdiag(H_s) B + eps I`` (springs.spring_hessians), so a Newton iteration with
a backtracking line search converges to its unique minimiser (unique for eps > 0; the
Hessian's kinks where springs go slack make it a semismooth Newton method, superlinear like
the smooth one).

- Steps: inexact Newton, the system solved by conjugate gradients preconditioned with one
  algebraic-multigrid V-cycle (linalg.py) to the relative residual ``eta_k`` of Eisenstat
  and Walker's second choice, ``eta_k = 0.9 (|g_k| / |g_{k-1}|)^2`` (safeguarded, at most 0.5),
  and never below what the stopping test needs (``0.5 tol / |g_k|``): loose early, tight only
  where the convergence is fast.
- The multigrid hierarchy is built on the first Hessian and rebuilt when a solve needs more
  than ``REBUILD_CG`` iterations (the Hessian has moved away from the one it was built on).
- Line search: Armijo backtracking on the energy *change*, computed spring by spring from
  the step without cancellation (``energy_change``), so the test still resolves decreases
  far below the rounding error of E itself (~1e-12 at 500 x 500) near the solution.
- Stop: ``max_i |dE/dx_i| <= tol`` over the free coordinates, IPOPT's dual infeasibility for
  this unconstrained problem (the same ``[solver] tol``), or ``max_iter``, or the deadline.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import numpy as np

from ..progress import QUIET_FOR, Clock
from .linalg import BlockHessian, linear_solver
from .springs import SpringSet, spring_forces, spring_geometry, spring_hessians

ARMIJO = 1e-4          # sufficient decrease fraction
MIN_STEP = 1e-12       # line-search floor: below it the direction is declared useless
ETA_MAX = 0.5          # loosest relative residual of a Newton system


class SpringEnergy:
    """E over the free particles' coordinates ``z`` (2 per free particle, x then y)."""

    def __init__(self, s: SpringSet, free: np.ndarray, held: np.ndarray,
                 natural: np.ndarray, eps: float) -> None:
        self.s, self.free, self.held, self.eps = s, free, held, eps
        self.natural = natural[free].ravel()
        self.pattern = BlockHessian.build(s.a, s.b, free)

    def positions(self, z: np.ndarray) -> np.ndarray:
        """All particle positions (Np, 2) for the free coordinates ``z``."""
        x = self.held.copy()
        x[self.free] = z.reshape(-1, 2)
        return x

    def value(self, z: np.ndarray) -> float:
        _, length = spring_geometry(self.positions(z), self.s)
        stretch = np.maximum(np.where(self.s.compress, self.s.l0 - length,
                                      length - self.s.l0), 0.0)
        return float(0.5 * np.sum(self.s.k * stretch ** 2)
                     + 0.5 * self.eps * np.sum((z - self.natural) ** 2))

    def gradient(self, z: np.ndarray) -> np.ndarray:
        """dE/dz: minus the net spring force, plus the regularisation's pull."""
        force = spring_forces(self.positions(z), self.s)[self.free].ravel()
        return self.eps * (z - self.natural) - force

    def hessian(self, z: np.ndarray):
        return self.pattern.matrix(*spring_hessians(self.positions(z), self.s), self.eps)

    def change(self, z: np.ndarray, step: np.ndarray) -> float:
        """E(z + step) - E(z) without the cancellation of subtracting two sums.

        Per spring, ``1/2 k (e1 - e0)(e1 + e0)`` with e the stretch; where the spring is in
        force at both ends of the step, ``l1 - l0 = (d1 - d0) . (d1 + d0) / (l1 + l0)`` with
        ``d1 - d0`` taken from the step itself.
        """
        s = self.s
        x0 = self.positions(z)
        dx = np.zeros_like(x0)
        dx[self.free] = step.reshape(-1, 2)
        d0, l0 = spring_geometry(x0, s)
        dd = dx[s.b] - dx[s.a]
        d1 = d0 + dd
        l1 = np.hypot(d1[:, 0], d1[:, 1])
        sign = np.where(s.compress, -1.0, 1.0)
        e0 = np.maximum(sign * (l0 - s.l0), 0.0)
        e1 = np.maximum(sign * (l1 - s.l0), 0.0)
        total = l1 + l0
        dl = np.einsum("ij,ij->i", dd, d0 + d1) / np.where(total > 0, total, 1.0)
        de = np.where((e0 > 0) & (e1 > 0), sign * dl, e1 - e0)
        reg = self.eps * (step @ (z - self.natural) + 0.5 * step @ step)
        return float(0.5 * np.sum(s.k * de * (e1 + e0)) + reg)


@dataclass
class NewtonOutcome:
    """Where the iteration ended and what it cost."""

    z: np.ndarray
    converged: bool
    status: str
    iterations: int
    cg_iterations: int        # conjugate-gradient iterations (0: direct solves)
    linear: str               # how the Newton systems were solved
    gradient_max: float
    timings: dict[str, float] = field(default_factory=dict)


def forcing(g_norm: float, g_max: float, previous: float | None, eta_previous: float,
            tol: float) -> float:
    """Eisenstat-Walker choice 2 with its safeguard, capped at ETA_MAX, and floored at
    ``0.5 tol / max|g|``: a tighter solve could not matter for the stopping test (should the
    step fall short, the next one is cheap)."""
    if previous is None:
        eta = ETA_MAX
    else:
        eta = 0.9 * (g_norm / previous) ** 2
        if 0.9 * eta_previous ** 2 > 0.1:
            eta = max(eta, 0.9 * eta_previous ** 2)
    return float(min(ETA_MAX, max(eta, 0.5 * tol / g_max)))


def minimise(energy: SpringEnergy, z0: np.ndarray, tol: float, max_iter: int,
             deadline: float) -> NewtonOutcome:
    """Inexact Newton from ``z0`` until ``max |dE/dz| <= tol`` (module docstring)."""
    clock = {"evaluations_s": 0.0, "assembly_s": 0.0, "line_search_s": 0.0}
    linear = linear_solver(z0.size)

    def timed(key, fn, *args):
        t = time.perf_counter()
        out = fn(*args)
        clock[key] += time.perf_counter() - t
        return out

    z = z0.astype(float).copy()
    g = timed("evaluations_s", energy.gradient, z)
    prev_norm, eta = None, ETA_MAX

    def outcome(converged: bool, status: str, it: int, g_max: float) -> NewtonOutcome:
        return NewtonOutcome(z, converged, status, it, linear.iterations, linear.describe(),
                             g_max, {**clock, **linear.timings})

    progress = Clock(QUIET_FOR)       # no solve runs silently: a line once it outlasts QUIET_FOR
    for it in range(max_iter + 1):
        g_max = float(np.max(np.abs(g))) if g.size else 0.0
        if (took := progress.due()) is not None:
            sys.stderr.write(f"  Newton iteration {it}: max |dE/dx| {g_max:.3g} (tol {tol:g}), "
                             f"{took:.0f} s\n")
            sys.stderr.flush()
        if g_max <= tol:
            return outcome(True, f"max |dE/dx| {g_max:.3g} <= tol {tol:g}", it, g_max)
        if it == max_iter or time.perf_counter() >= deadline:
            why = f"max_iter {max_iter} reached" if it == max_iter else "max_time exceeded"
            return outcome(False, f"{why}: max |dE/dx| {g_max:.3g} > tol {tol:g}", it, g_max)
        g_norm = float(np.linalg.norm(g))
        eta = forcing(g_norm, g_max, prev_norm, eta, tol)
        H = timed("assembly_s", energy.hessian, z)
        step = linear.solve(H, -g, eta)
        slope = float(g @ step)
        if not slope < 0:                   # not a descent direction (a failed solve)
            step, slope = -g, -g_norm ** 2
        t = time.perf_counter()
        alpha = 1.0
        while energy.change(z, alpha * step) > ARMIJO * alpha * slope:
            alpha *= 0.5
            if alpha < MIN_STEP:
                clock["line_search_s"] += time.perf_counter() - t
                return outcome(False, f"line search failed: max |dE/dx| {g_max:.3g}", it, g_max)
        clock["line_search_s"] += time.perf_counter() - t
        z = z + alpha * step
        prev_norm = g_norm
        g = timed("evaluations_s", energy.gradient, z)
    raise AssertionError("unreachable")          # pragma: no cover
