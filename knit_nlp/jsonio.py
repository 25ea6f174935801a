"""Writing result files: JSON (numpy scalars and arrays become plain numbers and lists), NPZ, CSV."""
from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np


def _plain(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    return obj


def write_json(path: Path, data: dict[str, Any]) -> Path:
    """Write ``data`` as indented JSON (non-finite numbers become null), creating the folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(_plain(data), indent=1) + "\n")
    return path


def write_npz(path: Path, **arrays: np.ndarray) -> Path:
    """Write arrays to a compressed NPZ, creating the folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)
    return path


def write_csv(path: Path, rows: Sequence[Mapping[str, Any]],
              fields: Sequence[str] | None = None) -> Path:
    """A study table as CSV (columns ``fields``, default the first row's keys)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(fields or rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path
