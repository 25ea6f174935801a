"""The paper's solver (section 3.3-3.5): explicit midpoint integration of m a = F (eqs. 6-11),
with the order constraint (3.4.1) and the over-long-spring correction (3.4.2) after each step.

Vectorised with numpy over springs and particles; the only Python loop is over time steps.
"""
from __future__ import annotations

import time
from typing import Callable

import numpy as np

from ..outcome import OUT_OF_TIME, out_of_time
from .problem import JacquardProblem
from .result import JacquardResult
from .springs import (Network, build_network, residual_force, spring_energy, spring_forces,
                      spring_geometry)

CLOCK_EVERY = 64      # steps between checks of the wall-clock budget ([solver] max_time)


def _order_groups(net: Network, wales: int) -> list[np.ndarray]:
    """Split the order pairs into groups sharing no particle (even wales, odd wales, the seam)."""
    i = net.order_left % wales
    seam = net.order_offset > 0
    return [np.flatnonzero((i % 2 == 0) & ~seam), np.flatnonzero((i % 2 == 1) & ~seam),
            np.flatnonzero(seam)]


def enforce_order(x: np.ndarray, v: np.ndarray, net: Network, groups: list[np.ndarray],
                  mobile: np.ndarray, sweeps: int = 4) -> None:
    """Restore X(i+1,j) - X(i,j) >= 0 in place: move a crossing pair to their common mid-point
    (momentum-conserving; a fixed particle stays and the other moves) and equalise their x-velocity."""
    for _ in range(sweeps):
        done = True
        for g in groups:
            if g.size == 0:
                continue
            l, r, off = net.order_left[g], net.order_right[g], net.order_offset[g]
            gap = x[r, 0] + off - x[l, 0]
            bad = gap < 0
            if not bad.any():
                continue
            done = False
            l, r, off, gap = l[bad], r[bad], off[bad], gap[bad]
            ml, mr = mobile[l].astype(float), mobile[r].astype(float)
            tot = np.maximum(ml + mr, 1e-300)
            x[l, 0] += gap * ml / tot
            x[r, 0] -= gap * mr / tot
            vm = (v[l, 0] * ml + v[r, 0] * mr) / tot
            v[l, 0] = np.where(ml > 0, vm, v[l, 0])
            v[r, 0] = np.where(mr > 0, vm, v[r, 0])
        if done:
            return


def limit_springs(x: np.ndarray, v: np.ndarray, net: Network, mobile: np.ndarray,
                  sweeps: int = 4) -> None:
    """Paper 3.4.2 (Provot): for springs longer than lambda_max*l_init remove the separating part
    of the end velocities, and (Provot's position step) pull the ends back to the limit.
    Jacobi sweeps; a particle in several over-long springs takes the mean of its corrections."""
    s, n = net.springs, x.shape[0]
    for _ in range(sweeps):
        d, length = spring_geometry(x, s)
        over = np.flatnonzero(length > s.limit * (1 + 1e-12))
        if over.size == 0:
            return
        a, b = s.a[over], s.b[over]
        u = d[over] / length[over, None]
        ma, mb = mobile[a].astype(float), mobile[b].astype(float)
        tot = np.maximum(ma + mb, 1e-300)
        excess = (length[over] - s.limit[over])[:, None] * u
        vn = np.maximum(np.sum((v[b] - v[a]) * u, axis=1), 0.0)[:, None] * u
        count = np.bincount(a, ma, n) + np.bincount(b, mb, n)
        count = np.maximum(count, 1.0)[:, None]
        for arr, delta in ((x, excess), (v, vn)):
            corr = np.zeros_like(arr)
            for ax in (0, 1):
                corr[:, ax] = (np.bincount(a, delta[:, ax] * ma / tot, n)
                               - np.bincount(b, delta[:, ax] * mb / tot, n))
            arr += corr / count


Accel = Callable[[np.ndarray, np.ndarray], np.ndarray]


def acceleration(net: Network, mass: float, damping: float) -> Accel:
    """a(x, v) = F(x, v) / m of eqs. (1)-(2) (spring and damping forces), zero on fixed particles."""
    mob = (~net.fixed)[:, None].astype(float)

    def accel(x: np.ndarray, v: np.ndarray) -> np.ndarray:
        return spring_forces(x, net.springs, v, damping) * (mob / mass)
    return accel


def midpoint_step(x: np.ndarray, v: np.ndarray, dt: float, accel: Accel,
                  ) -> tuple[np.ndarray, np.ndarray]:
    """One explicit midpoint step (eqs. 9-11), without the constraints of 3.4: an Euler half
    step to the midpoint (eq. 10), then the full step with the midpoint's velocity and
    acceleration (eq. 11). Second-order accurate (tests/test_explicit_order.py)."""
    a1 = accel(x, v)
    xh, vh = x + 0.5 * dt * v, v + 0.5 * dt * a1
    return x + dt * vh, v + dt * accel(xh, vh)


def solve_explicit(problem: JacquardProblem, network: Network | None = None, *,
                   max_steps: int | None = None, move_tol: float | None = None,
                   record_energy: bool = False, force_tol: float | None = None,
                   check_every: int = 20) -> JacquardResult:
    """Relax from the natural grid (pulled edges already moved) with the explicit midpoint method (eqs. 9-11) until the
    largest particle move in a step is below ``move_tol * w`` or ``max_steps`` is reached.

    With ``force_tol`` the stopping test is instead the residual force (largest net spring force
    on a free particle, checked every ``check_every`` steps) — used to compare with the static
    solver "to the same residual" (scripts/bench_jacquard.py)."""
    t0 = time.perf_counter()
    net = network or build_network(problem)
    opts = problem.solver
    max_steps = opts.max_steps if max_steps is None else max_steps
    tol = (opts.move_tol if move_tol is None else move_tol) * problem.w
    dt, m, kd = problem.dt, problem.mass, problem.damping
    mobile = ~net.fixed
    groups = _order_groups(net, problem.wales)
    x, v = net.held.copy(), np.zeros_like(net.natural)   # pulled edges start moved (a step)
    accel = acceleration(net, m, kd)
    history = [] if record_energy else None
    if history is not None:
        history.append(spring_energy(x, net.springs))
    t1 = time.perf_counter()
    converged, steps, move, timed_out = False, 0, np.inf, False
    deadline = t0 + opts.max_time
    # a diverging run overflows before its positions turn NaN; the status reports it
    with np.errstate(over="ignore", invalid="ignore"):
        for steps in range(1, max_steps + 1):
            if steps % CLOCK_EVERY == 0 and time.perf_counter() > deadline:
                timed_out, steps = True, steps - 1
                break
            x_new, v_new = midpoint_step(x, v, dt, accel)
            enforce_order(x_new, v_new, net, groups, mobile)
            limit_springs(x_new, v_new, net, mobile)
            move = float(np.max(np.abs(x_new - x)))
            x, v = x_new, v_new
            if history is not None:
                history.append(spring_energy(x, net.springs) + 0.5 * m * float(np.sum(v * v)))
            if not np.isfinite(move):
                break
            if force_tol is None and move < tol:
                converged = True
                break
            if force_tol is not None and steps % check_every == 0 \
                    and residual_force(x, net) < force_tol:
                converged = True
                break
    if np.isfinite(move):   # final projection: end with every spring within its limit
        enforce_order(x, v, net, groups, mobile, sweeps=100)
        limit_springs(x, v, net, mobile, sweeps=2000)
    t2 = time.perf_counter()
    status, message = (
        ("Converged", f"converged: residual force < {force_tol:.3g}") if converged and force_tol
        else ("Converged", f"converged: largest move {move:.3g} mm < {tol:.3g} mm") if converged
        else ("Diverged", "diverged (non-finite positions)") if not np.isfinite(move)
        else (OUT_OF_TIME, out_of_time(opts.max_time)) if timed_out
        else ("Maximum_Steps_Exceeded",
              f"step limit {max_steps} reached; largest move {move:.3g} mm"))
    return JacquardResult(problem, net, "explicit", x, converged, status, message, steps=steps,
                          timings={"build_s": t1 - t0, "solve_s": t2 - t1},
                          energy_history=None if history is None else np.array(history))
