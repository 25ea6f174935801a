"""Parse and validate a ``model = "jacquard"`` problem file into plain dataclasses.

Everything a user can get wrong is checked here, before any numerics, and reported as a
:class:`~knit_nlp.errors.ProblemError` naming file, table and key (spec/problem_files.md).
The model itself is spec/jacquard_mass_spring.md; docs/jacquard.md is the key reference.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..tomlio import Table, load_toml

SYMBOLS = {"#": "thick", "+": "thin", ".": "net"}
STRUCTURES = ("thick", "thin", "net")
SYSTEMS = ("fall_plate", "inlay")
EDGES = ("bottom", "top", "left", "right")

# Defaults (spec: spans; the rest are this project's choices, docs/jacquard.md).
DEFAULT_SPAN = {"fall_plate": {"thick": 4, "thin": 2, "net": 1},
                "inlay": {"thick": 3, "thin": 2, "net": 1}}
DEFAULT_STIFFNESS = {"fall_plate": {"longitudinal": 0.5, "thick": 1.0, "thin": 0.7},
                     "inlay": {"longitudinal": 0.5, "thick": 0.8, "thin": 0.6}}
DEFAULT_PRETENSION = 0.9
DEFAULT_GROUND_STIFFNESS = 1.0


@dataclass(frozen=True)
class JacquardSystem:
    """One jacquard bar system (fall-plate or inlay): its design grid and spring data.

    ``codes[j, i]`` is 0 (net), 1 (thin) or 2 (thick) for course ``j`` (bottom = 0), wale ``i``.
    ``span``, ``stiffness`` and ``pretension`` are keyed by structure / spring kind.
    """

    name: str
    codes: np.ndarray
    span: dict[str, int]
    stiffness: dict[str, float]
    pretension: dict[str, float]


@dataclass(frozen=True)
class SolverOptions:
    """``[solver]``: which method and its stopping rules."""

    method: str = "static"
    tol: float = 1e-10              # IPOPT tol
    max_iter: int = 500             # IPOPT iterations
    hessian: str = "exact"          # IPOPT hessian_approximation: exact | limited-memory
    move_tol: float = 1e-10         # explicit: stop when max move in a step < move_tol * w
    max_steps: int = 200_000        # explicit step limit
    regularization: float = 1e-8    # static: eps * max(k) * 1/2 |x - x_natural|^2 (0 = off)


@dataclass(frozen=True)
class JacquardProblem:
    """A validated double-jacquard problem (spec/jacquard_mass_spring.md)."""

    name: str
    description: str
    wales: int                       # M
    courses: int                     # N
    dz: float                        # courses / cm
    dh: float                        # wales / cm
    ground_stiffness: float
    ground_pretension: float
    systems: tuple[JacquardSystem, ...]
    mass: float = 1.0
    damping: float = 0.5
    dt: float = 0.05
    lambda_max: float = 1.10
    zigzag: int = 1                  # d_0: +1 first course's underlap goes right, -1 left
    boundary: str = "periodic"
    fixed_edges: tuple[str, ...] = ()
    loop_width_stiffness: float = 0.0   # extension: compression-only course springs (0 = off)
    solver: SolverOptions = field(default_factory=SolverOptions)
    source: str = ""

    @property
    def h(self) -> float:
        """Loop height in mm, h = 10/dz."""
        return 10.0 / self.dz

    @property
    def w(self) -> float:
        """Wale spacing in mm, w = 10/dh."""
        return 10.0 / self.dh

    @property
    def n_particles(self) -> int:
        return self.wales * self.courses

    def with_solver(self, **changes: Any) -> "JacquardProblem":
        """A copy with some ``[solver]`` options changed (e.g. ``with_solver(hessian="exact")``)."""
        return replace(self, solver=replace(self.solver, **changes))


def parse_design(text: str, table: Table, key: str) -> np.ndarray:
    """A text design (``#`` thick, ``+`` thin, ``.`` net; top line = top course) as codes[j, i]."""
    lines = [ln.strip() for ln in text.strip("\n").splitlines()]
    lines = [ln for ln in lines if ln]
    if not lines:
        raise table.error(key, "design is empty")
    width = len(lines[0])
    for row, line in enumerate(lines):
        bad = [c for c in line if c not in SYMBOLS]
        if bad:
            raise table.error(key, f"unknown design symbol {bad[0]!r} in line {row + 1} "
                              "(use '#' thick, '+' thin, '.' net)")
        if len(line) != width:
            raise table.error(key, f"design line {row + 1} has {len(line)} cells, line 1 has {width}")
    code = {"net": 0, "thin": 1, "thick": 2}
    grid = np.array([[code[SYMBOLS[c]] for c in line] for line in lines], dtype=np.int8)
    return grid[::-1].copy()  # top line of the text is the top course


def _read_design(t: Table, base: Path) -> tuple[str, str]:
    """The design text from ``design`` (inline) or ``design_file`` (beside the TOML file)."""
    has_inline, has_file = t.has("design"), t.has("design_file")
    if has_inline == has_file:
        raise t.error("design", "give exactly one of 'design' (inline text) or 'design_file'")
    if has_inline:
        return t.string("design"), "design"
    rel = t.string("design_file")
    path = (base / rel) if not Path(rel).is_absolute() else Path(rel)
    try:
        return path.read_text(encoding="utf-8"), "design_file"
    except (OSError, UnicodeDecodeError) as err:
        raise t.error("design_file", f"cannot read design file {path} ({err})") from None


def _ratio(t: Table, key: str, default: float) -> float:
    value = t.number(key, default)
    if not 0.0 < value <= 1.0:
        raise t.error(key, f"pretension ratio must be in (0, 1], got {value:g}")
    return value


def _read_system(parent: Table, name: str, base: Path, shape: tuple[int, int]) -> JacquardSystem:
    t = parent.table(name, required=True)
    text, key = _read_design(t, base)
    codes = parse_design(text, t, key)
    n, m = shape
    if codes.shape != (n, m):
        raise t.error(key, f"design is {codes.shape[1]} wales x {codes.shape[0]} courses; "
                      f"[fabric] declares {m} x {n}")
    st = t.table("span")
    span = {s: st.integer(s, DEFAULT_SPAN[name][s], minimum=1) for s in STRUCTURES}
    st.finish()
    if span["net"] != 1:
        raise st.error("net", "a net cell has no lateral offset: its span must be 1")
    kt = t.table("stiffness")
    stiff = {k: kt.number(k, DEFAULT_STIFFNESS[name][k], nonnegative=True)
             for k in ("longitudinal", "thick", "thin")}
    kt.finish()
    pt = t.table("pretension")
    pre = {k: _ratio(pt, k, DEFAULT_PRETENSION) for k in ("longitudinal", "thick", "thin")}
    pt.finish()
    t.finish()
    if max(span["thick"], span["thin"]) > m:
        raise t.error("span", f"an underlap spanning {max(span['thick'], span['thin'])} wales "
                      f"does not fit a repeat of {m} wales")
    return JacquardSystem(name, codes, span, stiff, pre)


def _read_solver(top: Table) -> SolverOptions:
    t = top.table("solver")
    d = SolverOptions()
    opts = SolverOptions(
        method=t.string("method", d.method, choices=("static", "explicit")),
        tol=t.number("tol", d.tol, positive=True),
        max_iter=t.integer("max_iter", d.max_iter, minimum=1),
        hessian=t.string("hessian", d.hessian, choices=("exact", "limited-memory")),
        move_tol=t.number("move_tol", d.move_tol, positive=True),
        max_steps=t.integer("max_steps", d.max_steps, minimum=1),
        regularization=t.number("regularization", d.regularization, nonnegative=True),
    )
    t.finish()
    return opts


def parse_problem(doc: dict[str, Any], path: Path | str) -> JacquardProblem:
    """Validate a parsed TOML document into a :class:`JacquardProblem` (no numerics)."""
    path = Path(path)
    top = Table(doc, path, "")
    name = top.string("name", path.stem)
    description = top.string("description", "")
    model = top.string("model", "jacquard")
    if model != "jacquard":
        raise top.error("model", f"expected 'jacquard', got {model!r}")
    fab = top.table("fabric", required=True)
    m = fab.integer("wales", minimum=1)
    n = fab.integer("courses", minimum=2)
    dz = fab.number("dz", positive=True)
    dh = fab.number("dh", positive=True)
    mass = fab.number("mass", 1.0, positive=True)
    damping = fab.number("damping", 0.5, nonnegative=True)
    dt = fab.number("dt", 0.05, positive=True)
    lam = fab.number("lambda_max", 1.10)
    if not 1.0 < lam <= 2.0:
        raise fab.error("lambda_max", f"must be in (1, 2] (the paper uses 1.01-1.15), got {lam:g}")
    zig = fab.string("zigzag", "right", choices=("right", "left"))
    boundary = fab.string("boundary", "periodic", choices=("periodic", "fixed"))
    edges = tuple(fab.strings("fixed_edges", list(EDGES), choices=EDGES))
    if boundary == "fixed" and not {"bottom", "top"} <= set(edges):
        raise fab.error("fixed_edges", "a fixed boundary must hold 'bottom' and 'top' "
                        "(otherwise the pillar chains go slack and the equilibrium is undetermined)")
    if boundary == "periodic" and fab.has("fixed_edges"):
        raise fab.error("fixed_edges", "only meaningful with boundary = \"fixed\"")
    if boundary == "periodic" and n % 2:
        raise fab.error("courses", f"a periodic repeat needs an even number of courses (the "
                        f"guide's zigzag repeats every 2 courses); got {n}")
    loop_k = fab.number("loop_width_stiffness", 0.0, nonnegative=True)
    fab.finish()
    gr = top.table("ground")
    gk = gr.number("stiffness", DEFAULT_GROUND_STIFFNESS, positive=True)
    gp = _ratio(gr, "pretension", DEFAULT_PRETENSION)
    gr.finish()
    systems = tuple(_read_system(top, s, path.parent, (n, m)) for s in SYSTEMS)
    solver = _read_solver(top)
    top.finish()
    return JacquardProblem(
        name=name, description=description, wales=m, courses=n, dz=dz, dh=dh,
        ground_stiffness=gk, ground_pretension=gp, systems=systems, mass=mass, damping=damping,
        dt=dt, lambda_max=lam, zigzag=1 if zig == "right" else -1, boundary=boundary,
        fixed_edges=edges if boundary == "fixed" else (), loop_width_stiffness=loop_k,
        solver=solver, source=str(path))


def load_problem(path: Path | str) -> JacquardProblem:
    """Read and validate a jacquard problem file."""
    return parse_problem(load_toml(Path(path)), path)
