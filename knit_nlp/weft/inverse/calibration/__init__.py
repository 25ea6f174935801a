"""Calibration of the weft model on measured tensile tests (``knit-nlp calibrate``).

Reading order follows the pipeline: ``measured`` (test CSVs) and ``metric`` (the measure of
agreement) -> ``spec`` (the spec file: a weft problem plus ``[[test]]`` and ``[calibrate]``) ->
``specimen`` (a test as a weft problem between two rigid clamps) -> ``curve`` (a test curve by
warm-started steps, with its sensitivities) -> ``fit`` (least squares in the logarithms,
standard errors) -> ``calibrate`` (the run) -> ``result`` and ``plot`` (the typed result and its
files) -> ``command`` (the CLI hook).
"""
from __future__ import annotations

from .calibrate import calibrate
from .result import CalibrationResult, TestOutcome
from .spec import CalibrationSpec, load_spec, parse_spec

__all__ = ["calibrate", "CalibrationResult", "TestOutcome", "CalibrationSpec", "load_spec",
           "parse_spec"]
