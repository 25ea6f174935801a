"""A weft-knit problem: read from TOML, checked completely before any symbolic work.

The contract is the README's "Weft problem files"; every rule a bad file can break raises
:class:`~knit_nlp.errors.ProblemError` naming file, table and key.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ..errors import ProblemError
from ..tomlio import Table, load_toml
from .basis import n_coeffs
from .crossings import LABELS, CrossingError, Crossings, find_crossings
from .parametrisation import Full, Parametrisation, Reduced
from .natural import PRESETS, NaturalLoop, natural_loop, natural_starts, preset_coeffs

# Gauss-Legendre nodes per panel. Panels break at every material point the model needs and are
# at most L/4 long; on the 10 x 10 diagonal pull 8 nodes give energy within 7e-12 (relative) and
# centrelines within 5e-10 of 32 nodes, while 16 nodes cost twice the function evaluations.
DEFAULT_NODES = 8


@dataclass(frozen=True)
class Clamp:
    """Fix the position (some coordinates) and optionally the tangent angle of a material point.

    ``loop`` is 1-based (course, wale); ``target`` the absolute position (a given displacement is
    converted); ``fix`` which of x, y are held.
    """

    loop: tuple[int, int]
    point: str | float
    s: float
    target: np.ndarray
    fix: tuple[bool, bool] = (True, True)
    angle: float | None = None


@dataclass(frozen=True)
class RigidClamp:
    """Points that move together as one rigid body: each goes to centre + R(rotation)(P0 − centre)
    + translation, P0 its natural position (a line clamp is the usual case)."""

    points: tuple[tuple[tuple[int, int], str | float, float], ...]   # (loop, label, s)
    translation: np.ndarray
    rotation: float
    centre: np.ndarray


@dataclass(frozen=True)
class Load:
    """A point force and/or moment doing work on the fabric at a material point."""

    loop: tuple[int, int]
    point: str | float
    s: float
    force: np.ndarray
    moment: float = 0.0


@dataclass(frozen=True)
class SolverOptions:
    """IPOPT tolerance and iteration limit; continuation steps (None: only when needed)."""

    tol: float = 1e-8
    max_iter: int = 3000
    continuation: int | None = None


@dataclass(frozen=True)
class WeftProblem:
    """Everything needed to build and solve one weft-knit NLP."""

    model: ClassVar[str] = "weft"

    name: str
    description: str
    courses: int
    wales: int
    natural: NaturalLoop
    crossings: Crossings | None
    quadrature_nodes: int = 8
    k_a: float = 1.0
    k_b: float = 0.01
    R_f: float = 1.0
    clamps: tuple[Clamp, ...] = ()
    loads: tuple[Load, ...] = ()
    rigid_clamps: tuple[RigidClamp, ...] = ()
    reduction: Reduced | None = None
    solver: SolverOptions = field(default_factory=SolverOptions)
    source: str = "<memory>"

    @property
    def t(self) -> int:
        return self.natural.harmonics

    @property
    def L(self) -> float:
        return self.natural.length

    @property
    def n_loops(self) -> int:
        return self.courses * self.wales

    @property
    def parametrisation(self) -> Parametrisation:
        """The file's default: ``Reduced`` when it has a ``[reduction]`` table, else ``Full``."""
        return self.reduction or Full()

    def natural_starts(self) -> np.ndarray:
        """Natural start point of every loop, (m, n, 2)."""
        return natural_starts(self.natural, self.courses, self.wales)

    def natural_position(self, loop: tuple[int, int], s: float) -> np.ndarray:
        """Natural position of the material point s of a 1-based loop."""
        i, j = loop
        return self.natural_starts()[i - 1, j - 1] + self.natural.xy([s])[0]


def load_problem(path: Path | str) -> WeftProblem:
    """Read and check a weft problem file."""
    path = Path(path)
    return parse_problem(load_toml(path), path)


def parse_problem(doc: dict[str, Any], source: Path | str) -> WeftProblem:
    """Check a parsed TOML document against the contract and build a :class:`WeftProblem`.

    ``source`` names the document in messages (its file) and gives the default ``name``."""
    top = Table(doc, source, "")
    name = top.string("name", Path(source).stem)
    description = top.string("description", "")
    top.string("model", "weft", choices=("weft",))
    fab = top.table("fabric", required=True)
    m, n = fab.integer("courses", minimum=1), fab.integer("wales", minimum=1)
    fab.finish()
    natural, nodes, geometry_key, loop_tab = _read_loop(top.table("loop"))
    crossings = None
    try:
        crossings = find_crossings(natural)
    except CrossingError as err:
        if m >= 2:
            raise loop_tab.error(geometry_key, f"natural geometry rejected: {err}") from None
    mat = top.table("material")
    k_a = mat.number("k_a", 1.0, nonnegative=True)
    k_b = mat.number("k_b", 0.01, nonnegative=True)
    R_f = mat.number("R_f", 1.0, nonnegative=True)
    mat.finish()
    points = _PointReader(m, n, natural, crossings)
    starts = natural_starts(natural, m, n)
    clamps = tuple(_read_clamp(t, points, natural, starts) for t in top.tables("clamp"))
    rigid = tuple(_read_rigid(t, points, natural, starts) for t in top.tables("rigid_clamp"))
    _check_overconstraint(top, clamps, rigid, points)
    loads = tuple(_read_load(t, points) for t in top.tables("load"))
    reduction = _read_reduction(top, m, n) if top.has("reduction") else None
    solver = _read_solver(top.table("solver"))
    top.finish()
    return WeftProblem(name, description, m, n, natural, crossings, nodes, k_a, k_b, R_f,
                       clamps, loads, rigid, reduction, solver, str(source))


def _read_loop(tab: Table) -> tuple[NaturalLoop, int, str, Table]:
    preset = tab.string("preset", "jersey", choices=PRESETS)
    L = tab.number("length", 10.0, positive=True)
    t = tab.integer("harmonics", 3)
    if t < 1:
        raise tab.error("harmonics", f"must be a positive integer, got {t}")
    key = "preset"
    if tab.has("natural_coefficients"):
        coeffs = np.array(tab.numbers("natural_coefficients", length=n_coeffs(t)))
        key = "natural_coefficients"
    else:
        coeffs = preset_coeffs(preset, t)
    spacing = tab.number("course_spacing", None, positive=True)
    if tab.has("course_spacing"):
        key = "course_spacing" if key == "preset" else key
    nodes = tab.integer("quadrature_nodes", DEFAULT_NODES)
    if nodes < 2:
        raise tab.error("quadrature_nodes", f"must be at least 2, got {nodes}")
    tab.finish()
    return natural_loop(coeffs, L, t, spacing), nodes, key, tab


class _PointReader:
    """Resolves ``loop`` and ``point`` keys of clamp and load tables to (i, j) and s."""

    def __init__(self, m: int, n: int, natural: NaturalLoop, crossings: Crossings | None) -> None:
        self.m, self.n, self.natural, self.crossings = m, n, natural, crossings

    def loop(self, tab: Table) -> tuple[int, int]:
        i, j = tab.integers("loop", length=2)
        if not (1 <= i <= self.m and 1 <= j <= self.n):
            raise tab.error("loop", f"[{i}, {j}] is outside the {self.m} x {self.n} fabric "
                            f"(courses 1..{self.m}, wales 1..{self.n})")
        return i, j

    def point(self, tab: Table) -> tuple[str | float, float]:
        value = tab.value("point")
        L = self.natural.length
        if isinstance(value, str):
            if value == "start":
                return value, 0.0
            if value == "end":
                return value, L
            if value not in LABELS:
                raise tab.error("point", f"unknown point label {value!r}; use start, end, "
                                f"{' '.join(LABELS)} or a number s in [0, {L:g}]")
            if self.crossings is None:
                raise tab.error("point", f"label {value!r} needs crossings, which this "
                                "natural geometry does not have; give a number s instead")
            return value, self.crossings.s[value]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise tab.error("point", "expected a label string or a number s")
        if not 0.0 <= value <= L:
            raise tab.error("point", f"s = {value:g} is outside [0, {L:g}]")
        return float(value), float(value)


def _read_clamp(tab: Table, points: _PointReader, natural: NaturalLoop,
                starts: np.ndarray) -> Clamp:
    tab.allow("loop", "point", "position", "displacement", "fix", "angle")
    loop = points.loop(tab)
    label, s = points.point(tab)
    fix = tab.strings("fix", ["x", "y"], choices=("x", "y"))
    if len(set(fix)) != len(fix):
        raise tab.error("fix", "lists a coordinate twice")
    angle = tab.number("angle", None)
    if not fix and angle is None:
        raise tab.error("fix", "an empty fix list needs an angle, or the clamp holds nothing")
    has_pos, has_disp = tab.has("position"), tab.has("displacement")
    if has_pos and has_disp or (fix and not (has_pos or has_disp)):
        raise tab.error("position", "give exactly one of position and displacement")
    natural = starts[loop[0] - 1, loop[1] - 1] + natural.xy([s])[0]
    if has_pos:
        target = np.array(tab.numbers("position", length=2))
    else:
        target = natural + np.array(tab.numbers("displacement", [0.0, 0.0], length=2))
    tab.finish()
    return Clamp(loop, label, s, target, ("x" in fix, "y" in fix), angle)


def _read_rigid(tab: Table, points: _PointReader, natural: NaturalLoop,
                starts: np.ndarray) -> RigidClamp:
    tab.allow("points", "translation", "rotation", "centre")
    pts = []
    for sub in tab.tables("points"):
        sub.name = f"{tab.name}.{sub.name}"
        sub.allow("loop", "point")
        loop = points.loop(sub)
        label, s = points.point(sub)
        sub.finish()
        pts.append((loop, label, s))
    if not pts:
        raise tab.error("points", "a rigid clamp needs at least one point")
    p0 = np.array([starts[lp[0] - 1, lp[1] - 1] + natural.xy([s])[0] for lp, _, s in pts])
    translation = np.array(tab.numbers("translation", [0.0, 0.0], length=2))
    rotation = tab.number("rotation", 0.0)
    centre = np.array(tab.numbers("centre", p0.mean(axis=0).tolist(), length=2))
    tab.finish()
    return RigidClamp(tuple(pts), translation, rotation, centre)


def _read_load(tab: Table, points: _PointReader) -> Load:
    tab.allow("loop", "point", "force", "moment")
    loop = points.loop(tab)
    label, s = points.point(tab)
    if not (tab.has("force") or tab.has("moment")):
        raise tab.error("force", "a load needs force = [fx, fy] and/or moment = M")
    force = np.array(tab.numbers("force", [0.0, 0.0], length=2))
    moment = tab.number("moment", 0.0)
    tab.finish()
    return Load(loop, label, s, force, moment)


def canonical_point(loop: tuple[int, int], s: float, L: float, n: int) -> tuple[int, int, float]:
    """One name for one material point: the end of loop (i, j<n) is the start of (i, j+1)."""
    i, j = loop
    if j < n and abs(s - L) <= 1e-12 * L:
        return i, j + 1, 0.0
    return i, j, round(s, 12)


def _check_overconstraint(top: Table, clamps: tuple[Clamp, ...], rigid: tuple[RigidClamp, ...],
                          points: _PointReader) -> None:
    """No coordinate or angle of one material point may be held twice."""
    held: dict[tuple[Any, ...], str] = {}
    L, n = points.natural.length, points.n

    def hold(table: str, key: str, loop: tuple[int, int], s: float, label: Any, dof: str) -> None:
        where = (canonical_point(loop, s, L, n), dof)
        if where in held:
            raise ProblemError(top.file, table, key, f"over-constrains loop {list(loop)} point "
                               f"{label!r}: its {dof} is already held by {held[where]}")
        held[where] = table

    for k, c in enumerate(clamps):
        for dof in [d for d, f in zip("xy", c.fix) if f]:
            hold(f"clamp[{k + 1}]", "fix", c.loop, c.s, c.point, dof)
        if c.angle is not None:
            hold(f"clamp[{k + 1}]", "angle", c.loop, c.s, c.point, "angle")
    for k, r in enumerate(rigid):
        for q, (loop, label, s) in enumerate(r.points):
            for dof in "xy":
                hold(f"rigid_clamp[{k + 1}]", f"points[{q + 1}]", loop, s, label, dof)


def _read_reduction(top: Table, m: int, n: int) -> Reduced:
    tab = top.table("reduction")
    courses = tab.integers("representative_courses", [1, m] if m > 1 else [1])
    wales = tab.integers("representative_wales", [1, n] if n > 1 else [1])
    for key, values, last in (("representative_courses", courses, m),
                              ("representative_wales", wales, n)):
        if not values or values[0] != 1 or values[-1] != last:
            raise tab.error(key, f"must start at 1 and end at {last}")
        if any(b <= a for a, b in zip(values[:-1], values[1:])):
            raise tab.error(key, "must be strictly increasing")
    tab.finish()
    return Reduced(tuple(courses), tuple(wales))


def _read_solver(tab: Table) -> SolverOptions:
    d = SolverOptions()
    tol = tab.number("tol", d.tol, positive=True)
    max_iter = tab.integer("max_iter", d.max_iter, minimum=1)
    steps = tab.integer("continuation", d.continuation, minimum=1)
    tab.finish()
    return SolverOptions(tol, max_iter, steps)
