"""Parse and validate a ``model = "jacquard"`` problem file into plain dataclasses.

Everything a user can get wrong is checked here, before any numerics, and reported as a
:class:`~knit_nlp.errors.ProblemError` naming file, table and key.
The model and the key reference are in docs/jacquard.md.
"""
from __future__ import annotations

import io
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from ..errors import ProblemError, quoted
from ..limits import check_memory, jacquard_bytes
from ..outcome import SolverOptions as BaseSolverOptions
from ..tomlio import Table, load_toml, read_regular_file
from ..units import DEFAULT_FORCE, Units

SYMBOLS = {"#": "thick", "+": "thin", ".": "net"}
STRUCTURES = ("thick", "thin", "net")
SYSTEMS = ("fall_plate", "inlay")
EDGES = ("bottom", "top", "left", "right")

# Defaults (the paper's spans, docs/jacquard.md; the rest are this project's choices, docs/jacquard.md).
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
class SolverOptions(BaseSolverOptions):
    """``[solver]``: the shared ``tol`` (IPOPT), ``max_iter`` (IPOPT iterations) and
    ``max_time`` (seconds), and which method with its own stopping rules."""

    tol: float = 1e-10
    max_iter: int = 500
    method: str = "static"
    hessian: str = "exact"          # IPOPT hessian_approximation: exact | limited-memory
    move_tol: float = 1e-10         # explicit: stop when max move in a step < move_tol * w
    max_steps: int = 200_000        # explicit step limit
    regularization: float = 1e-8    # static: eps * max(k) * 1/2 |x - x_natural|^2 (0 = off)


@dataclass(frozen=True)
class Pull:
    """``[[pull]]``: a held edge moved by ``displacement`` (dx, dy) in mm from its natural place
    (docs/jacquard.md, "Pulling an edge")."""

    edge: str
    displacement: tuple[float, float]


@dataclass(frozen=True)
class JacquardProblem:
    """A validated double-jacquard problem (docs/jacquard.md)."""

    model: ClassVar[str] = "jacquard"
    # lengths in mm; forces in whatever unit the stiffnesses are per mm (docs/jacquard.md)
    units: ClassVar[Units] = Units("mm", DEFAULT_FORCE)

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
    pulls: tuple[Pull, ...] = ()     # extension: held edges that move ([[pull]])
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
            raise table.error(key, f"unknown design symbol {quoted(bad[0])} in line {row + 1} "
                              "(use '#' thick, '+' thin, '.' net)")
        if len(line) != width:
            raise table.error(key, f"design line {row + 1} has {len(line)} cells, line 1 has {width}")
    code = {"net": 0, "thin": 1, "thick": 2}
    grid = np.array([[code[SYMBOLS[c]] for c in line] for line in lines], dtype=np.int8)
    return grid[::-1].copy()  # top line of the text is the top course


PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
LUMINANCE = np.array([0.299, 0.587, 0.114])
MAX_DESIGN_BYTES = 8 * 2 ** 20      # design files and images (docs/limits.md)


def png_size(data: bytes) -> tuple[int, int] | None:
    """(width, height) from a PNG's IHDR chunk, or None if ``data`` does not start like a PNG."""
    if len(data) < 24 or data[:8] != PNG_SIGNATURE or data[12:16] != b"IHDR":
        return None
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def png_transparent_key(data: bytes) -> np.ndarray | None:
    """The colour a greyscale or RGB PNG's ``tRNS`` chunk makes fully transparent, as samples
    in [0, 1] (one for grey, three for RGB), or None when it has none. (A palette image's
    ``tRNS`` is decoded into an alpha channel by the reader; this is the case it ignores.)"""
    depth, colour_type = data[24], data[25]
    if colour_type not in (0, 2):
        return None
    offset = 8
    while offset + 8 <= len(data):
        length = int.from_bytes(data[offset:offset + 4], "big")
        kind = data[offset + 4:offset + 8]
        if kind in (b"IDAT", b"IEND"):
            return None
        if kind == b"tRNS":
            body = data[offset + 8:offset + 8 + length]
            samples = [int.from_bytes(body[k:k + 2], "big") for k in range(0, len(body) - 1, 2)]
            return np.array(samples, dtype=np.float64) / (2 ** depth - 1)
        offset += 12 + length
    return None


def _with_alpha(pixels: np.ndarray, key: np.ndarray, depth: int) -> np.ndarray:
    """RGBA pixels, alpha 0 where a pixel has the ``tRNS`` colour ``key`` (to within half a
    step of the image's bit depth), 1 elsewhere."""
    rgb = pixels[:, :, None] if pixels.ndim == 2 else pixels[:, :, :3]
    clear = np.all(np.abs(rgb - key[:rgb.shape[2]]) < 0.5 / (2 ** depth - 1), axis=2)
    colour = np.repeat(rgb, 3, axis=2) if rgb.shape[2] == 1 else rgb
    return np.concatenate([colour, np.where(clear, 0.0, 1.0)[:, :, None]], axis=2)


def _load_png(path: Path, table: Table, key: str, shape: tuple[int, int]) -> np.ndarray:
    """The pixels of a PNG file as floats in [0, 1], shape (rows, cols) or (rows, cols, 3|4).

    The header's width x height must be the fabric's wales x courses (``shape`` = (n, m)) and
    is checked before anything is decoded, so an image can never decode into more pixels than
    the size limits allow."""
    data = _read_design_bytes(path, table, key)
    size = png_size(data)
    if size is None:
        raise table.error(key, f"{quoted(path)} is not a PNG image")
    n, m = shape
    if size != (m, n):
        raise table.error(key, f"design image is {size[0]} x {size[1]} pixels; [fabric] "
                          f"declares {m} wales x {n} courses (one pixel per cell)")
    import matplotlib.image as mpimg      # heavy (0.7-1.4 s with Pillow): only for PNG designs
    try:
        pixels = np.asarray(mpimg.imread(io.BytesIO(data), format="png"))
    except (OSError, ValueError, SyntaxError, EOFError) as err:  # Pillow's errors
        raise table.error(key, f"cannot read design image {quoted(path)} "
                          f"({quoted(err)})") from None
    if np.issubdtype(pixels.dtype, np.integer):
        pixels = pixels / np.iinfo(pixels.dtype).max
    pixels = pixels.astype(np.float64)
    clear = png_transparent_key(data)
    return pixels if clear is None else _with_alpha(pixels, clear, data[24])


def _opaque_colours(pixels: np.ndarray, table: Table, key: str, path: Path) -> np.ndarray:
    """Greyscale or RGB(A) pixels as RGB rows x cols x 3; any pixel with alpha < 1 (an alpha
    channel's, or a ``tRNS`` chunk's transparent colour) is an error naming the file."""
    if pixels.ndim == 2:
        return np.repeat(pixels[:, :, None], 3, axis=2)
    if pixels.ndim != 3 or pixels.shape[2] not in (3, 4):
        raise table.error(key, f"unsupported image layout {pixels.shape} "
                          "(use greyscale, RGB or RGBA)")
    if pixels.shape[2] == 4:
        see_through = np.argwhere(pixels[:, :, 3] < 1.0)
        if len(see_through):
            row, col = see_through[0]
            raise table.error(key, f"design image {quoted(path, 200)}: pixel (x={col}, y={row} "
                              f"from the top left) has alpha {pixels[row, col, 3]:.3g} < 1 (a "
                              "transparent cell is ambiguous): flatten the image (save it "
                              "without transparency)")
    return pixels[:, :, :3]


def read_design_image(path: Path, table: Table, key: str, shape: tuple[int, int]) -> np.ndarray:
    """A three-colour PNG design as codes[j, i] (0 net, 1 thin, 2 thick; j = 0 bottom course).

    One pixel per cell; the top pixel row is the top course (as in text designs). Greyscale,
    RGB and RGBA PNGs, 8/16-bit or float, are accepted. Colour rule: black = thick, mid grey =
    thin, white = net, classified by luminance ``Y = 0.299 R + 0.587 G + 0.114 B`` in [0, 1]:
    ``Y < 1/3`` thick, ``1/3 <= Y < 2/3`` thin, ``Y >= 2/3`` net. Errors (naming ``key``): a
    missing, unreadable or non-PNG file, any pixel with alpha < 1, more than three distinct
    colours.
    """
    rgb = _opaque_colours(_load_png(path, table, key, shape), table, key, path)
    n_colours = len(np.unique(rgb.reshape(-1, 3), axis=0))
    if n_colours > 3:
        raise table.error(key, f"design image {quoted(path)} has {n_colours} distinct colours; use at "
                          "most three (black = thick, mid grey = thin, white = net)")
    luminance = rgb @ LUMINANCE
    grid = np.where(luminance < 1 / 3, 2, np.where(luminance < 2 / 3, 1, 0)).astype(np.int8)
    return grid[::-1].copy()  # top pixel row is the top course


DESIGN_KEYS = ("design", "design_file", "design_image")


def _resolve(base: Path, rel: str, t: Table, key: str) -> Path:
    """A design file named in the problem file: a relative path, resolved (symbolic links
    followed) inside the problem file's folder; anything else is refused."""
    if "\0" in rel or not rel or Path(rel).is_absolute():
        raise t.error(key, f"must be a relative path inside the problem file's folder; "
                      f"got {quoted(rel)}")
    try:
        folder = base.resolve()
        path = (folder / rel).resolve()
    except (OSError, RuntimeError) as err:       # RuntimeError: a symbolic-link loop
        raise t.error(key, f"cannot resolve {quoted(rel)} ({quoted(err)})") from None
    if not path.is_relative_to(folder):
        raise t.error(key, f"{quoted(rel)} leads outside the problem file's folder; design "
                      "files must lie in it or below it")
    return path


def _read_design_bytes(path: Path, t: Table, key: str) -> bytes:
    """A design file's bytes: a regular file of at most :data:`MAX_DESIGN_BYTES`."""
    try:
        return read_regular_file(path, MAX_DESIGN_BYTES)
    except ProblemError as err:
        what = "image" if key == "design_image" else "file"
        raise t.error(key, f"cannot read design {what} {quoted(path.name)}: "
                      f"{err.message}") from None


def _read_design(t: Table, base: Path, shape: tuple[int, int]) -> tuple[np.ndarray, str]:
    """The design codes and the key they came from: ``design`` (inline text), ``design_file``
    (text file) or ``design_image`` (PNG), files relative to the TOML file; exactly one."""
    given = [k for k in DESIGN_KEYS if t.has(k)]
    if len(given) != 1:
        which = f"got {', '.join(given)}" if given else "got none"
        raise t.error(given[1] if len(given) > 1 else "design",
                      "give exactly one of 'design' (inline text), 'design_file' (text file) "
                      f"or 'design_image' (PNG); {which}")
    key = given[0]
    if key == "design":
        return parse_design(t.string("design"), t, key), key
    path = _resolve(base, t.string(key), t, key)
    if key == "design_image":
        return read_design_image(path, t, key, shape), key
    try:
        text = _read_design_bytes(path, t, key).decode("utf-8")
    except UnicodeDecodeError as err:
        raise t.error(key, f"design file {quoted(path.name)} is not UTF-8 text "
                      f"(byte {err.start})") from None
    return parse_design(text, t, key), key


def _ratio(t: Table, key: str, default: float) -> float:
    value = t.number(key, default)
    if not 0.0 < value <= 1.0:
        raise t.error(key, f"pretension ratio must be in (0, 1], got {value:g}")
    return value


def _read_system(parent: Table, name: str, base: Path, shape: tuple[int, int]) -> JacquardSystem:
    t = parent.table(name, required=True)
    codes, key = _read_design(t, base, shape)
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
        max_time=t.number("max_time", d.max_time, positive=True),
    )
    t.finish()
    return opts


def _read_pulls(top: Table, boundary: str, edges: tuple[str, ...]) -> tuple[Pull, ...]:
    """``[[pull]]`` tables: ``edge`` (a held edge) and ``displacement = [dx, dy]`` in mm."""
    pulls: list[Pull] = []
    for t in top.tables("pull"):
        edge = t.string("edge", choices=EDGES)
        if boundary != "fixed":
            raise t.error("edge", 'pulling an edge needs boundary = "fixed" in [fabric]')
        if edge not in edges:
            raise t.error("edge", f"edge {edge!r} is not held: add it to [fabric] fixed_edges")
        if edge in (q.edge for q in pulls):
            raise t.error("edge", f"edge {edge!r} is pulled twice")
        dx, dy = t.numbers("displacement", length=2)
        t.finish()
        pulls.append(Pull(edge, (dx, dy)))
    return tuple(pulls)


def parse_problem(doc: dict[str, Any], source: Path | str) -> JacquardProblem:
    """Validate a parsed TOML document into a :class:`JacquardProblem` (no numerics).

    ``source`` names the document in messages (its file), gives the default ``name`` and the
    folder that design files are read from."""
    path = Path(source)
    top = Table(doc, path, "")
    name = top.stem("name")
    description = top.string("description", "")
    model = top.string("model", "jacquard")
    if model != "jacquard":
        raise top.error("model", f"expected 'jacquard', got {quoted(model)}")
    fab = top.table("fabric", required=True)
    m = fab.integer("wales", minimum=1)
    n = fab.integer("courses", minimum=2)
    check_memory(fab, "courses", jacquard_bytes(m, n), f"a {m} x {n} repeat")
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
    pulls = _read_pulls(top, boundary, edges)
    solver = _read_solver(top)
    top.finish()
    return JacquardProblem(
        name=name, description=description, wales=m, courses=n, dz=dz, dh=dh,
        ground_stiffness=gk, ground_pretension=gp, systems=systems, mass=mass, damping=damping,
        dt=dt, lambda_max=lam, zigzag=1 if zig == "right" else -1, boundary=boundary,
        fixed_edges=edges if boundary == "fixed" else (), loop_width_stiffness=loop_k,
        pulls=pulls, solver=solver, source=str(path))


def load_problem(path: Path | str) -> JacquardProblem:
    """Read and validate a jacquard problem file."""
    return parse_problem(load_toml(Path(path)), path)
