"""A weft-knit problem: read from TOML, checked completely before any symbolic work.

The contract is docs/weft_files.md; every rule a bad file can break raises
:class:`~knit_nlp.errors.ProblemError` naming file, table and key.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ...errors import ProblemError, quoted
from ...limits import check_memory, weft_bytes
from ...tomlio import Table, finite_number, load_toml
from ...outcome import SolverOptions as BaseSolverOptions
from ...units import Units, read_units
from .basis import n_coeffs
from .compression import ACRYLIC, SoftShell
from .reach import unreachable
from .crossing_points import LABELS, CrossingError, Crossings, find_crossings
from .parametrisation import Adaptive, Full, Parametrisation, Reduced
from .natural_loop import PRESETS, NaturalLoop, natural_loop, natural_starts, preset_coeffs
from .spatial.natural3d import NaturalShapeError, flat

GEOMETRIES = ("planar", "3d")
SPATIAL_KEYS = ("core_radius", "contact_rigidity", "contact_exponent", "elevation_modes",
                "crossing_springs", "friction")
MAX_ELEVATION_MODES = 12

# Gauss-Legendre nodes per panel. Panels break at every material point the model needs and are
# at most L/4 long; on the 10 x 10 diagonal pull 8 nodes give energy within 7e-12 (relative) and
# centrelines within 5e-10 of 32 nodes, while 16 nodes cost twice the function evaluations.
DEFAULT_NODES = 8
MAX_NODES = 64            # docs/limits.md
MAX_HARMONICS = 30
MAX_CONTINUATION = 1000

# Grip shorthands (docs/weft_files.md, "Grips"): which loops a clamp, rigid clamp or load table names.
EDGES = {"bottom": ("course", "first"), "top": ("course", "last"),
         "left": ("wale", "first"), "right": ("wale", "last")}
# The point an edge grips when the table gives none: the yarn's ends on the side edges.
EDGE_POINTS = {"left": "start", "right": "end"}
SELECTORS = ("loop", "course", "wale", "edge")
# Stitch landmarks beyond the paper's crossing labels: the loop's head (top of the needle loop).
LANDMARKS = {"head": 0.5}                  # fraction of the loop length L


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
    table: str = ""                  # the file's table, e.g. "clamp[3]"
    expanded: bool = False           # one of several clamps a course/wale/edge shorthand made
    key: str = "position"            # the table's key that gave the target (for messages)


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
    table: str = ""
    expanded: bool = False


@dataclass(frozen=True)
class Yarn:
    """The yarn's thickness (an extension of the paper's model, docs/contact.md): centrelines
    of yarn pieces that do not cross in the natural fabric stay 2·radius apart.

    ``geometry = "3d"`` (docs/weft3d.md): loops are space curves, the designed crossings
    persistent sliding contacts with the soft-shell law (``compression.SoftShell``: the
    other fields), ``elevation_modes`` harmonics q of the elevation angle, the paper's
    crossing springs only with ``crossing_springs``; ``friction`` μ of the lagged Coulomb
    friction at the designed crossings (0: none; ``model/spatial/friction.py``);
    ``natural3d`` the natural 3-D loop."""

    radius: float
    geometry: str = "planar"
    core_radius: float | None = None
    contact_rigidity: float | None = None
    contact_exponent: float | None = None
    elevation_modes: int = 0
    crossing_springs: bool = False
    friction: float = 0.0
    natural3d: Any = field(default=None, compare=False, repr=False)

    @property
    def spatial(self) -> bool:
        """True for the 3-D model."""
        return self.geometry == "3d"

    def shell(self) -> SoftShell:
        """The compression law of the 3-D model's crossings."""
        return SoftShell(self.radius, self.core_radius, self.contact_rigidity,
                         self.contact_exponent)


@dataclass(frozen=True)
class SolverOptions(BaseSolverOptions):
    """``[solver]``: the shared ``tol``, ``max_iter`` (IPOPT) and ``max_time`` (wall-clock budget
    in seconds of one solve, all its IPOPT calls together), and ``continuation``: steps to the
    targets (None: only when the direct solve fails)."""

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
    reduction: Reduced | Adaptive | None = None
    solver: SolverOptions = field(default_factory=SolverOptions)
    source: str = "<memory>"
    units: Units = field(default_factory=Units)
    yarn: Yarn | None = None          # None: the paper's model, no yarn contact

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
        """Natural start point of every loop, (m, n, 2): in the 3-D model on the natural 3-D
        fabric's lattice (docs/weft3d.md, N1: free for a thick yarn's wraps)."""
        if self.yarn is not None and self.yarn.spatial:
            return self.yarn.natural3d.starts(self.courses, self.wales)[..., :2]
        return natural_starts(self.natural, self.courses, self.wales)

    @property
    def lattice(self) -> tuple[float, float]:
        """(wale spacing, course spacing) of the natural fabric (3-D: its own lattice)."""
        if self.yarn is not None and self.yarn.spatial:
            sh = self.yarn.natural3d
            return sh.wale_spacing, sh.course_spacing
        return self.natural.wale_spacing, self.natural.course_spacing

    def natural_xy(self, s: np.ndarray | list[float]) -> np.ndarray:
        """Plan positions (len(s), 2) along a natural loop from its start (in the 3-D model the
        projection of the natural 3-D loop, docs/weft3d.md)."""
        if self.yarn is not None and self.yarn.spatial:
            return self.yarn.natural3d.xyz(s)[:, :2]
        return self.natural.xy(s)

    def tables(self, kind: str) -> list[list[int]]:
        """The 0-based indices of the points each of the file's ``[[kind]]`` tables made
        (``kind``: clamp, load or rigid_clamp), in file order: a course, wale or edge table
        makes several. A problem built in Python has one table per point."""
        if kind == "rigid_clamp":
            return [[q] for q in range(len(self.rigid_clamps))]
        points = self.clamps if kind == "clamp" else self.loads
        names = [p.table or f"point {q}" for q, p in enumerate(points)]
        return [[q for q, nm in enumerate(names) if nm == name] for name in dict.fromkeys(names)]

    def natural_position(self, loop: tuple[int, int], s: float) -> np.ndarray:
        """Natural position of the material point s of a 1-based loop (in the 3-D model the
        projection of the natural 3-D loop, docs/weft3d.md)."""
        i, j = loop
        return self.natural_starts()[i - 1, j - 1] + self.natural_xy([s])[0]


def load_problem(path: Path | str) -> WeftProblem:
    """Read and check a weft problem file."""
    path = Path(path)
    return parse_problem(load_toml(path), path)


def parse_problem(doc: dict[str, Any], source: Path | str) -> WeftProblem:
    """Check a parsed TOML document against the contract and build a :class:`WeftProblem`.

    ``source`` names the document in messages (its file) and gives the default ``name``."""
    top = Table(doc, source, "")
    name = top.stem("name")
    description = top.string("description", "")
    top.string("model", "weft", choices=("weft",))
    fab = top.table("fabric", required=True)
    m, n = fab.integer("courses", minimum=1), fab.integer("wales", minimum=1)
    fab.finish()
    natural, crossings, rejected, nodes, geometry_key, loop_tab = _read_loop(top.table("loop"),
                                                                              fab, m, n)
    if rejected and m >= 2:
        raise loop_tab.error(geometry_key, f"natural geometry rejected: {rejected}")
    mat = top.table("material")
    k_a = mat.number("k_a", 1.0, nonnegative=True)
    k_b = mat.number("k_b", 0.01, nonnegative=True)
    R_f = mat.number("R_f", 1.0, positive=True)     # R_f = 0: loops bend freely, no equilibrium
    mat.finish()
    points = PointReader(m, n, natural, crossings)
    starts = natural_starts(natural, m, n)
    clamps = tuple(c for t in top.tables("clamp") for c in _read_clamp(t, points, starts))
    rigid = tuple(_read_rigid(t, points, starts) for t in top.tables("rigid_clamp"))
    _check_overconstraint(top, clamps, rigid, points)
    loads = tuple(ld for t in top.tables("load") for ld in _read_load(t, points))
    reduction = _read_reduction(top, m, n) if top.has("reduction") else None
    solver = _read_solver(top.table("solver"))
    units = read_units(top.table("units"))
    yarn = _read_yarn(top.table("yarn"), natural, crossings) if top.has("yarn") else None
    if yarn is not None and yarn.spatial:
        if reduction is not None:
            raise ProblemError(source, "yarn", "geometry", 'the reduced model is planar: remove '
                               '[reduction] to solve the 3-D model, or remove geometry = "3d"')
        clamps = tuple(_rebased(c, natural, yarn.natural3d, m, n) for c in clamps)
    top.finish()
    pr = WeftProblem(name, description, m, n, natural, crossings, nodes, k_a, k_b, R_f,
                     clamps, loads, rigid, reduction, solver, str(source), units, yarn)
    _check_reach(pr)
    return pr


def _rebased(c: Clamp, planar: NaturalLoop, shape: Any, m: int, n: int) -> Clamp:
    """A clamp given by a displacement (not a position) moves from the natural 3-D fabric's
    projection, on its own lattice, instead of the paper's (the 3-D model's natural state)."""
    if c.key == "position":
        return c
    i, j = c.loop[0] - 1, c.loop[1] - 1
    there = shape.starts(m, n)[i, j, :2] + shape.xyz([c.s])[0, :2]
    return replace(c, target=c.target + there - natural_starts(planar, m, n)[i, j]
                   - planar.xy([c.s])[0])


def _check_reach(pr: WeftProblem) -> None:
    """Refuse grips no configuration satisfies (:mod:`.reach`): targets of one course farther
    apart than its yarn, a net load along a coordinate nothing holds."""
    targets = np.array([c.target for c in pr.clamps]).reshape(-1, 2)
    rigid = np.array([[*r.translation, r.rotation] for r in pr.rigid_clamps]).reshape(-1, 3)
    forces = np.array([ld.force for ld in pr.loads]).reshape(-1, 2)
    found = unreachable(pr, targets, rigid, forces)
    if found:
        raise ProblemError(pr.source, *found)


def _read_yarn(tab: Table, natural: NaturalLoop, crossings: Crossings | None) -> Yarn:
    """``[yarn]``: ``radius`` (length units: positive, below a quarter of the loop length);
    ``geometry`` "planar" (default) or "3d", and for "3d" the keys of :data:`SPATIAL_KEYS`
    (docs/weft_files.md, "[yarn]")."""
    radius = tab.number("radius", positive=True)
    if radius >= natural.length / 4:
        raise tab.error("radius", f"{radius:g} is not below a quarter of the loop length "
                        f"{natural.length:g}; a yarn that thick has no room in its own loop")
    from .contact.rule import refusal           # the radii the contact rule can judge
    if (why := refusal(natural, radius)) is not None:
        raise tab.error("radius", why)
    geometry = tab.string("geometry", "planar", choices=GEOMETRIES)
    if geometry == "planar":
        for key in SPATIAL_KEYS:
            if tab.has(key):
                raise tab.error(key, 'only with geometry = "3d"' + (
                    " (friction acts where the 3-D model's yarns slide through their crossings;"
                    " the planar model has no such contacts)" if key == "friction" else ""))
        tab.finish()
        return Yarn(radius)
    core = tab.number("core_radius", radius * ACRYLIC.core_radius / ACRYLIC.radius,
                      positive=True)
    if core >= radius:
        raise tab.error("core_radius", f"{core:g} must be below the radius {radius:g}")
    rigidity = tab.number("contact_rigidity", ACRYLIC.rigidity, positive=True)
    exponent = tab.number("contact_exponent", ACRYLIC.exponent)
    if not exponent > 1.0:
        raise tab.error("contact_exponent", f"must exceed 1, got {exponent:g}")
    modes = tab.integer("elevation_modes", 4, minimum=2, maximum=MAX_ELEVATION_MODES)
    springs = tab.boolean("crossing_springs", False)
    friction = tab.number("friction", 0.0, nonnegative=True)
    tab.finish()
    from .spatial.natural_fit import natural_3d  # it checks with proximity, which reads problems
    try:
        shape = (natural_3d(natural, crossings, modes, radius, core) if crossings is not None
                 else flat(natural, modes, radius))
    except NaturalShapeError as err:
        raise tab.error("radius", f"{err}; try a smaller radius or more elevation_modes") from None
    return Yarn(radius, geometry, core, rigidity, exponent, modes, springs, friction, shape)


def _read_loop(tab: Table, fab: Table, m: int,
               n: int) -> tuple[NaturalLoop, Crossings | None, str, int, str, Table]:
    """The natural loop; the size of the NLP it implies is checked before it is measured."""
    preset = tab.string("preset", "jersey", choices=PRESETS)
    L = tab.number("length", 10.0, positive=True)
    t = tab.integer("harmonics", 3, maximum=MAX_HARMONICS)
    if t < 1:
        raise tab.error("harmonics", f"must be a positive integer, got {t}")
    nodes = tab.integer("quadrature_nodes", DEFAULT_NODES, maximum=MAX_NODES)
    if nodes < 2:
        raise tab.error("quadrature_nodes", f"must be at least 2, got {nodes}")
    check_memory(fab, "courses", weft_bytes(m, n, t, nodes),
                 f"a {m} x {n} fabric with {t} harmonics and {nodes} quadrature nodes")
    key = "preset"
    if tab.has("natural_coefficients"):
        coeffs = np.array(tab.numbers("natural_coefficients", length=n_coeffs(t)))
        key = "natural_coefficients"
    else:
        coeffs = preset_coeffs(preset, t)
    spacing = tab.number("course_spacing", None, positive=True)
    if tab.has("course_spacing"):
        key = "course_spacing" if key == "preset" else key
    tab.finish()
    natural, crossings, rejected = _measured(np.asarray(coeffs, dtype=float).tobytes(), L, t,
                                             spacing)
    return natural, crossings, rejected, nodes, key, tab


@functools.lru_cache(maxsize=64)
def _measured(coeffs: bytes, L: float, t: int,
              spacing: float | None) -> tuple[NaturalLoop, Crossings | None, str]:
    """The natural loop, its crossings (None and the reason if it has none), memoised: measuring
    them takes a few tenths of a second, and studies and tests read the same loop many times."""
    natural = natural_loop(np.frombuffer(coeffs), L, t, spacing)
    try:
        return natural, find_crossings(natural), ""
    except CrossingError as err:
        return natural, None, str(err)


class PointReader:
    """Resolves the ``loop`` (or ``course``, ``wale``, ``edge``) and ``point`` keys of clamp and
    load tables to loops (i, j) and s."""

    def __init__(self, m: int, n: int, natural: NaturalLoop, crossings: Crossings | None) -> None:
        self.m, self.n, self.natural, self.crossings = m, n, natural, crossings

    def loops(self, tab: Table) -> tuple[list[tuple[int, int]], str | None]:
        """The loops a table names: ``loop = [i, j]`` (one), or every loop of ``course = i``,
        ``wale = j`` or ``edge = "bottom" | "top" | "left" | "right"``. Also the edge's default
        point label (None when the table must give one)."""
        given = [k for k in SELECTORS if tab.has(k)]
        if len(given) != 1:
            raise tab.error(given[1] if given else "loop",
                            "give exactly one of loop, course, wale and edge")
        key = given[0]
        if key == "loop":
            return [self.loop(tab)], None
        if key == "edge":
            edge = tab.string("edge", choices=EDGES)
            kind, end = EDGES[edge]
            index = 1 if end == "first" else (self.m if kind == "course" else self.n)
            return self._line(kind, index), EDGE_POINTS.get(edge)
        index, top = tab.integer(key), self.m if key == "course" else self.n
        if not 1 <= index <= top:
            raise tab.error(key, f"{index} is outside the {self.m} x {self.n} fabric "
                            f"({key}s 1..{top})")
        return self._line(key, index), None

    def _line(self, kind: str, index: int) -> list[tuple[int, int]]:
        if kind == "course":
            return [(index, j) for j in range(1, self.n + 1)]
        return [(i, index) for i in range(1, self.m + 1)]

    def loop(self, tab: Table) -> tuple[int, int]:
        i, j = tab.integers("loop", length=2)
        if not (1 <= i <= self.m and 1 <= j <= self.n):
            raise tab.error("loop", f"[{i}, {j}] is outside the {self.m} x {self.n} fabric "
                            f"(courses 1..{self.m}, wales 1..{self.n})")
        return i, j

    def point(self, tab: Table, default: str | None = None) -> tuple[str | float, float]:
        value = tab.value("point") if default is None else tab.value("point", default)
        L = self.natural.length
        if isinstance(value, str):
            if value == "start":
                return value, 0.0
            if value == "end":
                return value, L
            if value in LANDMARKS:
                return value, LANDMARKS[value] * L
            if value not in LABELS:
                raise tab.error("point", f"unknown point label {quoted(value)}; use start, end, "
                                f"{', '.join(LANDMARKS)}, {' '.join(LABELS)} or a number s in "
                                f"[0, {L:g}]")
            if self.crossings is None:
                raise tab.error("point", f"label {quoted(value)} needs crossings, which this "
                                "natural geometry does not have; give a number s instead")
            return value, self.crossings.s[value]
        try:
            value = finite_number(value)
        except ValueError:
            raise tab.error("point", "expected a label string or a finite number s") from None
        if not 0.0 <= value <= L:
            raise tab.error("point", f"s = {value:g} is outside [0, {L:g}]")
        return float(value), float(value)


def _direction(tab: Table, size_key: str) -> np.ndarray | None:
    """``direction`` (degrees counter-clockwise from +x, or a vector [dx, dy]) times ``size_key``
    (``distance`` or ``magnitude``, >= 0); None when the table gives neither."""
    if not (tab.has("direction") or tab.has(size_key)):
        return None
    if not (tab.has("direction") and tab.has(size_key)):
        missing = size_key if tab.has("direction") else "direction"
        raise tab.error(missing, f"direction and {size_key} go together; give both")
    value = tab.value("direction")
    if isinstance(value, list):
        vec = np.array(tab.numbers("direction", length=2))
        norm = float(np.hypot(*vec))
        if norm == 0.0:
            raise tab.error("direction", "the vector [0, 0] has no direction")
        unit = vec / norm
    else:
        angle = np.radians(tab.number("direction"))
        unit = np.array([np.cos(angle), np.sin(angle)])
    return unit * tab.number(size_key, nonnegative=True)


def _read_clamp(tab: Table, points: PointReader, starts: np.ndarray) -> list[Clamp]:
    """One clamp per loop the table names (a course, wale or edge shorthand makes several)."""
    tab.allow(*SELECTORS, "point", "position", "displacement", "direction", "distance", "fix",
              "angle")
    loops, default_point = points.loops(tab)
    label, s = points.point(tab, default_point)
    fix = tab.strings("fix", ["x", "y"], choices=("x", "y"))
    if len(set(fix)) != len(fix):
        raise tab.error("fix", "lists a coordinate twice")
    angle = tab.number("angle", None)
    if not fix and angle is None:
        raise tab.error("fix", "an empty fix list needs an angle, or the clamp holds nothing")
    pull = _direction(tab, "distance")
    given = [k for k in ("position", "displacement", "direction") if tab.has(k)]
    if len(given) > 1 or (fix and not given):
        raise tab.error(given[0] if given else "position",
                        "give exactly one of position, displacement and direction + distance")
    if given == ["position"] and len(loops) > 1:
        raise tab.error("position", f"one position for {len(loops)} points would stack them; "
                        "give a displacement (or direction + distance) for a course, wale or edge")
    move = pull if pull is not None else np.array(
        tab.numbers("displacement", [0.0, 0.0], length=2))
    position = np.array(tab.numbers("position", length=2)) if given == ["position"] else None
    tab.finish()
    natural = points.natural.xy([s])[0]
    return [Clamp(loop, label, s,
                  position if position is not None
                  else starts[loop[0] - 1, loop[1] - 1] + natural + move,
                  ("x" in fix, "y" in fix), angle, tab.name, not tab.has("loop"),
                  "distance" if pull is not None else (given or ["fix"])[0]) for loop in loops]


def _read_rigid(tab: Table, points: PointReader, starts: np.ndarray) -> RigidClamp:
    """A rigid clamp over listed ``points``, or over ``point`` of every loop of a course, wale or
    edge; moved by ``translation`` (or ``direction`` + ``distance``) and ``rotation``."""
    tab.allow("points", *SELECTORS[1:], "point", "translation", "direction", "distance",
              "rotation", "centre")
    pts = []
    if tab.has("points"):
        extra = [k for k in (*SELECTORS[1:], "point") if tab.has(k)]
        if extra:
            raise tab.error(extra[0], "give either points = [...] or a course, wale or edge")
        for sub in tab.tables("points"):
            sub.name = f"{tab.name}.{sub.name}"
            sub.allow("loop", "point")
            loop = points.loop(sub)
            label, s = points.point(sub)
            sub.finish()
            pts.append((loop, label, s))
        if not pts:
            raise tab.error("points", "a rigid clamp needs at least one point")
    else:
        if tab.has("loop"):
            raise tab.error("loop", "a rigid clamp takes points = [...], or a course, wale or edge")
        if not any(tab.has(k) for k in SELECTORS[1:]):
            raise tab.error("points", "give points = [...], or course, wale or edge with a point")
        loops, default_point = points.loops(tab)
        label, s = points.point(tab, default_point)
        pts = [(loop, label, s) for loop in loops]
    p0 = np.array([starts[lp[0] - 1, lp[1] - 1] + points.natural.xy([s])[0] for lp, _, s in pts])
    pull = _direction(tab, "distance")
    if pull is not None and tab.has("translation"):
        raise tab.error("translation", "give translation or direction + distance, not both")
    translation = pull if pull is not None else np.array(
        tab.numbers("translation", [0.0, 0.0], length=2))
    rotation = tab.number("rotation", 0.0)
    centre = np.array(tab.numbers("centre", p0.mean(axis=0).tolist(), length=2))
    tab.finish()
    return RigidClamp(tuple(pts), translation, rotation, centre)


def _read_load(tab: Table, points: PointReader) -> list[Load]:
    """One load per loop the table names; a course, wale or edge gets the force at every point."""
    tab.allow(*SELECTORS, "point", "force", "direction", "magnitude", "moment")
    loops, default_point = points.loops(tab)
    label, s = points.point(tab, default_point)
    pull = _direction(tab, "magnitude")
    if pull is not None and tab.has("force"):
        raise tab.error("force", "give force or direction + magnitude, not both")
    if not (tab.has("force") or tab.has("moment") or pull is not None):
        raise tab.error("force", "a load needs force = [fx, fy] (or direction + magnitude) "
                        "and/or moment = M")
    force = pull if pull is not None else np.array(tab.numbers("force", [0.0, 0.0], length=2))
    moment = tab.number("moment", 0.0)
    tab.finish()
    return [Load(loop, label, s, force, moment, tab.name, not tab.has("loop")) for loop in loops]


def canonical_point(loop: tuple[int, int], s: float, L: float, n: int) -> tuple[int, int, float]:
    """One name for one material point: the end of loop (i, j<n) is the start of (i, j+1)."""
    i, j = loop
    if j < n and abs(s - L) <= 1e-12 * L:
        return i, j + 1, 0.0
    return i, j, round(s, 12)


def _check_overconstraint(top: Table, clamps: tuple[Clamp, ...], rigid: tuple[RigidClamp, ...],
                          points: PointReader) -> None:
    """No coordinate or angle of one material point may be held twice."""
    held: dict[tuple[Any, ...], str] = {}
    L, n = points.natural.length, points.n

    def hold(table: str, key: str, loop: tuple[int, int], s: float, label: Any, dof: str) -> None:
        where = (canonical_point(loop, s, L, n), dof)
        if where in held:
            raise ProblemError(top.file, table, key, f"over-constrains loop {list(loop)} point "
                               f"{label!r}: its {dof} is already held by {held[where]}")
        held[where] = table

    for c in clamps:
        for dof in [d for d, f in zip("xy", c.fix) if f]:
            hold(c.table, "fix", c.loop, c.s, c.point, dof)
        if c.angle is not None:
            hold(c.table, "angle", c.loop, c.s, c.point, "angle")
    for k, r in enumerate(rigid):
        for q, (loop, label, s) in enumerate(r.points):
            for dof in "xy":
                hold(f"rigid_clamp[{k + 1}]", f"points[{q + 1}]", loop, s, label, dof)


def _read_reduction(top: Table, m: int, n: int) -> Reduced | Adaptive:
    tab = top.table("reduction")
    adaptive = tab.boolean("adaptive", False)
    tolerance = tab.number("tolerance", None, positive=True)
    max_parameters = tab.integer("max_parameters", None, minimum=1)
    for key in ("representative_courses", "representative_wales"):
        if adaptive and tab.has(key):
            raise tab.error(key, "not with adaptive = true (adaptive starts from the corners)")
    for key, value in (("tolerance", tolerance), ("max_parameters", max_parameters)):
        if value is not None and not adaptive:
            raise tab.error(key, "only with adaptive = true")
    if adaptive:
        tab.finish()
        return Adaptive(tolerance, max_parameters)
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
    steps = tab.integer("continuation", d.continuation, minimum=1, maximum=MAX_CONTINUATION)
    max_time = tab.number("max_time", d.max_time, positive=True)
    tab.finish()
    return SolverOptions(tol=tol, max_iter=max_iter, max_time=max_time, continuation=steps)
