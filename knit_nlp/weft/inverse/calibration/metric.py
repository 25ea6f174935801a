"""The measure of agreement between a model curve and a measured test (issue 20, item 3).

For each force F of the metric (by default 2, 5, 10, 15, 20 and 25 N): every run is read at its
first frame whose force reaches F (strain from the run's first frame, as the reader gives it);
the median over runs is compared with the model's strain at F, interpolated on its curve.
``rms_strain_error`` is the root mean square of the differences over the forces, for the axial
strain and, where the test measured it, the lateral strain.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....errors import ProblemError
from .measured import MeasuredTest, Run

METRIC_FORCES = (2.0, 5.0, 10.0, 15.0, 20.0, 25.0)      # N


def first_reaching(run: Run, force: float) -> int | None:
    """Index of the run's first frame whose force is at least ``force`` (None: never)."""
    hits = np.flatnonzero(run.force >= force)
    return int(hits[0]) if hits.size else None


def check_reaches(test: MeasuredTest, forces: tuple[float, ...], where: str) -> None:
    """Every run reaches the largest force the metric reads it at, else one ProblemError."""
    top = max(forces)
    for run in test.runs:
        if first_reaching(run, top) is None:
            raise ProblemError(test.path, f"run {run.label}", "force_N",
                               f"no frame reaches {top:g} N (the run's largest force is "
                               f"{run.force.max():g} N); the metric reads every run at {where} "
                               f"= {list(forces)}: lower them or leave the run out")


def levels(test: MeasuredTest, forces: tuple[float, ...] | np.ndarray,
           lateral: bool = False) -> np.ndarray:
    """(runs, forces) strains of every run at its first frame reaching each force."""
    out = np.empty((len(test.runs), len(forces)))
    for r, run in enumerate(test.runs):
        series = run.lateral if lateral else run.axial
        for k, force in enumerate(forces):
            idx = first_reaching(run, force)
            out[r, k] = np.nan if idx is None or series is None else series[idx]
    return out


@dataclass(frozen=True)
class MetricPoints:
    """The metric of one test: measured medians and model strains at the metric forces."""

    forces: tuple[float, ...]
    measured_axial: np.ndarray
    model_axial: np.ndarray
    measured_lateral: np.ndarray | None
    model_lateral: np.ndarray | None

    @property
    def rms_axial(self) -> float | None:
        return rms(self.model_axial - self.measured_axial)

    @property
    def rms_lateral(self) -> float | None:
        if self.measured_lateral is None or self.model_lateral is None:
            return None
        return rms(self.model_lateral - self.measured_lateral)

    def to_json(self) -> dict:
        rows = []
        for k, force in enumerate(self.forces):
            row = {"force_N": force, "measured_axial": self.measured_axial[k],
                   "model_axial": self.model_axial[k]}
            if self.measured_lateral is not None and self.model_lateral is not None:
                row.update(measured_lateral=self.measured_lateral[k],
                           model_lateral=self.model_lateral[k])
            rows.append(row)
        return {"axial": self.rms_axial, "lateral": self.rms_lateral, "points": rows}


def rms(diff: np.ndarray) -> float | None:
    """RMS of the differences; None when the model did not reach every force (NaN)."""
    diff = np.asarray(diff, dtype=float)
    return None if diff.size == 0 or not np.all(np.isfinite(diff)) else float(
        np.sqrt(np.mean(diff ** 2)))


def metric(test: MeasuredTest, forces: tuple[float, ...], model_axial: np.ndarray,
           model_lateral: np.ndarray | None) -> MetricPoints:
    """The metric of ``test`` against the model's strains at ``forces`` (NaN: not reached)."""
    axial = np.median(levels(test, forces), axis=0)
    lateral = np.median(levels(test, forces, lateral=True), axis=0) if test.has_lateral else None
    return MetricPoints(tuple(forces), axial, np.asarray(model_axial, dtype=float), lateral,
                        None if lateral is None or model_lateral is None
                        else np.asarray(model_lateral, dtype=float))
