"""Errors a user can cause, reported as one line that names file, table and key (exit code 2)."""
from __future__ import annotations


class ProblemError(Exception):
    """A bad problem file or bad argument.

    ``str(err)`` is the one-line message the CLI prints: ``file: [table] key: message``.
    """

    def __init__(self, file: str, table: str, key: str, message: str) -> None:
        self.file, self.table, self.key, self.message = str(file), table, key, message
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"[{self.table}]" if self.table else "(top level)"
        key = f" {self.key}" if self.key else ""
        return f"{self.file}: {where}{key}: {self.message}"


class ArgumentError(ProblemError):
    """A bad command-line argument (exit code 2): ``str(err)`` is ``ARGUMENT: message``."""

    def __init__(self, argument: str, message: str) -> None:
        super().__init__(argument, "", "", message)

    def __str__(self) -> str:
        return f"{self.file}: {self.message}"
