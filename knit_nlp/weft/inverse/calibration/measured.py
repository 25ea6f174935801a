"""Measured uniaxial tests, read from CSV: the stitch-by-stitch tracking files and plain columns.

Two formats (docs/real_fabric.md):

- ``stitch_by_stitch``: the columns of the published tracking data (Singal et al., Nat. Commun.
  15, 2622, 2024): ``run``, ``frame``, ``force_N`` and the pixel positions ``right_pin_x``,
  ``right_pin_y``, ``left_pin_x``, ``left_pin_y``, ``bottom_pin_x``, ``bottom_pin_y``,
  ``top_pin_x``, ``top_pin_y`` (other columns are ignored). Axial strain is the top-bottom pin
  distance over that distance in the run's first frame, minus 1; lateral strain the same for the
  left-right pins. A comment line ``# clamp_size_px = C; fabric_width_px = W`` gives the
  specimen's width at the clamp in clamp widths, W / C.
- ``columns``: ``force_N``, ``axial_strain`` and optionally ``lateral_strain`` and ``run`` (a
  label; without it the file is one run), strains as measured by the user from their reference.

Lines starting with ``#`` are comments. Every bad file is one :class:`ProblemError` naming the
file, the line or run, the column and what to do; nothing here hangs on any input (regular files
of bounded size, bounded cells, no recursion).
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ....errors import ProblemError, quoted
from ....tomlio import MAX_MAGNITUDE, read_regular_file

MAX_TEST_BYTES = 32 * 2 ** 20      # a test's CSV (the shipped ones are 0.2 and 0.6 MB)
MAX_CELL_CHARS = 64                # a number or a run label
MAX_COLUMNS = 64
FORMATS = ("stitch_by_stitch", "columns")
PINS = ("right_pin", "left_pin", "bottom_pin", "top_pin")
SBS_COLUMNS = ("run", "frame", "force_N") + tuple(f"{p}_{c}" for p in PINS for c in "xy")
COLUMNS_REQUIRED = ("force_N", "axial_strain")
COLUMNS_OPTIONAL = ("lateral_strain", "run")
_GEOMETRY = re.compile(r"clamp_size_px\s*=\s*([^;\s]+)\s*;\s*fabric_width_px\s*=\s*([^;\s]+)")


@dataclass(frozen=True)
class Run:
    """One run of a test, frames in order: force (N) and strains from the run's first frame."""

    label: str
    force: np.ndarray
    axial: np.ndarray
    lateral: np.ndarray | None
    aspect: float | None = None       # gauge length / width in the first frame (pins)


@dataclass(frozen=True)
class MeasuredTest:
    """A test file's runs; ``width_clamps`` the specimen width in clamp widths (if recorded)."""

    file: str                          # as written in the spec
    path: Path
    format: str
    runs: tuple[Run, ...]
    width_clamps: float | None = None
    description: str = ""

    @property
    def has_lateral(self) -> bool:
        return all(r.lateral is not None for r in self.runs)

    @property
    def aspect(self) -> float | None:
        """Median over runs of the first frame's gauge length over width (pins), if measured."""
        values = [r.aspect for r in self.runs if r.aspect is not None]
        return float(np.median(values)) if values else None

    @property
    def max_force(self) -> float:
        return float(max(r.force.max() for r in self.runs))

    @property
    def common_force(self) -> float:
        """The largest force every run reaches."""
        return float(min(r.force.max() for r in self.runs))


def _fail(path: Path, where: str, key: str, message: str) -> ProblemError:
    return ProblemError(path, where, key, message)


def _lines(path: Path) -> tuple[list[str], list[tuple[int, str]]]:
    """(comment texts, (line number, line) of the other non-blank lines)."""
    try:
        text = read_regular_file(path, MAX_TEST_BYTES).decode("utf-8")
    except UnicodeDecodeError as err:
        raise _fail(path, "", "", f"not UTF-8 text (byte {err.start}); save the test as a "
                    "UTF-8 CSV file") from None
    comments, rows = [], []
    for k, line in enumerate(text.splitlines()):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            comments.append(stripped.lstrip("#").strip())
        else:
            rows.append((k + 1, line))
    if not rows:
        raise _fail(path, "", "", "no header and no rows; a test CSV needs a header line and "
                    "one row per frame")
    return comments, rows


def _cells(path: Path, number: int, line: str, count: int | None) -> list[str]:
    where = f"line {number}"
    if len(line) > MAX_COLUMNS * (MAX_CELL_CHARS + 1):
        raise _fail(path, where, "", f"a line of {len(line)} characters; rows hold at most "
                    f"{MAX_COLUMNS} cells of {MAX_CELL_CHARS} characters")
    try:
        cells = [c.strip() for c in next(csv.reader([line]))]
    except csv.Error as err:
        raise _fail(path, where, "", f"not a CSV row ({err})") from None
    if count is not None and len(cells) != count:
        raise _fail(path, where, "", f"expected {count} cells (as the header), got {len(cells)}")
    for cell in cells:
        if len(cell) > MAX_CELL_CHARS:
            raise _fail(path, where, "", f"a cell of {len(cell)} characters; numbers and run "
                        f"labels have at most {MAX_CELL_CHARS}")
    return cells


def _header(path: Path, number: int, line: str, required: tuple[str, ...],
            optional: tuple[str, ...] | None) -> list[str]:
    """The header's names: every required column present, none twice; with ``optional`` given,
    no column outside required + optional."""
    names = _cells(path, number, line, None)
    if len(names) > MAX_COLUMNS:
        raise _fail(path, f"line {number}", "header", f"{len(names)} columns; at most {MAX_COLUMNS}")
    seen = set()
    for name in names:
        if name in seen:
            raise _fail(path, f"line {number}", name, "column named twice in the header")
        seen.add(name)
    missing = [c for c in required if c not in seen]
    if missing:
        raise _fail(path, f"line {number}", "header", f"missing column(s) {', '.join(missing)}; "
                    f"the header needs {','.join(required)}")
    if optional is not None:
        extra = [c for c in names if c not in required + optional]
        if extra:
            raise _fail(path, f"line {number}", extra[0],
                        f"unknown column; allowed: {', '.join(required + optional)}")
    return names


def _number(path: Path, number: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _fail(path, f"line {number}", column, f"expected a number, got {quoted(text)}; "
                    "every cell of this column must be a number") from None
    if not math.isfinite(value) or abs(value) > MAX_MAGNITUDE:
        raise _fail(path, f"line {number}", column, f"must be finite with magnitude <= "
                    f"{MAX_MAGNITUDE:g}, got {quoted(text)}")
    return value


def _table(path: Path, rows: list[tuple[int, str]], names: list[str],
           numeric: tuple[str, ...]) -> tuple[dict[str, np.ndarray], list[str], list[int]]:
    """The numeric columns as arrays, the run labels (or "1") and line numbers."""
    cols = {c: names.index(c) for c in numeric}
    run_col = names.index("run") if "run" in names else None
    data = {c: np.empty(len(rows) - 1) for c in numeric}
    runs, numbers = [], []
    for k, (number, line) in enumerate(rows[1:]):
        cells = _cells(path, number, line, len(names))
        for c, q in cols.items():
            data[c][k] = _number(path, number, c, cells[q])
        label = cells[run_col] if run_col is not None else "1"
        if not label:
            raise _fail(path, f"line {number}", "run", "empty run label")
        runs.append(label)
        numbers.append(number)
    if not runs:
        raise _fail(path, "", "", "a header but no rows; a test needs at least two frames per run")
    return data, runs, numbers


def _groups(runs: list[str]) -> dict[str, np.ndarray]:
    """Row indices of each run label, in the order the runs first appear."""
    out: dict[str, list[int]] = {}
    for k, label in enumerate(runs):
        out.setdefault(label, []).append(k)
    return {label: np.array(idx) for label, idx in out.items()}


def _checked_force(path: Path, label: str, force: np.ndarray) -> None:
    if len(force) < 2:
        raise _fail(path, f"run {label}", "force_N", "a run needs at least two frames")
    if not force.max() > force[0]:
        raise _fail(path, f"run {label}", "force_N", f"the force never rises above the first "
                    f"frame's {force[0]:g} N; a tensile test's force must grow (check the column "
                    "or the run's frames)")
    top = int(np.argmax(force))
    if len(force) - 1 - top > top:
        raise _fail(path, f"run {label}", "force_N", f"the force reaches its largest value "
                    f"{force[top]:g} N at frame {top + 1} of {len(force)} and falls after it for "
                    "most of the run; a tensile test's force must grow (check the column or the "
                    "frames' order; cut the frames after a break)")


def read_stitch_by_stitch(path: Path, file: str) -> MeasuredTest:
    """A tracking file of the published format (module docstring)."""
    comments, rows = _lines(path)
    names = _header(path, rows[0][0], rows[0][1], SBS_COLUMNS, None)
    data, labels, _ = _table(path, rows, names, SBS_COLUMNS[1:])
    runs = []
    for label, idx in _groups(labels).items():
        order = idx[np.argsort(data["frame"][idx], kind="stable")]
        frames = data["frame"][order]
        if np.any(np.diff(frames) == 0):
            raise _fail(path, f"run {label}", "frame", "a frame number appears twice in one run")
        force = data["force_N"][order]
        _checked_force(path, label, force)
        pin = {p: np.stack([data[f"{p}_x"][order], data[f"{p}_y"][order]], axis=1) for p in PINS}
        gauge = np.linalg.norm(pin["top_pin"] - pin["bottom_pin"], axis=1)
        width = np.linalg.norm(pin["right_pin"] - pin["left_pin"], axis=1)
        for name, dist in (("gauge length (top-bottom pins)", gauge),
                           ("width (left-right pins)", width)):
            if not dist[0] > 0:
                raise _fail(path, f"run {label}", "frame", f"the first frame's {name} is zero; "
                            "the pins must be apart to measure strain from them")
        runs.append(Run(label, force, gauge / gauge[0] - 1.0, width / width[0] - 1.0,
                        float(gauge[0] / width[0])))
    width_clamps = None
    for text in comments:
        match = _GEOMETRY.search(text)
        if match:
            width_clamps = _width_clamps(path, match.group(1), match.group(2))
    return MeasuredTest(file, path, "stitch_by_stitch", tuple(runs), width_clamps,
                        comments[0] if comments else "")


def _width_clamps(path: Path, clamp: str, fabric: str) -> float:
    values = []
    for key, text in (("clamp_size_px", clamp), ("fabric_width_px", fabric)):
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and 0 < value <= MAX_MAGNITUDE):
            raise _fail(path, "comment", key, f"must be a positive number of pixels, got "
                        f"{quoted(text)}")
        values.append(value)
    return values[1] / values[0]


def read_columns(path: Path, file: str) -> MeasuredTest:
    """A user's own test: ``force_N, axial_strain[, lateral_strain][, run]``."""
    comments, rows = _lines(path)
    names = _header(path, rows[0][0], rows[0][1], COLUMNS_REQUIRED, COLUMNS_OPTIONAL)
    numeric = COLUMNS_REQUIRED + (("lateral_strain",) if "lateral_strain" in names else ())
    data, labels, _ = _table(path, rows, names, numeric)
    runs = []
    for label, idx in _groups(labels).items():
        force = data["force_N"][idx]
        _checked_force(path, label, force)
        lateral = data["lateral_strain"][idx] if "lateral_strain" in data else None
        runs.append(Run(label, force, data["axial_strain"][idx], lateral))
    return MeasuredTest(file, path, "columns", tuple(runs), None,
                        comments[0] if comments else "")


def read_test(path: Path, file: str, fmt: str) -> MeasuredTest:
    """Read a test file of format ``fmt`` (one of :data:`FORMATS`)."""
    reader = {"stitch_by_stitch": read_stitch_by_stitch, "columns": read_columns}[fmt]
    return reader(path, file)
