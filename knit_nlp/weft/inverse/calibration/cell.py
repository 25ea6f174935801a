"""A test's specimen as the 3-D model's periodic cell (``[calibrate] specimen = "periodic"``):
one loop repeated on its lattice, a fabric with no edges (``model.spatial.periodic``;
docs/real_fabric.md, "A periodic cell").

The measured specimens are 66.56 and 95.87 mm wide, tens of loops across; the free-edged model
specimens that ``calibrate`` solves within its time (3 loops across) are mostly edge. The cell is the other limit: no edges at all. Read as a
specimen (``CellSpecimen``, the same reading as ``specimen.Specimen``):

* the pull's travel u is the change of the lattice spacing along it, so the axial strain is
  u / gauge with gauge = the natural spacing along the pull (w₀ along the courses, c₀ along
  the wales);
* the force is the one through one cell (the pull row's multiplier, dU/d(spacing)), so the
  pitch width is the natural spacing across (c₀, or w₀): real force = F · W / pitch width, W
  the test's real width, as for the clamped specimens;
* the lateral strain is the change of the spacing across the pull over its natural value.

A curve is the same warm-started stepping as a clamped specimen's (``curve.CurveModel``); the
first node starts from the natural loop. Bent from a straight yarn (``[calibrate]
bending_reference = "straight"``, as the source's simulation) the loop is prestressed: the
first node is then the cell relaxed at zero force with both spacings free, and strains, force
per width and lateral strain are read from that relaxed lattice (``CellModel.lattice``).
The contact rigidity is a parameter of the cell's NLP (``takes_rigidity``), not the clamped
specimens' energy scale: the cell's equilibria are not unique, and the scaled NLP's IPOPT path
found another (``model.spatial.periodic``). Each node's check is the
model's own all-pairs check of 4 × 4 loops of the periodic fabric (``periodic.check_cell``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...model.problem import WeftProblem
from ...model.spatial.periodic import (SAMPLES, CellSolution, PeriodicCell, build_cell,
                                       cell_shape, check_cell, natural_state, solve_cell)
from .curve import Curve, CurveModel
from .specimen import PullReading


@dataclass(frozen=True)
class CellSpecimen(PullReading):
    """A test's periodic cell read as a specimen (module docstring)."""

    problem: WeftProblem
    direction: str
    gauge: float                  # natural spacing along the pull
    pitch_width: float            # natural spacing across it: the width one cell carries
    kind: str = "periodic"
    reference: str = "natural"    # the bending reference: the natural loop, or a straight yarn

    @property
    def lateral_width(self) -> float:
        """The lateral strain's reference: the same natural spacing across the pull."""
        return self.pitch_width

    @property
    def courses(self) -> None:
        return None

    @property
    def wales(self) -> None:
        return None

    @property
    def label(self) -> str:
        return ("a periodic cell (one loop, no edges)" if self.reference == "natural" else
                "a periodic cell (one loop, no edges) bent from a straight yarn")


@dataclass(frozen=True)
class CellNode:
    """One solve of a curve's cell and the unloaded cell's spacing across the pull that it is
    read per (the natural lattice's, or the straight yarn's relaxed one)."""

    solution: CellSolution
    across: float

    @property
    def x(self) -> np.ndarray:
        return self.solution.x

    @property
    def success(self) -> bool:
        return self.solution.success

    @property
    def status(self) -> str:
        return self.solution.status

    @property
    def iterations(self) -> int:
        return self.solution.iterations


def build_cell_specimen(problem: WeftProblem, direction: str, samples: int = SAMPLES,
                        reference: str = "natural") -> tuple[CellSpecimen, PeriodicCell]:
    """The cell of ``problem``'s 3-D yarn (its natural loop and compression law) pulled along
    ``direction``, bent from the natural loop or (``reference = "straight"``) from a straight
    yarn, and its specimen reading; ``[solver] max_iter`` and ``max_time`` bound each curve
    step, as a clamped specimen's."""
    yarn, opts = problem.yarn, problem.solver
    cell = build_cell(yarn.natural3d, yarn.shell(), direction, samples,
                      straight=reference == "straight", max_iter=opts.max_iter,
                      max_time=opts.max_time)
    return CellSpecimen(problem, direction, cell.spacing0, cell.across0,
                        reference=reference), cell


class CellModel(CurveModel):
    """A test's periodic cell and its curves (``curve.CurveModel``: params are (pulled
    spacing, R_f, k))."""

    spatial = True
    takes_rigidity = True
    # The cell is soft until its loops jam, then stiffens 7-20 times (docs/real_fabric.md):
    # steps aimed at even force increments grew to curve.MAX_STRAIN_STEP (10 % strain) on the
    # soft part and the jam fell between two nodes (measured, acrylic_3d_source's law: k x
    # 1.02-1.1 gave curves of 9 nodes ending at 617-4150 N, and the fit's residual jumped
    # between 0.118 and 0.148 in that range). Steps of at most 2.5 % put nodes on the jam.
    max_strain_step = 0.025

    def __init__(self, specimen: CellSpecimen, cell: PeriodicCell,
                 reference: str = "natural") -> None:
        self.specimen, self.cell, self.reference = specimen, cell, reference
        self._rests: dict[tuple[float, float], CellSolution] = {}

    def rest(self, R_f: float, k: float) -> CellSolution:
        """The unloaded cell at (R_f, k): bent from a straight yarn it is prestressed and
        relaxes at zero force, both spacings free, from the natural loop (cached)."""
        if (R_f, k) not in self._rests:
            self._rests[(R_f, k)] = solve_cell(self.cell, self.specimen.gauge, R_f,
                                               natural_state(self.cell.natural), free=True,
                                               rigidity=k)
        return self._rests[(R_f, k)]

    def lattice(self, R_f: float, k: float) -> tuple[float, float]:
        """The unloaded cell's spacings (along, across the pull) that strains are read from:
        the natural lattice, or the straight yarn's relaxed one at (R_f, k)."""
        if self.reference == "natural":
            return self.specimen.gauge, self.specimen.pitch_width
        x = self.rest(R_f, k).x
        return self.cell.along(x), self.cell.across(x)

    def unloaded_lattice(self, c: Curve) -> tuple[float, float]:
        """The lattice (w, c) of curve ``c``'s first node, the unloaded cell."""
        shape = cell_shape(self.cell, c.xs[0])
        return shape.wale_spacing, shape.course_spacing

    def params(self, material: dict[str, float], u: float) -> tuple[float, float, float]:
        """(pulled spacing, R_f, k): the travel u is the gauge's share of the strain, u/gauge,
        from the unloaded lattice (:meth:`lattice`)."""
        k = float(material.get("contact_rigidity", self.cell.rigidity))
        R_f = float(material["R_f"])
        along = self.lattice(R_f, k)[0]
        return along * (1.0 + float(u) / self.specimen.gauge), R_f, k

    def _solve(self, p: tuple[float, float, float], x0: np.ndarray | None, curve: Curve,
               p0: Any = None) -> CellNode:
        if x0 is None and self.reference == "straight":
            rep = self.rest(p[1], p[2])                   # the unloaded, relaxed cell
        else:
            start = natural_state(self.cell.natural) if x0 is None else x0
            rep = solve_cell(self.cell, p[0], p[1], start, rigidity=p[2])
        curve.solves += 1
        curve.iterations += rep.iterations
        return CellNode(rep, self.lattice(p[1], p[2])[1])

    def read(self, rep: CellNode) -> tuple[float, float]:
        """(force through one cell, spacing across), both per the unloaded cell's spacing
        across as the specimen's pitch width: the force at a real width W is then F·W over the
        unloaded spacing, and the lateral strain the spacing's change over it."""
        scale = self.specimen.pitch_width / rep.across
        return rep.solution.F * scale, self.cell.across(rep.x) * scale

    def multipliers(self, rep: CellNode) -> np.ndarray:
        return np.array([self.read(rep)[0]])

    def check(self, x: np.ndarray) -> dict[str, Any]:
        block = check_cell(self.cell, x).block(self.specimen.problem.units.length)
        block["fabric"] = "4 x 4 loops of the periodic cell"
        return block
