"""The output folder of every command (``--out``): checked before anything is solved, created
only once the input has been read and checked, so bad input writes nothing."""
from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

from .errors import ArgumentError, ProblemError, quoted, shown

OUTPUT_SUFFIXES = ("json", "npz", "png", "svg", "csv", "gif")


def check_out(out: str) -> Path:
    """The output folder, checked without creating anything: refused (one line, exit 2) if it
    names a file, lies under a file, or its nearest existing folder cannot be written."""
    folder = Path(out)
    if not out or "\0" in out:
        raise ProblemError("--out", "", "", f"not a usable folder name: {quoted(out)}")
    try:
        if folder.exists() and not folder.is_dir():
            raise ProblemError(out, "", "", "--out names an existing file; give a folder")
        existing = next(p for p in (folder, *folder.absolute().parents) if p.exists())
    except OSError as err:
        raise ProblemError(out, "", "", f"cannot create the output folder "
                           f"({shown(err.strerror or err)})") from None
    if not existing.is_dir():
        raise ProblemError(out, "", "", f"--out lies under {quoted(existing)}, which is "
                           "not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ProblemError(out, "", "", f"cannot create the output folder (cannot write into "
                           f"{quoted(existing)})")
    return folder


def prepare_out(out: str, name: str, kinds: tuple[str, ...],
                files: tuple[str, ...] = ()) -> Path:
    """The output folder, checked (:func:`check_out`), created and shown writable by creating
    and removing a file in it (``os.access`` tells root that /proc may be written); also
    refused if it holds a non-file where an output must go: ``<name>.<kind>.<suffix>`` for
    each kind, and each of ``files``. Called after the input is read and checked, before
    solving: bad input writes nothing, and a folder nothing can be written to is found before
    the solve, not after."""
    folder = check_out(out)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as err:
        raise ProblemError(out, "", "", f"cannot create the output folder or write into it "
                           f"({shown(err.strerror or err)})") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ProblemError(out, "", "", "cannot write into the output folder")
    names = [f"{name}.{kind}.{suffix}" for kind in kinds for suffix in OUTPUT_SUFFIXES]
    check_files(out, folder, (*names, *files))
    return folder


def check_files(out: str, folder: Path, names: tuple[str, ...] | list[str]) -> None:
    """Refuse (one line naming ``out``) if any of ``names`` in ``folder`` exists and is not a
    regular file: a result cannot be written there."""
    for file_name in names:
        target = folder / file_name
        if target.exists() and not target.is_file():
            raise ProblemError(out, "", "", f"{quoted(target.name)} exists and is not a "
                               "file; results cannot be written there: remove it or choose "
                               "another --out")


def output_name(flag: str, name: str) -> str:
    """A name given for output files (``--name``): letters, digits, ``_ - . +``, not starting
    with a dot, at most 100 characters, so it names files in ``--out`` and nowhere else."""
    if not re.fullmatch(r"[A-Za-z0-9_+\-][A-Za-z0-9_.+\-]*", name) or len(name) > 100:
        raise ArgumentError(f"{flag} {name}", "use letters, digits, '_', '-', '+' and '.' "
                            "(not first), at most 100 characters")
    return name
