"""The model of one tensile test: the specimen fabric between two rigid clamps.

Pulled along the courses (``direction = "courses"``, the model's x) the clamps hold the side
edges (every course's yarn end: ``start`` of wale 1, ``end`` of wale n); along the wales
(``"wales"``, y) the bottom course at its sinker points (``start``) and the top course at its
heads (``head``). The first clamp stays; the second is translated along the pull. Its reaction
along the pull, per specimen width, is the fabric's stress; the axial strain is the change of
the clamps' separation over its natural value; the lateral strain is measured between the free
edges at mid-height, where a test's pins sit (the middle loop, or the mean of the middle two).

The specimen's loop counts follow the measured aspect ratio (gauge length over width): the
shorter side has ``min_loops`` loops and the longer side the count whose natural aspect ratio,
clamp separation over pitch width (courses × course spacing, or wales × wale spacing), is
nearest the measured one. A problem file's own ``[fabric]`` overrides that choice.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...transcription.rows import rigid_natural_points
from ...model.problem import WeftProblem, parse_problem

DIRECTIONS = ("courses", "wales")
MAX_LOOPS = 200                    # along the pull, from the aspect ratio
PULLED = 2                         # the moving rigid clamp's number


class PullReading:
    """What every test's model reads alike (a clamped ``Specimen``, a periodic
    ``cell.CellSpecimen``): the pull's axis and the natural aspect ratio."""

    direction: str
    gauge: float
    pitch_width: float

    @property
    def axis(self) -> int:
        """0: the pull is along x; 1: along y."""
        return DIRECTIONS.index(self.direction)

    @property
    def aspect(self) -> float:
        return self.gauge / self.pitch_width


@dataclass(frozen=True)
class Specimen(PullReading):
    """A built test: its weft problem and how to read stress and strains from a solution."""

    problem: WeftProblem
    direction: str
    gauge: float                   # natural clamp separation L0 (length units)
    pitch_width: float             # courses · c (x pull) or wales · w (y pull)
    lateral_points: tuple[tuple[tuple[tuple[int, int], float], ...], ...]   # (low edge, high edge)
    lateral_width: float           # natural distance between the free edges' points
    kind: str = "clamped"

    @property
    def courses(self) -> int:
        return self.problem.courses

    @property
    def wales(self) -> int:
        return self.problem.wales

    @property
    def label(self) -> str:
        return f"{self.courses} x {self.wales} loops between rigid clamps"

    def translation(self, u: float) -> list[float]:
        """The pulled clamp's motion (tx, ty, rotation) for a pull of ``u``."""
        motion = [0.0, 0.0, 0.0]
        motion[self.axis] = float(u)
        return motion


def _middle(count: int) -> list[int]:
    """1-based index of the middle loop (odd count) or of the middle two (even)."""
    return [(count + 1) // 2] if count % 2 else [count // 2, count // 2 + 1]


def grips(direction: str) -> list[dict[str, Any]]:
    """The two rigid clamps of a pull along ``direction`` (problem-file tables)."""
    if direction == "courses":
        return [{"edge": "left"}, {"edge": "right"}]
    return [{"edge": "bottom", "point": "start"}, {"edge": "top", "point": "head"}]


def loop_counts(base: WeftProblem, direction: str, aspect: float,
                min_loops: int) -> tuple[int, int]:
    """(courses, wales) of the specimen for a measured gauge/width ``aspect``: ``min_loops``
    on the shorter side, the longer side's count the one nearest the aspect (module doc)."""
    head = float(np.diff(base.natural_xy([0.0, 0.5 * base.L])[:, 1])[0])
    w, c = base.lattice
    sides = [(min_loops, k) for k in range(min_loops, MAX_LOOPS + 1)]       # (along, across)
    sides += [(k, min_loops) for k in range(min_loops + 1, MAX_LOOPS + 1)]

    def miss(side: tuple[int, int]) -> float:
        m, n = _courses_wales(direction, *side)
        if direction == "courses":          # clamps on the yarn ends: n wale spacings apart
            gauge, width = n * w, m * c
        else:                               # sinkers of course 1 to heads of course m
            gauge, width = (m - 1) * c + head, n * w
        return abs(np.log(gauge / width / aspect))
    return _courses_wales(direction, *min(sides, key=miss))


def _courses_wales(direction: str, along: int, across: int) -> tuple[int, int]:
    return (across, along) if direction == "courses" else (along, across)


def _pitch_width(base: WeftProblem, direction: str, m: int, n: int) -> float:
    w, c = base.lattice
    return m * c if direction == "courses" else n * w


def specimen_doc(doc: dict[str, Any], direction: str, courses: int, wales: int,
                 name: str) -> dict[str, Any]:
    """The weft problem document of a test: the spec's own tables, the specimen's size and the
    two rigid clamps."""
    out = copy.deepcopy(doc)
    out["name"] = name
    out["fabric"] = {"courses": courses, "wales": wales}
    out["rigid_clamp"] = grips(direction)
    return out


def build_specimen(doc: dict[str, Any], source: str, direction: str, courses: int,
                   wales: int, name: str) -> Specimen:
    """Parse the test's problem and locate its clamps and lateral points."""
    pr = parse_problem(specimen_doc(doc, direction, courses, wales, name), source)
    clamp_pts = rigid_natural_points(pr)
    axis = DIRECTIONS.index(direction)
    gauge = float(clamp_pts[1][:, axis].mean() - clamp_pts[0][:, axis].mean())
    L = pr.L
    if direction == "courses":
        low = tuple(((1, j), 0.0) for j in _middle(wales))
        high = tuple(((courses, j), 0.5 * L) for j in _middle(wales))
    else:
        low = tuple(((i, 1), 0.0) for i in _middle(courses))
        high = tuple(((i, wales), L) for i in _middle(courses))
    other = 1 - axis
    lateral = float(np.mean([pr.natural_position(lp, s)[other] for lp, s in high])
                    - np.mean([pr.natural_position(lp, s)[other] for lp, s in low]))
    return Specimen(pr, direction, gauge, _pitch_width(pr, direction, courses, wales),
                    (low, high), lateral)
