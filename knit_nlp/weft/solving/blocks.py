"""The typed blocks a forward solve's variant adds to its result (docs/weft_files.md, "Result
JSON"): ``contact`` (a solve with a yarn radius, ``contact.equilibrium.contact_block``),
``adaptive`` (the adaptive representatives' refinement, ``adaptive``) and ``warm_start`` (the
full model started from the reduced one, ``api.solve(warm_from_reduced=True)``). Each is a
frozen dataclass read by attribute; ``to_json()`` is the result JSON's block, key for key.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any


@dataclass(frozen=True)
class Contact:
    """One active contact: the two loops (course, wale; 1-based), the material coordinates
    of its two centreline points, their midpoint, the force (minus the gap row's multiplier,
    in the problem's force unit), the gap and the gap the pair requires."""

    loops: tuple[tuple[int, int], tuple[int, int]]
    s: tuple[float, float]
    point: tuple[float, float]
    force: float
    gap: float
    required: float

    def to_json(self) -> dict[str, Any]:
        return {"loops": [list(self.loops[0]), list(self.loops[1])], "s": list(self.s),
                "point": list(self.point), "force": self.force, "gap": self.gap,
                "required": self.required}


@dataclass(frozen=True)
class ContactBlock:
    """The result JSON's ``contact``: the radius, the route the solve took, the pairs in
    reach and the active contacts, the smallest gaps (free pairs: over 2r; thick-yarn pairs:
    over their requirement; None when there are none), the largest force, crossings against
    the natural fabric, and the effort (contact solves, the contact NLP's size)."""

    radius: float
    route: str
    pairs_in_reach: int
    active: int
    smallest_gap: float | None
    smallest_gap_over_2r: float | None
    thick_pairs: int
    thick_smallest_gap_over_required: float | None
    interlock_pairs: int
    largest_force: float
    force_unit: str
    new_crossings: int
    lost_designed_crossings: int
    contacts: tuple[Contact, ...]
    solves: int
    contact_nlp: dict[str, int]

    def to_json(self) -> dict[str, Any]:
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["contacts"] = [c.to_json() for c in self.contacts]
        out["contact_nlp"] = dict(self.contact_nlp)
        return out


@dataclass(frozen=True)
class AdaptiveBlock:
    """The result JSON's ``adaptive``: per grid refined its step (``AdaptiveStep.as_dict``:
    representatives, parameter count, energy, iterations, time, success, error estimate) and
    the last grid's ``estimate`` (the RMS centreline error it estimates)."""

    steps: tuple[dict[str, Any], ...]
    estimate: float

    def to_json(self) -> dict[str, Any]:
        return {"steps": [dict(st) for st in self.steps], "estimate": self.estimate}


@dataclass(frozen=True)
class WarmStart:
    """The result JSON's ``warm_start``: the full model started from the reduced model's
    lifted solution, and how that reduced solve went."""

    reduced_success: bool
    reduced_iterations: int
    reduced_solve_s: float

    def to_json(self) -> dict[str, Any]:
        return {"from": "reduced", "reduced_success": self.reduced_success,
                "reduced_iterations": self.reduced_iterations,
                "reduced_solve_s": self.reduced_solve_s}
