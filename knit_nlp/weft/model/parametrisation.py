"""How the loops' coefficients are parametrised: every loop free (:class:`Full`), or
interpolated from representative loops (:class:`Reduced`, eqs. 22-27; the map is in
``transcription.reduction``).

Both are plain values: ``transcribe(problem, Reduced((1, 5, 10), (1, 10)))``. :class:`Adaptive`
is a solve strategy that chooses the representatives itself (``solving.adaptive``); it never
reaches the transcription factory.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numpy as np


@dataclass(frozen=True)
class Full:
    """Every loop's 2t+2 coefficients are decision variables (continuity as constraints)."""

    name = "full"

    def resolve(self, courses: int, wales: int) -> "Full":
        return self


@dataclass(frozen=True)
class Reduced:
    """Representative courses and wales (1-based, strictly increasing, from 1 to m and n).

    ``None`` means the paper's corner form: the first and last course (wale).
    """

    courses: tuple[int, ...] | None = None
    wales: tuple[int, ...] | None = None
    name = "reduced"

    def resolve(self, courses: int, wales: int) -> "Reduced":
        """Concrete representatives for an m × n fabric (corners where not given), checked."""
        reps = []
        for given, last, what in ((self.courses, courses, "courses"), (self.wales, wales, "wales")):
            values = tuple(int(v) for v in given) if given is not None else (
                (1, last) if last > 1 else (1,))
            if not values or values[0] != 1 or values[-1] != last:
                raise ValueError(f"representative {what} must start at 1 and end at {last}; "
                                 f"got {list(values)}")
            if any(b <= a for a, b in zip(values[:-1], values[1:])):
                raise ValueError(f"representative {what} must be strictly increasing; "
                                 f"got {list(values)}")
            reps.append(values)
        return Reduced(*reps)


def spread(count: int, n: int) -> tuple[int, ...]:
    """``count`` indices spread evenly over 1..n, first and last included (all n when fewer)."""
    return tuple(sorted({int(round(v)) for v in np.linspace(1, n, min(count, n))}))


def even_grid(k: int, courses: int, wales: int) -> Reduced:
    """The even k × k grid of an m × n fabric: k representative courses and k wales spread
    evenly (k = 2: the paper's corner form; every course or wale where k exceeds them)."""
    return Reduced(spread(k, courses), spread(k, wales))


@dataclass(frozen=True)
class Adaptive:
    """Representatives chosen by refinement from the corners (``solving.adaptive``): refine
    until the estimated RMS centreline error is at most ``tolerance`` (length units; None:
    0.1·L) or the next grid would exceed ``max_parameters`` (None: 30 % of the full model's
    count)."""

    tolerance: float | None = None
    max_parameters: int | None = None


Parametrisation = Union[Full, Reduced, Adaptive]
