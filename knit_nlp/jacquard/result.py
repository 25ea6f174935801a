"""What a jacquard solve returns, and the derived quantities the result JSON reports."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .problem import JacquardProblem
from .springs import Network, spring_energy, spring_geometry, residual_force


@dataclass
class JacquardResult:
    """Final particle positions and how they were obtained."""

    problem: JacquardProblem
    network: Network
    solver: str                      # "static" or "explicit"
    positions: np.ndarray            # (M*N, 2), row j*M + i
    success: bool
    status: str                      # IPOPT's status text, or the explicit stopping reason
    steps: int | None = None         # explicit: steps taken
    iterations: int | None = None    # static: IPOPT iterations
    timings: dict[str, float] = field(default_factory=dict)
    energy_history: np.ndarray | None = None   # explicit, if recorded: kinetic + spring energy
    constraints: dict[str, int] | None = None  # static: generation rounds, limits/orders in NLP

    @property
    def residual_force(self) -> float:
        """Largest net spring force on a non-fixed particle (includes constraint reactions)."""
        return residual_force(self.positions, self.network)

    @property
    def energy(self) -> float:
        return spring_energy(self.positions, self.network.springs)

    def displacement(self) -> np.ndarray:
        return self.positions - self.network.natural

    def max_stretch(self) -> float:
        """Largest l / l_init over yarn springs (must stay <= lambda_max)."""
        s = self.network.springs
        _, length = spring_geometry(self.positions, s)
        yarn = ~s.compress
        return float(np.max(length[yarn] / s.l_init[yarn])) if yarn.any() else 1.0

    def min_order_gap(self) -> float:
        """Smallest X(i+1,j) - X(i,j) (must stay >= 0)."""
        net, x = self.network, self.positions
        if net.order_left.size == 0:
            return float("inf")
        return float(np.min(x[net.order_right, 0] + net.order_offset - x[net.order_left, 0]))

    def wale_skew(self) -> dict[str, np.ndarray]:
        """Per wale: mean lateral displacement (mm) and mean pillar-loop inclination (degrees).

        The inclination of loop (i,j) is the angle of P(i,j)->P(i,j+1) from the vertical,
        positive leaning right; the mean over the wale's courses is its skew.
        """
        p = self.problem
        x = self.positions.reshape(p.courses, p.wales, 2)
        dx = (self.positions - self.network.natural)[:, 0].reshape(p.courses, p.wales)
        up = np.roll(x, -1, axis=0)
        up[-1, :, 1] += p.courses * p.h if p.boundary == "periodic" else 0.0
        seg = (up - x)[: p.courses if p.boundary == "periodic" else p.courses - 1]
        angle = np.degrees(np.arctan2(seg[..., 0], seg[..., 1]))
        return {"mean_dx_mm": dx.mean(axis=0), "mean_angle_deg": angle.mean(axis=0),
                "max_abs_angle_deg": np.abs(angle).max(axis=0)}
