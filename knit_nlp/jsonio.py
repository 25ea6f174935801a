"""Writing result files: JSON (numpy scalars and arrays become plain numbers and lists), NPZ, CSV;
each atomically (a temporary file in the same folder, then renamed: :mod:`knit_nlp.atomic`)."""
from __future__ import annotations

import csv
import json
import re
import secrets
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .atomic import atomic_file, write_text


_TOKEN = secrets.token_hex(8)
BULK = 1024      # arrays of at least this many numbers are written by ``array_text``


def array_text(a: np.ndarray) -> str:
    """JSON text of a real or integer array as nested lists: the numbers exactly as
    ``json.dumps`` writes them (``repr``: shortest round-trip; null where not finite), one
    innermost list per line. Formatted in bulk by one ``%`` operation per array, about 5x
    faster than ``json.dumps(tolist(), indent=...)`` for half a million particles (which
    also put every number on a line of its own)."""
    if a.ndim == 0 or a.size == 0:
        return json.dumps(_plain(a.tolist()))
    values = a.ravel().tolist()
    spec = "%r" if a.dtype.kind == "f" else "%d"
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        spec, values = "%s", [repr(v) if np.isfinite(v) else "null" for v in values]
    inner = "[" + ", ".join([spec] * a.shape[-1]) + "]"
    if a.ndim == 1:
        return inner % tuple(values)
    # blocks of the last two axes in one formatting operation, split by a NUL (never in a
    # number), then the brackets of the outer axes around groups of blocks
    block = "[" + ",\n ".join([inner] * a.shape[-2]) + "]"
    blocks = ((block + "\x00") * (a.size // (a.shape[-1] * a.shape[-2])) % tuple(values))
    lines = blocks[:-1].split("\x00")
    for size in reversed(a.shape[:-2]):
        lines = ["[" + ",\n ".join(lines[i:i + size]) + "]" for i in range(0, len(lines), size)]
    return lines[0]


def _plain(obj: Any, bulk: dict[str, str] | None = None) -> Any:
    """Plain JSON values; with ``bulk``, large numeric arrays are replaced by marker strings
    and their text (``array_text``) is put in ``bulk`` under the marker."""
    if isinstance(obj, dict):
        return {str(k): _plain(v, bulk) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v, bulk) for v in obj]
    if isinstance(obj, np.ndarray):
        if bulk is not None and obj.size >= BULK and obj.dtype.kind in "fiu":
            marker = f"\x00{_TOKEN}{len(bulk)}\x00"   # no other string can be this
            bulk[json.dumps(marker)] = array_text(obj)
            return marker
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def json_text(data: dict[str, Any]) -> str:
    """``data`` as indented JSON (non-finite numbers become null); numeric arrays of at least
    ``BULK`` numbers one innermost list per line (``array_text``)."""
    bulk: dict[str, str] = {}
    text = json.dumps(_plain(data, bulk), indent=1)
    if not bulk:
        return text + "\n"
    pattern = re.compile("|".join(map(re.escape, bulk)))
    return pattern.sub(lambda m: bulk[m.group(0)], text) + "\n"


def write_json(path: Path, data: dict[str, Any]) -> Path:
    """Write ``data`` as ``json_text``, creating the folder."""
    return write_text(path, json_text(data))


def write_npz(path: Path, **arrays: np.ndarray) -> Path:
    """Write arrays to a compressed NPZ, creating the folder."""
    with atomic_file(path) as fh:
        np.savez_compressed(fh, **arrays)
    return path


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]],
              fields: Sequence[str] | None = None) -> Path:
    """A study table as CSV (columns ``fields``, default the first row's keys)."""
    with atomic_file(path, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(fields or rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path
