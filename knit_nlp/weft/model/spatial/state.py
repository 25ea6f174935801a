"""The independent 3-D check of a problem's answer (``proximity.check_3d``): the samples per
loop, the natural centrelines the designed crossings are read on, and the report."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..centrelines import SAMPLES as CENTRELINE_SAMPLES
from ..contact.pairs import SAMPLES, check_samples
from .proximity import ProximityReport, check_3d, natural_lines

if TYPE_CHECKING:
    from ..problem import WeftProblem


def spatial_samples(problem: WeftProblem, samples: int = SAMPLES) -> int:
    """Samples per loop of the 3-D check: ``check_samples`` (4 per radius, at least 16, at
    most ``samples``), and never fewer than the result pictures' 61."""
    return max(CENTRELINE_SAMPLES, check_samples(problem.L, problem.yarn.radius, samples))


def spatial_natural(problem: WeftProblem, samples: int) -> np.ndarray:
    """The natural 3-D centrelines the check reads the designed crossings on
    (``proximity.natural_lines``)."""
    return natural_lines(problem.yarn.natural3d, problem.wales, samples)


def spatial_state(problem: WeftProblem, centrelines: np.ndarray) -> ProximityReport:
    """The independent 3-D check of deformed centrelines (m, n, S, 3) of a problem."""
    yarn = problem.yarn
    return check_3d(centrelines, spatial_natural(problem, centrelines.shape[2]), problem.L,
                    yarn.radius, yarn.core_radius)
