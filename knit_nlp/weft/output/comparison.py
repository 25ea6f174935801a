"""Full and reduced models of one problem side by side (``knit-nlp compare``), as a result."""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ...jsonio import write_json
from ...provenance import source_record
from ..model.centrelines import SAMPLES
from .plot import plot_overlay
from .results import WeftResult


@dataclass(repr=False)
class Comparison:
    """Full and reduced models of one problem side by side, and the full model warm-started
    from the reduced; distances between corresponding centreline points."""

    full: WeftResult
    reduced: WeftResult
    full_warm_from_reduced: WeftResult
    samples: int = SAMPLES

    @cached_property
    def _distance(self) -> np.ndarray:
        return np.linalg.norm(self.full.centrelines(self.samples)
                              - self.reduced.centrelines(self.samples), axis=-1)

    @property
    def distance_max(self) -> float:
        return float(self._distance.max())

    @property
    def distance_rms(self) -> float:
        return float(np.sqrt(np.mean(self._distance ** 2)))

    @property
    def energy_gap(self) -> float:
        """Reduced minus full stored energy (never negative at a shared minimum)."""
        return self.reduced.energy.total - self.full.energy.total

    @property
    def speedup_reduced(self) -> float:
        """Full (build + solve) time over reduced (build + solve) time."""
        def cost(r: WeftResult) -> float:
            return r.build_s + r.report.solve_s
        return cost(self.full) / cost(self.reduced)

    @property
    def success(self) -> bool:
        return all(r.success for r in self.models().values())

    def models(self) -> dict[str, WeftResult]:
        return {"full": self.full, "reduced": self.reduced,
                "full_warm_from_reduced": self.full_warm_from_reduced}

    def __repr__(self) -> str:
        return (f"Comparison({self.full.problem.name!r}: energy full {self.full.energy.total:.6g},"
                f" reduced {self.reduced.energy.total:.6g}; distance max {self.distance_max:.4g},"
                f" rms {self.distance_rms:.4g}; reduced {self.speedup_reduced:.2f}x as fast)")

    def to_json(self) -> dict[str, Any]:
        """``<problem>.compare.json``."""
        keys = ("success", "status", "n_parameters", "n_variables", "n_constraints",
                "iterations", "energy", "timings")
        return {"problem": self.full.problem.name,
                **({"source": src} if (src := source_record(self.full.problem.source)) else {}),
                "models": {name: {k: r.to_json()[k] for k in keys}
                           for name, r in self.models().items()},
                "distance": {"max": self.distance_max, "rms": self.distance_rms,
                             "samples_per_loop": self.samples},
                "energy_gap": self.energy_gap, "speedup_reduced": self.speedup_reduced,
                **({"adaptive": {**self.reduced.extra["adaptive"], "true_rms": self.distance_rms}}
                   if "adaptive" in self.reduced.extra else {})}

    def save(self, out_dir: Path | str) -> list[Path]:
        """``DIR/<problem>.compare.json`` and the overlay ``.compare.png``."""
        name = self.full.problem.name
        js = write_json(Path(out_dir) / f"{name}.compare.json", self.to_json())
        png = plot_overlay(Path(out_dir) / f"{name}.compare.png",
                           self.full.centrelines(self.samples),
                           self.reduced.centrelines(self.samples),
                           f"{name}: full (black) vs reduced, max distance {self.distance_max:.3g} "
                           f"{self.full.problem.units.length}", self.full.problem.units)
        return [js, png]
