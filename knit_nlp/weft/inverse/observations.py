"""Observed positions of material points (docs/inverse.md, "Identification").

CSV with a header, columns exactly ``case,course,wale,point,x,y``; lines starting with ``#``
before or after the header are comments (extension: how the data were made). Every bad row is
one ProblemError naming the file, the row and the column.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import ProblemError
from ...tomlio import Table, read_regular_file
from ..model.problem import WeftProblem, PointReader

COLUMNS = ["case", "course", "wale", "point", "x", "y"]


@dataclass(frozen=True)
class Observation:
    case: str
    loop: tuple[int, int]
    point: str | float
    s: float
    xy: np.ndarray


MAX_TABLE_BYTES = 8 * 2 ** 20    # an observations CSV (docs/limits.md)


def read_rows(path: Path) -> list[tuple[int, dict[str, str]]]:
    """(line number, row) of every data row; the header must be exactly COLUMNS."""
    try:                    # a regular file of bounded size: no FIFO or /dev/zero (issue 13)
        text = read_regular_file(path, MAX_TABLE_BYTES).decode("utf-8")
    except UnicodeDecodeError as err:
        raise ProblemError(path, "", "", f"not UTF-8 text (byte {err.start})") from None
    lines = [(k + 1, ln) for k, ln in enumerate(text.splitlines())
             if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        raise ProblemError(path, "", "", "no header and no rows")
    header = _cells(path, *lines[0])
    if [h.strip() for h in header] != COLUMNS:
        raise ProblemError(path, f"line {lines[0][0]}", "header",
                           f"columns must be exactly {','.join(COLUMNS)}; got {','.join(header)}")
    rows = []
    for number, ln in lines[1:]:
        cells = _cells(path, number, ln)
        if len(cells) != len(COLUMNS):
            raise ProblemError(path, f"line {number}", "", f"expected {len(COLUMNS)} cells, got {len(cells)}")
        rows.append((number, dict(zip(COLUMNS, (c.strip() for c in cells)))))
    return rows


def _cells(path: Path, number: int, line: str) -> list[str]:
    """The cells of one CSV line; a line the csv module refuses (a cell over its field limit
    of 128 KiB, a stray quote) is one ProblemError naming it."""
    try:
        return next(csv.reader([line]))
    except csv.Error as err:
        raise ProblemError(path, f"line {number}", "", f"not a CSV row ({err})") from None


def _number(path: Path, where: str, key: str, text: str, integer: bool = False) -> float:
    try:
        value = int(text) if integer else float(text)
    except ValueError:
        kind = "an integer" if integer else "a number"
        raise ProblemError(path, where, key, f"expected {kind}, got {text!r}") from None
    if not math.isfinite(value):
        raise ProblemError(path, where, key, f"must be finite, got {text}")
    return value


def load_observations(path: Path | str, problems: dict[str, WeftProblem],
                      other_cases: bool = False) -> list[Observation]:
    """Observations of the named cases, points resolved as clamps' points are; rows of other
    cases are an error unless ``other_cases`` (then skipped)."""
    path = Path(path)
    out = []
    for number, row in read_rows(path):
        where = f"line {number}"
        case = row["case"]
        if case not in problems:
            if other_cases:
                continue
            raise ProblemError(path, where, "case", f"unknown case {case!r}; the problems given "
                               f"are {', '.join(sorted(problems))}")
        pr = problems[case]
        i = int(_number(path, where, "course", row["course"], integer=True))
        j = int(_number(path, where, "wale", row["wale"], integer=True))
        label = row["point"]
        try:
            point: str | float = float(label)
        except ValueError:
            point = label
        tab = Table({"loop": [i, j], "point": point}, path, where)
        reader = PointReader(pr.courses, pr.wales, pr.natural, pr.crossings)
        loop = reader.loop(tab)
        name, s = reader.point(tab)
        xy = np.array([_number(path, where, "x", row["x"]), _number(path, where, "y", row["y"])])
        out.append(Observation(case, loop, name, s, xy))
    if not out:
        raise ProblemError(path, "", "", "no observations")
    return out
