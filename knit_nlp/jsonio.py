"""Writing result JSON: numpy scalars and arrays become plain JSON numbers and lists."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from .atomic import write_text


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
    """Write ``data`` as indented JSON (non-finite numbers become null), creating the folder;
    atomically (:mod:`knit_nlp.atomic`)."""
    return write_text(path, json.dumps(_plain(data), indent=1) + "\n")
