"""Errors a user can cause, reported as one line that names file, table and key (exit code 2).

Everything a message shows that came from the user (file names, keys, values) passes through
:func:`shown`, so a message is always one line of printable text: control characters, NUL and
escape sequences are shown escaped, and long values are cut.
"""
from __future__ import annotations

MAX_SHOWN = 60


def shown(value: object, limit: int = MAX_SHOWN) -> str:
    """``value`` as printable one-line text: non-printable characters escaped (``\\x1b``),
    at most ``limit`` characters (a cut value ends in ``...``)."""
    text = str(value)
    escaped = "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii")
                      for c in text)
    return escaped if len(escaped) <= limit else escaped[:limit] + "..."


def quoted(value: object, limit: int = MAX_SHOWN) -> str:
    """``value`` quoted for a message: ``'...'`` around :func:`shown`."""
    return f"'{shown(value, limit)}'"


class ProblemError(Exception):
    """A bad problem file or bad argument.

    ``str(err)`` is the one-line message the CLI prints: ``file: [table] key: message``, or
    ``file: (top level) key: message`` for a top-level key, ``file: message`` for the whole file
    (or a flag: "(top level)" names file keys only).
    """

    def __init__(self, file: object, table: str, key: str, message: str) -> None:
        self.file, self.table, self.key, self.message = str(file), table, key, message
        super().__init__(str(self))

    def __str__(self) -> str:
        if not self.table and not self.key:          # the whole file, or a flag such as --out
            return f"{shown(self.file, 200)}: {shown(self.message, 400)}"
        where = f"[{shown(self.table)}]" if self.table else "(top level)"
        key = f" {shown(self.key)}" if self.key else ""
        return f"{shown(self.file, 200)}: {where}{key}: {shown(self.message, 400)}"


class ArgumentError(ProblemError):
    """A bad command-line argument (exit code 2): ``str(err)`` is ``ARGUMENT: message``."""

    def __init__(self, argument: str, message: str) -> None:
        super().__init__(argument, "", "", message)

    def __str__(self) -> str:
        return f"{shown(self.file, 200)}: {shown(self.message, 400)}"
