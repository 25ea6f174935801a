"""Which problem file a result came from, and the refusal to overwrite another problem's result.

A result JSON records ``"source": {"file": ..., "sha256": ...}`` (docs/weft_files.md, docs/jacquard.md). A
run whose outputs would replace a result recorded from a *different* problem (another file whose
content also differs) stops with a ProblemError unless forced; re-running the same file, or an
edited version of the same file, overwrites as before.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Iterable

from .errors import ProblemError


def source_record(source: str | Path) -> dict[str, str] | None:
    """``{"file": absolute path, "sha256": content hash}`` of a problem file; None for a problem
    that was not read from a file."""
    path = Path(source)
    try:
        data = path.read_bytes()
    except OSError:
        return None
    return {"file": str(path.resolve()), "sha256": hashlib.sha256(data).hexdigest()}


def _recorded(path: Path) -> dict[str, Any] | None:
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    src = doc.get("source") if isinstance(doc, dict) else None
    return src if isinstance(src, dict) else None


def check_overwrite(outputs: Iterable[Path], source: str | Path, force: bool = False) -> None:
    """Refuse (ProblemError naming the clash) when any existing result JSON in ``outputs``
    records another problem: a different file and different content than ``source``."""
    mine = source_record(source)
    if force or mine is None:
        return
    for out in outputs:
        theirs = _recorded(out) if out.suffix == ".json" and out.exists() else None
        if theirs and theirs.get("file") != mine["file"] and theirs.get("sha256") != mine["sha256"]:
            raise ProblemError(source, "", "name", f"{out} holds the result of another problem "
                               f"({theirs.get('file')}); give this problem its own name or "
                               "--out folder, or pass --force to overwrite it")
