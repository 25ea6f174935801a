"""Full and reduced models of one problem side by side (``knit-nlp compare``), as a result."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ...jsonio import write_json
from ...provenance import source_record
from ..model.centrelines import SAMPLES
from .results import WeftResult

RMS_LOOPS_OK = 0.1
"""Largest RMS centreline distance, in loop lengths L, at which the reduced model is good enough.
A tenth of the yarn length of one loop is a fraction of a loop's width: every loop is in its
place and of its shape in the overlay picture. The case that asked for a verdict differed by
2-4 L (23 mm): whole loops out of place, which the reduced grid's interpolation cannot follow."""

ENERGY_REL_OK = 0.05
"""Largest relative energy difference |E_reduced / E_full - 1| at which the reduced model is good
enough. The reduced model has fewer degrees of freedom, so its energy is an upper bound: the
excess is how much stiffer the interpolation makes the fabric. 5 % is about the repeatability of
a fabric tensile test, so a smaller excess is below what a measurement could tell apart."""


def _energy_ratio(reduced: float, full: float) -> float:
    """E_reduced / E_full; 1 when both are zero (nothing stored), infinite when only the full
    energy is zero."""
    if full == 0:
        return 1.0 if reduced == 0 else float("inf")
    return reduced / full


def verdict(rms: float, loop_length: float, ratio: float, unit: str = "") -> tuple[bool, str]:
    """(reduced is good enough, the line saying so) from the RMS centreline distance, the loop
    length L (same unit) and E_reduced / E_full: good when rms <= :data:`RMS_LOOPS_OK` L and
    |ratio - 1| <= :data:`ENERGY_REL_OK`."""
    loops, excess = rms / loop_length, abs(ratio - 1)
    limits = f"limits {RMS_LOOPS_OK:g} L and {ENERGY_REL_OK * 100:g} %"
    if loops <= RMS_LOOPS_OK and excess <= ENERGY_REL_OK:
        return True, (f"verdict: the reduced model is within {loops:.2g} loop lengths RMS and "
                      f"{excess * 100:.2g} % energy of the full model ({limits})")
    distance = f"{rms:.3g} {unit}".rstrip()
    return False, (f"verdict: use the full model (reduced differs by {distance} RMS = "
                   f"{loops:.2g} loop lengths, energy {ratio:.3g}x; {limits})")


@dataclass(frozen=True)
class GridRow:
    """One even k × k reduced grid against the full model (``compare --grids``): the
    accuracy-against-time frontier, as plain data."""

    k: int
    courses: list[int]                # the representatives solved (clamped ones added)
    wales: list[int]
    n_parameters: int
    success: bool
    seconds: float                    # build + solve
    speedup: float                    # full (build + solve) over this grid's
    distance_rms: float               # centreline distance to the full solution (length units)
    distance_max: float
    energy_ratio: float               # E_grid / E_full
    ok: bool | None                   # within the verdict's limits (None: a solve failed)

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def _cost(r: WeftResult) -> float:
    """Build + solve time of a result (s)."""
    return r.build_s + r.report.solve_s


def grid_row(k: int, full: WeftResult, reduced: WeftResult, samples: int = SAMPLES) -> GridRow:
    """The frontier's row of the even k × k grid solved as ``reduced``: its
    :class:`Comparison` with the full model, as plain data."""
    cmp = Comparison(full, reduced, None, samples)
    reps = cmp.representatives or {}
    return GridRow(k, list(reps.get("courses", [])), list(reps.get("wales", [])),
                   reduced.nlp.n_parameters, reduced.success, _cost(reduced),
                   cmp.speedup_reduced, cmp.distance_rms, cmp.distance_max, cmp.energy_ratio,
                   cmp.reduced_ok)


@dataclass(repr=False)
class Comparison:
    """Full and reduced models of one problem side by side, and (when asked for) the full model
    warm-started from the reduced; distances between corresponding centreline points."""

    full: WeftResult
    reduced: WeftResult
    full_warm_from_reduced: WeftResult | None = None
    samples: int = SAMPLES
    frontier: list[GridRow] = field(default_factory=list)   # compare --grids: even k × k grids

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
        return _cost(self.full) / _cost(self.reduced)

    @property
    def fastest_ok(self) -> GridRow | None:
        """The fastest grid of the frontier within the verdict's limits (None: none is, and the
        full model is the one to use; where its ``speedup`` is below 1 it is slower than the
        full model, which is then the one to use too)."""
        good = [g for g in self.frontier if g.ok]
        return max(good, key=lambda g: g.speedup) if good else None

    @property
    def energy_ratio(self) -> float:
        """Reduced over full stored energy."""
        return _energy_ratio(self.reduced.energy.total, self.full.energy.total)

    @property
    def reduced_ok(self) -> bool | None:
        """Whether the reduced model is good enough (:func:`verdict`); None when the full or
        the reduced solve did not converge."""
        return self._verdict[0]

    @property
    def verdict(self) -> str:
        """One line: use the full model, or the reduced one is within the limits."""
        return self._verdict[1]

    @cached_property
    def _verdict(self) -> tuple[bool | None, str]:
        failed = [k for k in ("full", "reduced") if not self.models()[k].success]
        if failed:
            return None, f"verdict: none (the {' and '.join(failed)} model did not converge)"
        pr = self.full.problem
        return verdict(self.distance_rms, pr.L, self.energy_ratio, pr.units.length)

    @property
    def representatives(self) -> dict[str, Any] | None:
        """The reduced model's grid: representative ``courses`` and ``wales`` (and ``asked``
        when the clamped ones were added), as in its result JSON."""
        return self.reduced.representatives()

    # the results contract (knit_nlp/outcome.py): every model solved converged
    @property
    def success(self) -> bool:
        return all(r.success for r in self.models().values())

    def _failed(self) -> dict[str, WeftResult]:
        return {name: r for name, r in self.models().items() if not r.success}

    @property
    def status(self) -> str:
        """The first model that did not converge's status (full, reduced, warm-started), or
        the full model's (``Solve_Succeeded``) when all did."""
        return next(iter(self._failed().values()), self.full).status

    @property
    def message(self) -> str:
        """One sentence: every model converged, or which did not and why."""
        failed = self._failed()
        if not failed:
            return "converged: " + " and ".join(self.models()) + " models"
        return "; ".join(f"the {name} model: {r.message}" for name, r in failed.items())

    def models(self) -> dict[str, WeftResult]:
        """The models solved: full, reduced and, when asked for, full_warm_from_reduced."""
        warm = self.full_warm_from_reduced
        return {"full": self.full, "reduced": self.reduced,
                **({"full_warm_from_reduced": warm} if warm is not None else {})}

    def _warm_json(self) -> dict[str, Any] | None:
        warm = self.full_warm_from_reduced
        if warm is None:
            return None
        return {"energy_minus_full": warm.energy.total - self.full.energy.total}

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
                "energy_gap": self.energy_gap, "energy_ratio": self.energy_ratio,
                "speedup_reduced": self.speedup_reduced,
                "representatives": self.representatives,
                "fabric": {"courses": self.full.problem.courses,
                           "wales": self.full.problem.wales},
                "loop_length": self.full.problem.L,
                "verdict": {"reduced_ok": self.reduced_ok, "text": self.verdict,
                            "rms_loop_lengths": self.distance_rms / self.full.problem.L,
                            "limits": {"rms_loop_lengths": RMS_LOOPS_OK,
                                       "energy_relative": ENERGY_REL_OK}},
                "warm": self._warm_json(),
                **({"frontier": {"grids": [g.to_json() for g in self.frontier],
                                 "fastest_ok": None if (best := self.fastest_ok) is None
                                 else best.k}} if self.frontier else {}),
                **({"adaptive": {**self.reduced.adaptive.to_json(),
                                 "true_rms": self.distance_rms}}
                   if self.reduced.adaptive is not None else {})}

    def save(self, out_dir: Path | str) -> list[Path]:
        """``DIR/<problem>.compare.json`` and the overlay ``.compare.png``."""
        from .plot import plot_overlay      # matplotlib (about 0.4 s) only when drawing
        name = self.full.problem.name
        js = write_json(Path(out_dir) / f"{name}.compare.json", self.to_json())
        png = plot_overlay(Path(out_dir) / f"{name}.compare.png",
                           self.full.centrelines(self.samples),
                           self.reduced.centrelines(self.samples),
                           f"{name}: full (black) vs reduced, max distance {self.distance_max:.3g} "
                           f"{self.full.problem.units.length}", self.full.problem.units)
        return [js, png]
