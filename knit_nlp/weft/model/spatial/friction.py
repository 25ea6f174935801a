"""Lagged Coulomb friction at the designed crossings (docs/weft3d.md, "Friction", eqs. F1-F4;
after Li et al., *Incremental Potential Contact*, 2020, its lagged friction potential D with
the mollifier f0, statically: one load step is one IPC time step).

Each designed crossing c keeps its material coordinates σ_u, σ_l on its two yarns (S5); in a
load step the yarns slide through it by

    (F1)  Δ_c = (σ_u − σ̄_u, σ_l − σ̄_l),   |Δ_c|² = Δ_u² + Δ_l² − 2 c̄ Δ_u Δ_l,

the length of the relative slide of the two yarns' material at the contact (v_u − v_l =
t_l σ̇_l − t_u σ̇_u, t the unit tangents), with c̄ = t̄_u·t̄_l the lagged cosine between them.
The friction potential of the step is

    (F2)  f0(y) = −y³/(3ε²) + y²/ε + ε/3  (y < ε),   f0(y) = y  (y ≥ ε)   (C¹),
    (F3)  D_c = μ N̄_c f0(|Δ_c|),

whose derivative is the Coulomb force μN̄ along the slide once it exceeds ε (below ε the
crossing sticks, its force growing linearly with the slide: the static regime of the
mollifier). N̄_c, σ̄, c̄ are the last accepted load step's (lagged: parameters of the NLP, not
variables; the first step's are the natural state's). The energy dissipated along a path is

    (F4)  Σ_steps μ Σ_c N̄_c |Δ_c|.

y = sqrt(|Δ|² + η²) with η = 10⁻⁹ ε so that the derivatives are finite at Δ = 0, where every
step starts (f0 then differs from (F2) by O(η²/ε)).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

EPSILON = 1e-3        # ε = EPSILON·L: the largest slide that sticks (F2)
ETA = 1e-9            # η = ETA·ε (module docstring)
LAGGED_ROWS = 4       # N̄, σ̄_u, σ̄_l, c̄ per crossing: the NLP's parameter block (4 × K)


def mollifier(y: ca.SX | ca.MX, eps: float) -> ca.SX | ca.MX:
    """f0(y) of (F2)."""
    return ca.if_else(y < eps, -y ** 3 / (3 * eps ** 2) + y ** 2 / eps + eps / 3, y)


def slide_squared(d_upper, d_lower, cosine):
    """|Δ|² of (F1) (numbers or CasADi expressions)."""
    return d_upper ** 2 + d_lower ** 2 - 2 * cosine * d_upper * d_lower


def friction_potential(mu: float, eps: float) -> ca.Function:
    """Function (σ (2), lagged (4): N̄, σ̄_u, σ̄_l, c̄) -> D (F3) of one crossing."""
    sig, lag = ca.SX.sym("sigma", 2), ca.SX.sym("lagged", LAGGED_ROWS)
    q = slide_squared(sig[0] - lag[1], sig[1] - lag[2], lag[3])
    y = ca.sqrt(q + (ETA * eps) ** 2)
    return ca.Function("friction", [sig, lag], [mu * lag[0] * mollifier(y, eps)],
                       ["sigma", "lagged"], ["D"])


@dataclass(frozen=True)
class Lagged:
    """The lagged values of one load step, per crossing (K): normal force N̄ (force units),
    material coordinates σ̄_u, σ̄_l and the cosine c̄ between the yarns (F1, F3)."""

    normal: np.ndarray
    sigma_upper: np.ndarray
    sigma_lower: np.ndarray
    cosine: np.ndarray

    def block(self) -> np.ndarray:
        """The NLP's lagged parameter block (4 × K), column-major as a vector."""
        return np.vstack([self.normal, self.sigma_upper, self.sigma_lower,
                          self.cosine]).ravel(order="F")

    def slides(self, sigma_upper: np.ndarray, sigma_lower: np.ndarray) -> np.ndarray:
        """|Δ_c| of (F1) at the coordinates reached."""
        q = slide_squared(sigma_upper - self.sigma_upper, sigma_lower - self.sigma_lower,
                          self.cosine)
        return np.sqrt(np.maximum(q, 0.0))


@dataclass(frozen=True)
class Friction:
    """The friction of one NLP: μ, ε (length units) and the number of crossings K."""

    mu: float
    eps: float
    count: int

    def dissipation(self, lagged: Lagged, sigma_upper: np.ndarray,
                    sigma_lower: np.ndarray) -> float:
        """μ Σ_c N̄_c |Δ_c| of one step (F4)."""
        return float(self.mu * np.sum(lagged.normal * lagged.slides(sigma_upper, sigma_lower)))


@dataclass(frozen=True)
class FrictionPath:
    """The load path's friction state that a solver carries (``WeftSolver.path``): the lagged
    values of the step being solved (after the path, of its last step: a round that solves the
    last step again keeps them), the accepted steps and the dissipation (F4) of those before
    the last (the last one's follows from its answer, ``dissipation``)."""

    lagged: Lagged
    steps: int = 0
    earlier: float = 0.0
    last: float = 0.0

    def accepted(self, dissipation: float) -> "FrictionPath":
        """The path after a step accepted with this dissipation (its lagged values kept until
        the next step starts, :meth:`next_step`)."""
        return replace(self, steps=self.steps + 1, earlier=self.earlier + self.last,
                       last=dissipation)

    def next_step(self, lagged: Lagged) -> "FrictionPath":
        """The path with the next step's lagged values (the last accepted answer's)."""
        return replace(self, lagged=lagged)
