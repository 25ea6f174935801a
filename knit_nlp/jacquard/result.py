"""What a jacquard solve returns (the results contract of :mod:`knit_nlp.outcome`), the derived
quantities, and the result JSON and files (``to_json`` is the JSON's only producer; ``save``
writes what ``knit-nlp solve`` writes, drawn by ``render``)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..jsonio import write_json
from ..outcome import Energy, Outcome, describe
from ..provenance import source_record
from .problem import JacquardProblem
from .springs import (Network, edge_particles, edge_reaction, residual_force, spring_energy,
                      spring_geometry)

ZERO_MODE_TREATMENT = ("each floating component of the spring graph has its centroid held at "
                       "its natural centroid (what the explicit dynamics conserves)")


@dataclass(repr=False)
class JacquardResult(Outcome):
    """Final particle positions and how they were obtained: the contract (``success``,
    ``status``: IPOPT's return status or the explicit solver's code, ``message``, ``nit``,
    ``energy``, ``to_json``, ``save``) and SciPy's ``x``, the positions (M*N, 2), row j*M + i.
    ``model`` is ``"jacquard"``, as in the JSON and the file names."""

    problem: JacquardProblem
    network: Network
    solver: str                      # "static" or "explicit"
    positions: np.ndarray            # (M*N, 2), row j*M + i
    success: bool
    status: str                      # IPOPT's status, or Converged | Diverged | ... (explicit)
    message: str = ""                # one sentence (default: the status described)
    steps: int | None = None         # explicit: steps taken
    iterations: int | None = None    # static: IPOPT iterations
    timings: dict[str, float] = field(default_factory=dict)
    energy_history: np.ndarray | None = None   # explicit, if recorded: kinetic + spring energy
    constraints: dict[str, int] | None = None  # static: generation rounds, limits/orders in NLP

    model = "jacquard"

    def __post_init__(self) -> None:
        if not self.message:
            self.message = describe(self.status, self.problem.solver.max_time)

    @property
    def residual_force(self) -> float:
        """Largest net spring force on a non-fixed particle (includes constraint reactions)."""
        return residual_force(self.positions, self.network)

    @property
    def energy(self) -> Energy:
        """The rope springs' stored energy (all of it is spring energy)."""
        value = spring_energy(self.positions, self.network.springs)
        return Energy(value, value)

    @property
    def x(self) -> np.ndarray:
        return self.positions

    @property
    def iterations_or_steps(self) -> int:
        return int(self.steps if self.solver == "explicit" else self.iterations or 0)

    @property
    def nit(self) -> int:
        """IPOPT iterations (static) or explicit steps."""
        return self.iterations_or_steps

    def _repr_fields(self) -> dict[str, object]:
        return {"solver": self.solver, "residual_force": self.residual_force}

    def displacement(self) -> np.ndarray:
        return self.positions - self.network.natural

    def max_stretch(self) -> float:
        """Largest l / l_init over yarn springs (must stay <= lambda_max)."""
        s = self.network.springs
        _, length = spring_geometry(self.positions, s)
        yarn = ~s.compress
        return float(np.max(length[yarn] / s.l_init[yarn])) if yarn.any() else 1.0

    def pulls(self) -> list[dict[str, Any]]:
        """Per ``[[pull]]``: the edge, its displacement (mm) and the reaction, the force the
        grip applies to the fabric (minus the net spring force on the edge's particles)."""
        p = self.problem
        return [{"edge": q.edge, "displacement": list(q.displacement),
                 "reaction": edge_reaction(self.positions, self.network,
                                           edge_particles(p, q.edge))} for q in p.pulls]

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

    def to_json(self) -> dict[str, Any]:
        """The result JSON (docs/jacquard.md, "Result JSON"); ``energy`` is the Energy object
        (a plain number before the results contract was shared: readers take both,
        ``Energy.from_json``)."""
        p, net = self.problem, self.network
        return {
            "problem": p.name, "model": "jacquard", "solver": self.solver,
            "success": self.success, "status": self.status, "message": self.message,
            "residual_force": self.residual_force,
            "steps": self.steps, "iterations": self.iterations, "constraints": self.constraints,
            "timings": self.timings,
            "energy": self.energy.to_json(),
            "max_stretch": self.max_stretch(), "lambda_max": p.lambda_max,
            "min_order_gap": self.min_order_gap(),
            "zero_modes": {"count": net.zero_modes, "floating_components": len(net.floating),
                           "treatment": ZERO_MODE_TREATMENT if self.solver == "static" else
                           "none needed: floating components keep their momentum (zero)"},
            "wales": p.wales, "courses": p.courses, "w_mm": p.w, "h_mm": p.h,
            "boundary": p.boundary, "n_particles": p.n_particles, "n_springs": net.springs.n,
            "pulls": self.pulls(),
            "particles": {"index": "j*M + i", "natural": net.natural, "final": self.positions},
            "skew": self.wale_skew(),
            **({"source": src} if (src := source_record(p.source)) else {}),
        }

    def save(self, out_dir: Path | str, svg: bool = False,
             window: int | None = None) -> list[Path]:
        """``DIR/<problem>.jacquard.json`` and ``.png`` (and ``.svg`` on request; ``window``:
        draw at most this many loops each way, default the whole fabric up to DRAW_LIMIT)."""
        from .render import render       # matplotlib (about 0.4 s) only when drawing
        out = Path(out_dir)
        js = write_json(out / f"{self.problem.name}.jacquard.json", self.to_json())
        pictures = render(self, out / f"{self.problem.name}.jacquard.png", svg=svg,
                          window=window)
        return [js, *pictures]
