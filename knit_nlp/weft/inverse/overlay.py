"""A solved result over a photograph (docs/inverse.md, "Overlay"; the paper's Fig. 8).

The picture's y axis points down, the model's up, so the similarity (scale, rotation, shift) is
fitted between model points z = x + iy and pixels w = px − i·py: w ≈ a·z + b with complex a
(scale·e^{i·rotation}) and b, which is linear least squares in (a, b) and exactly the
least-squares similarity (Umeyama's problem in two dimensions); two matches fix it.
"""
from __future__ import annotations

import io
import json
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import ProblemError, shown
from ...jsonio import write_json
from ...tomlio import Table, load_toml, read_regular_file
from ..model.problem import WeftProblem, PointReader, parse_problem
from ..model.quadrature import positions
from .spec import strip_control_keys

FITTED = "Similarity_Fitted"   # the status of every overlay answer (refused matches raise)


@dataclass(frozen=True)
class Similarity:
    """pixel = to_pixels(model): w = a·z + b in (px, −py) coordinates."""

    a: complex
    b: complex

    @property
    def scale(self) -> float:
        return float(abs(self.a))

    @property
    def rotation(self) -> float:
        """Radians, counter-clockwise in model coordinates (clockwise on the picture)."""
        return float(np.angle(self.a))

    def to_pixels(self, xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=float)
        w = self.a * (xy[..., 0] + 1j * xy[..., 1]) + self.b
        return np.stack([w.real, -w.imag], axis=-1)

    def as_dict(self) -> dict:
        return {"scale_px_per_unit": self.scale, "rotation_rad": self.rotation,
                "shift_px": [float(self.b.real), float(-self.b.imag)]}


def fit_similarity(model: np.ndarray, pixels: np.ndarray) -> Similarity:
    """Least-squares similarity from matched model points (k × 2) and pixels (k × 2), k ≥ 2."""
    z = model[:, 0] + 1j * model[:, 1]
    w = pixels[:, 0] - 1j * pixels[:, 1]
    (a, b), *_ = np.linalg.lstsq(np.stack([z, np.ones_like(z)], axis=1), w, rcond=None)
    return Similarity(complex(a), complex(b))


@dataclass(frozen=True)
class Match:
    loop: tuple[int, int]
    point: str | float
    s: float
    pixel: np.ndarray


@dataclass
class SolvedShape:
    """What the overlay needs of a solve result: its JSON and the NPZ written beside it."""

    result: dict
    lines: np.ndarray          # (m, n, S, 2) deformed centrelines
    coefficients: np.ndarray   # (m, n, 2t+2)
    starts: np.ndarray         # (m, n, 2)
    L: float

    def position(self, loop: tuple[int, int], s: float) -> np.ndarray:
        i, j = loop[0] - 1, loop[1] - 1
        t = (self.coefficients.shape[-1] - 2) // 2
        return positions(self.coefficients[i, j][None], [s], self.L, t)[0, 0] + self.starts[i, j]


MAX_RESULT_BYTES = 256 * 2 ** 20     # a result JSON or NPZ read back (docs/limits.md)
MAX_ARRAY_BYTES = 256 * 2 ** 20      # ... and the arrays its NPZ declares, before decompressing
ARRAYS = ("deformed", "coefficients", "starts", "s")


def load_result(path: Path) -> SolvedShape:
    """A ``knit-nlp solve`` result JSON and its NPZ (same stem), checked: a JSON object, and
    finite real arrays of consistent shapes (anything else is one ProblemError)."""
    try:
        result = json.loads(read_regular_file(path, MAX_RESULT_BYTES))
    except (UnicodeDecodeError, ValueError) as err:
        raise ProblemError(path, "", "", f"not a weft solve result ({err})") from None
    if not isinstance(result, dict):
        raise ProblemError(path, "", "", f"not a weft solve result (a JSON "
                           f"{type(result).__name__}, not an object)")
    npz = path.with_suffix(".npz")
    if not npz.exists():
        raise ProblemError(path, "", "", f"needs the result JSON and the NPZ beside it ({npz})")
    arrays = _read_npz(npz)
    lines, coefficients, starts, s = (arrays[k] for k in ARRAYS)
    return SolvedShape(result, lines, coefficients, starts, float(s[-1]))


def _read_npz(npz: Path) -> dict[str, np.ndarray]:
    """The result's arrays (``ARRAYS``) as floats, refused in one line unless finite and of
    the shapes a solve writes: ``s`` (S,) increasing from 0, ``coefficients`` (m, n, 2t+2),
    ``starts`` (m, n, 2), ``deformed`` (m, n, S, 2)."""
    data = read_regular_file(npz, MAX_RESULT_BYTES)
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as zf:
            arrays = {key: _member(npz, zf, key) for key in ARRAYS}
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, KeyError) as err:
        raise ProblemError(npz, "", "", f"not a weft solve result ({shown(err, 200)})") from None
    _check_arrays(npz, arrays)
    return arrays


def _member(npz: Path, zf: zipfile.ZipFile, key: str) -> np.ndarray:
    """One array of an NPZ, its declared size checked against ``MAX_ARRAY_BYTES`` before it is
    read (zipfile reads no more than a member declares)."""
    try:
        info = zf.getinfo(f"{key}.npy")
    except KeyError:
        raise ProblemError(npz, "", key, "not a weft solve result (no such array)") from None
    with zf.open(info) as fh:
        version = np.lib.format.read_magic(fh)
        header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                  else np.lib.format.read_array_header_2_0)
        shape, _, dtype = header(fh)
    size = math.prod(shape) * dtype.itemsize
    if max(size, info.file_size) > MAX_ARRAY_BYTES:
        raise ProblemError(npz, "", key, f"declares {max(size, info.file_size)} bytes, larger "
                           f"than the limit of {MAX_ARRAY_BYTES} bytes")
    if dtype.kind not in "fiu":
        raise ProblemError(npz, "", key, f"not a weft solve result (numbers of type {dtype})")
    with zf.open(info) as fh:
        return np.lib.format.read_array(fh, allow_pickle=False).astype(float)


def _check_arrays(npz: Path, arrays: dict[str, np.ndarray]) -> None:
    s, coefficients = arrays["s"], arrays["coefficients"]
    for key, a in arrays.items():
        if not np.isfinite(a).all():
            raise ProblemError(npz, "", key, "not a weft solve result (values not finite)")
    if s.ndim != 1 or s.size < 2 or s[0] != 0 or not (np.diff(s) > 0).all():
        raise ProblemError(npz, "", "s", "not a weft solve result (the material coordinates "
                           "must be two or more, increasing from 0)")
    if coefficients.ndim != 3 or coefficients.shape[2] < 4 or coefficients.shape[2] % 2:
        raise ProblemError(npz, "", "coefficients", f"not a weft solve result (shape "
                           f"{coefficients.shape}; expected courses x wales x (2 harmonics + 2))")
    m, n = coefficients.shape[:2]
    for key, shape in (("starts", (m, n, 2)), ("deformed", (m, n, s.size, 2))):
        if arrays[key].shape != shape:
            raise ProblemError(npz, "", key, f"not a weft solve result (shape "
                               f"{arrays[key].shape}; expected {shape} from the coefficients "
                               "and s)")


def check_shape(shape: SolvedShape, pr: WeftProblem, result_path: Path, problem: Path) -> None:
    """The problem resolving point labels must be the result's: as many courses and wales
    loops and harmonics."""
    m, n, k = shape.coefficients.shape
    if (m, n, k) != (pr.courses, pr.wales, 2 * pr.t + 2):
        raise ProblemError(problem, "", "", f"a {pr.courses} x {pr.wales} fabric with {pr.t} "
                           f"harmonics, but the result {result_path} is {m} x {n} with "
                           f"{(k - 2) // 2}: pass the result's own problem with --problem")


def point_reader(problem_path: Path) -> tuple[PointReader, WeftProblem]:
    pr = parse_problem(strip_control_keys(load_toml(problem_path)), problem_path)
    return PointReader(pr.courses, pr.wales, pr.natural, pr.crossings), pr


MAX_PIXEL = 1e7      # |pixel coordinate|: far beyond any photograph MAX_IMAGE_PIXELS admits


def parse_match(text: str, reader: PointReader) -> Match:
    """``C,W,POINT=PX,PY`` (course, wale, point label or s; pixel, origin top left, y down)."""
    try:
        left, right = text.split("=")
        c, w, point = left.split(",")
        px, py = (float(v) for v in right.split(","))
        loop_raw = [int(c), int(w)]
    except ValueError:
        raise ProblemError("--match", "", text, "expected C,W,POINT=PX,PY, e.g. 5,5,H=412,300") from None
    if not all(math.isfinite(v) and abs(v) <= MAX_PIXEL for v in (px, py)):
        raise ProblemError("--match", "", text, f"the pixel must be two finite numbers within "
                           f"±{MAX_PIXEL:.0e} px, got {px!r}, {py!r}")
    try:
        value: str | float = float(point)
    except ValueError:
        value = point.strip()
    tab = Table({"loop": loop_raw, "point": value}, "--match", text)
    loop = reader.loop(tab)
    label, s = reader.point(tab)
    return Match(loop, label, s, np.array([px, py]))


def overlay_name(result_path: Path, image: Path) -> str:
    """``<result stem>.<image stem>``: the name of an overlay's files (``.overlay.png``,
    ``.overlay.json``), so overlays of one result on several photographs do not overwrite
    each other."""
    return f"{result_path.name.removesuffix('.json')}.{image.stem}"


@dataclass
class OverlayAnswer:
    """The similarity fitted to the matches, the centrelines and observations mapped to pixels,
    and (for ``save``) the result and photograph they were drawn from.

    The results contract (knit_nlp/outcome.py): an answer exists only once the similarity is
    fixed (matches that fix none are refused with a ``ProblemError``), so ``success`` is always
    true and ``status`` :data:`FITTED`; ``to_json()`` is ``<stem>.overlay.json`` and
    ``save(out)`` writes it and ``<stem>.overlay.png`` (``stem``: :func:`overlay_name`).
    """

    transform: Similarity
    residuals_px: np.ndarray
    matches: list[Match]
    model_points: np.ndarray
    observed_rms: float | None
    lines_px: np.ndarray
    observed_px: np.ndarray | None
    problem: str = ""                       # the result's problem (the picture's caption)
    result_path: Path | None = None         # the solve result JSON overlaid
    image: Path | None = None               # the photograph's file ...
    picture: np.ndarray | None = None       # ... and its pixels (rows, columns[, channels])

    @property
    def success(self) -> bool:
        return True

    @property
    def status(self) -> str:
        return FITTED

    @property
    def message(self) -> str:
        """One sentence: the similarity and its largest match residual."""
        return (f"similarity fitted to {len(self.matches)} matches: {self._similarity_words()}; "
                f"largest match residual {self.largest_residual:.3g} px")

    @property
    def largest_residual(self) -> float:
        return float(max(self.residuals_px, default=0.0))

    @property
    def name(self) -> str:
        """The files' stem, :func:`overlay_name` of the result and the photograph."""
        result_path, image = self._sources()
        return overlay_name(result_path, image)

    def _similarity_words(self) -> str:
        t = self.transform
        return f"scale {t.scale:.4g} px/unit, rotation {np.degrees(t.rotation):.3f} deg"

    def _sources(self) -> tuple[Path, Path]:
        if self.result_path is None or self.image is None:
            raise ValueError("result_path, image: an overlay's files are named after the "
                             "result and the photograph; pass both to overlay()")
        return self.result_path, self.image

    def to_json(self) -> dict[str, Any]:
        """``<stem>.overlay.json``: the files, the similarity, per match its pixel residual, and
        the RMS misfit of the observations in model units (None without observations)."""
        return {"result": _path_or_none(self.result_path), "image": _path_or_none(self.image),
                "transform": self.transform.as_dict(),
                "matches": [{"loop": list(m.loop), "point": m.point, "pixel": m.pixel.tolist(),
                             "residual_px": float(r)}
                            for m, r in zip(self.matches, self.residuals_px)],
                "observed_rms_model_units": self.observed_rms}

    def save(self, out_dir: Path | str) -> list[Path]:
        """``DIR/<stem>.overlay.json`` and ``.overlay.png`` (the photograph at its own
        resolution, the centrelines, matches and observations drawn over it)."""
        from .plot import plot_on_image     # matplotlib (about 0.4 s) only when drawing
        out, stem = Path(out_dir), self.name
        if self.picture is None:
            raise ValueError("picture: the overlay is drawn on the photograph's pixels; pass "
                             "them to overlay()")
        png = plot_on_image(out / f"{stem}.overlay.png", self.picture, self.lines_px,
                            np.array([m.pixel for m in self.matches]),
                            self.transform.to_pixels(self.model_points), self.observed_px,
                            self._caption())
        return [write_json(out / f"{stem}.overlay.json", self.to_json()), png]

    def _caption(self) -> str:
        return (f"{self.problem}: similarity {self._similarity_words()}; largest match residual "
                f"{self.largest_residual:.3g} px")


def _path_or_none(path: Path | None) -> str | None:
    return None if path is None else str(path)


def overlay(shape: SolvedShape, matches: list[Match], observed: list | None = None, *,
            result_path: Path | None = None, image: Path | None = None,
            picture: np.ndarray | None = None) -> OverlayAnswer:
    """Fit the similarity, map the centrelines and report residuals (Python API); the result
    file, the photograph's file and its pixels are kept for ``save``."""
    if len(matches) < 2:
        raise ProblemError("--match", "", "", f"two or more matches are needed, got {len(matches)}")
    model = np.array([shape.position(m.loop, m.s) for m in matches])
    pixels = np.array([m.pixel for m in matches])
    if _spread(model) <= 1e-6 * shape.L:
        raise ProblemError("--match", "", "", "the matched material points coincide: match "
                           "points far apart on the fabric")
    sim = fit_similarity(model, pixels)
    _check_scale(sim, model, pixels)
    res = np.linalg.norm(sim.to_pixels(model) - pixels, axis=1)
    rms, obs_px = None, None
    if observed:
        comp = np.array([shape.position(o.loop, o.s) for o in observed])
        xy = np.array([o.xy for o in observed])
        rms = float(np.sqrt(np.mean(np.sum((comp - xy) ** 2, axis=1))))
        obs_px = sim.to_pixels(xy)
    return OverlayAnswer(sim, res, matches, model, rms, sim.to_pixels(shape.lines), obs_px,
                         str(shape.result.get("problem", "")), result_path, image, picture)


def _spread(points: np.ndarray) -> float:
    """The largest distance between two of the points (k × 2)."""
    return float(np.max(np.linalg.norm(points[:, None] - points[None], axis=-1)))


def _check_scale(sim: Similarity, model: np.ndarray, pixels: np.ndarray) -> None:
    """A similarity the matches fix: the matched pixels, and the fitted images of the matched
    material points, at least a pixel apart (below that the scale is the pixels' rounding)."""
    if _spread(pixels) < 1.0:
        raise ProblemError("--match", "", "", f"the matched pixels lie within 1 px of each other "
                           f"(largest distance {_spread(pixels):.3g} px): they fix no scale; "
                           "match points far apart on the photograph")
    if not np.isfinite([sim.a, sim.b]).all() or sim.scale * _spread(model) < 1.0:
        raise ProblemError("--match", "", "", f"the matches fix no scale (the least-squares "
                           f"similarity maps them within 1 px of each other, scale "
                           f"{sim.scale:.3g} px/unit): check which pixel belongs to which point")
