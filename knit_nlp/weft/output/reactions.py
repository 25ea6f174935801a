"""What a solved weft model reports at its clamps and loads, and the view of a solution the
pictures and loading paths draw from (:class:`SolvedFabric`).

Sign convention (eqs. 13, 18-19 with clamp rows g = P − target): CasADi's multipliers make
∇f + Jᵀλ = 0, so the force a clamp applies to the fabric, which balances the elastic force
−∂U/∂P, is −λ. Clamps, loads and rigid clamps are numbered from 1 in ``number``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ...outcome import Energy
from ..model.problem import WeftProblem


@dataclass(frozen=True)
class ClampReaction:
    """One clamp after the solve: where its point ended, its target and the clamp's force
    (and moment, for an angle clamp) on the fabric."""

    number: int
    loop: tuple[int, int]
    point: str | float
    position: np.ndarray
    target: np.ndarray
    fix: tuple[str, ...]
    reaction: np.ndarray
    angle: float | None = None
    reaction_moment: float | None = None
    group: str | None = None         # the file's table when a shorthand made this clamp
    table: str = ""                  # the file's table ("clamp[2]"), "" when built in Python

    @property
    def grip(self) -> str:
        """The name users know this clamp's grip by: its file table, else ``clamp N``."""
        return self.table or f"clamp {self.number}"

    def to_json(self) -> dict[str, Any]:
        out = {"loop": list(self.loop), "point": self.point, "position": self.position.tolist(),
               "reaction": self.reaction.tolist(), "target": self.target.tolist(),
               "fix": list(self.fix)}
        if self.table:
            out["table"] = self.table
        if self.angle is not None:
            out.update(angle=self.angle, reaction_moment=self.reaction_moment)
        if self.group:
            out["group"] = self.group
        return out


@dataclass(frozen=True)
class RigidClampReaction:
    """One rigid clamp: its points' positions and reactions, its motion, the total force and
    the moment of the reactions about the moved centre."""

    number: int
    points: tuple[tuple[tuple[int, int], str | float], ...]
    positions: np.ndarray            # (k, 2)
    reactions: np.ndarray            # (k, 2)
    translation: np.ndarray
    rotation: float
    centre: np.ndarray

    @property
    def force(self) -> np.ndarray:
        return self.reactions.sum(axis=0)

    @property
    def moment(self) -> float:
        arm = self.positions - (self.centre + self.translation)
        return float(np.sum(arm[:, 0] * self.reactions[:, 1] - arm[:, 1] * self.reactions[:, 0]))

    def to_json(self) -> dict[str, Any]:
        return {"points": [{"loop": list(lp), "point": label, "position": pos.tolist(),
                            "reaction": f.tolist()}
                           for (lp, label), pos, f in zip(self.points, self.positions,
                                                           self.reactions)],
                "translation": self.translation.tolist(), "rotation": self.rotation,
                "centre": self.centre.tolist(), "force": self.force.tolist(),
                "moment": self.moment}


@dataclass(frozen=True)
class LoadResult:
    """One point load and where its point ended."""

    number: int
    loop: tuple[int, int]
    point: str | float
    force: np.ndarray
    moment: float
    position: np.ndarray
    group: str | None = None

    def to_json(self) -> dict[str, Any]:
        out = {"loop": list(self.loop), "point": self.point, "force": self.force.tolist(),
               "moment": self.moment, "position": self.position.tolist()}
        if self.group:
            out["group"] = self.group
        return out


class SolvedFabric(Protocol):
    """What a picture or a loading path reads of a solution (``WeftResult`` has it)."""

    problem: WeftProblem
    model: str
    success: bool
    energy: Energy
    clamps: list[ClampReaction]
    rigid_clamps: list[RigidClampReaction]
    loads: list[LoadResult]
