"""Atomic result files: written to a temporary file in the target's folder, then renamed.

A run killed while writing leaves the previous file (or none) and a stray ``.<name>.*<suffix>``,
never a truncated or half-new result: ``os.replace`` within one folder is atomic on POSIX.
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any, Iterator


def _file_mode() -> int:
    """The permissions an ordinary new file gets under the current umask."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


@contextmanager
def atomic_file(path: Path, mode: str = "wb", **open_args: Any) -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path`` for writing; on success flush it to disk and
    rename it to ``path``; on any error remove it and leave ``path`` as it was."""
    with temporary_path(path) as tmp, open(tmp, mode, **open_args) as fh:
        yield fh
        fh.flush()
        os.fsync(fh.fileno())


def write_text(path: Path, text: str) -> Path:
    """``path`` atomically holding ``text`` (UTF-8)."""
    with atomic_file(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    return Path(path)


@contextmanager
def temporary_path(path: Path) -> Iterator[Path]:
    """For writers that want a file name (e.g. matplotlib's PillowWriter): a temporary name
    beside ``path`` with the same suffix, renamed to ``path`` on success, removed on error."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, _file_mode())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
