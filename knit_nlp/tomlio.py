"""Reading TOML problem files with typed, key-checked access (README, "Weft problem files").

Every read goes through :class:`Table`, which knows the file and table it reads from, checks each
value's type, and rejects keys nobody asked for. Nothing in a problem file is ever executed.
"""
from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any, Iterable

from .errors import ProblemError

_MISSING = object()


def load_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; unreadable or malformed files raise :class:`ProblemError`."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ProblemError(path, "", "", "no such file") from None
    except tomllib.TOMLDecodeError as err:
        raise ProblemError(path, "", "", f"not valid TOML ({err})") from None
    except (OSError, UnicodeDecodeError) as err:
        raise ProblemError(path, "", "", f"cannot read file ({err})") from None


def _type_name(value: Any) -> str:
    return {bool: "boolean", int: "integer", float: "number", str: "string",
            list: "array", dict: "table"}.get(type(value), type(value).__name__)


class Table:
    """One TOML table of a problem file, read key by key.

    ``name`` is how messages name the table (``fabric``, ``clamp[2]``, ``""`` for the top level).
    Call :meth:`finish` after reading: any key not read is reported as unknown.
    """

    def __init__(self, data: dict[str, Any], file: Path | str, name: str) -> None:
        self.data, self.file, self.name = data, str(file), name
        self._read: set[str] = set()

    def error(self, key: str, message: str) -> ProblemError:
        return ProblemError(self.file, self.name, key, message)

    def has(self, key: str) -> bool:
        return key in self.data

    def _raw(self, key: str, default: Any) -> Any:
        self._read.add(key)
        if key not in self.data:
            if default is _MISSING:
                raise self.error(key, "missing required key")
            return default
        return self.data[key]

    def integer(self, key: str, default: Any = _MISSING, minimum: int | None = None) -> int:
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected an integer, got {_type_name(value)}")
        if minimum is not None and value < minimum:
            raise self.error(key, f"must be >= {minimum}, got {value}")
        return value

    def number(self, key: str, default: Any = _MISSING, *, positive: bool = False,
               nonnegative: bool = False) -> float:
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        value = self._as_float(key, value)
        if positive and not value > 0:
            raise self.error(key, f"must be positive, got {value:g}")
        if nonnegative and value < 0:
            raise self.error(key, f"must not be negative, got {value:g}")
        return value

    def _as_float(self, key: str, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.error(key, f"expected a number, got {_type_name(value)}")
        if not math.isfinite(value):
            raise self.error(key, f"must be finite, got {value}")
        return float(value)

    def string(self, key: str, default: Any = _MISSING, choices: Iterable[str] | None = None) -> str:
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        if not isinstance(value, str):
            raise self.error(key, f"expected a string, got {_type_name(value)}")
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {', '.join(sorted(choices))}; got {value!r}")
        return value

    def numbers(self, key: str, default: Any = _MISSING, length: int | None = None) -> list[float]:
        """An array of numbers, optionally of a given length."""
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        if not isinstance(value, list):
            raise self.error(key, f"expected an array of numbers, got {_type_name(value)}")
        if length is not None and len(value) != length:
            raise self.error(key, f"expected {length} numbers, got {len(value)}")
        return [self._as_float(key, v) for v in value]

    def integers(self, key: str, default: Any = _MISSING, length: int | None = None) -> list[int]:
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        if not isinstance(value, list) or any(isinstance(v, bool) or not isinstance(v, int)
                                              for v in value):
            raise self.error(key, "expected an array of integers")
        if length is not None and len(value) != length:
            raise self.error(key, f"expected {length} integers, got {len(value)}")
        return list(value)

    def strings(self, key: str, default: Any = _MISSING, choices: Iterable[str] | None = None) -> list[str]:
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.error(key, "expected an array of strings")
        if choices is not None:
            bad = [v for v in value if v not in choices]
            if bad:
                raise self.error(key, f"unknown entry {bad[0]!r}; allowed: {', '.join(choices)}")
        return list(value)

    def value(self, key: str, default: Any = _MISSING) -> Any:
        """The raw value, for keys whose type the caller checks (e.g. string-or-number)."""
        return self._raw(key, default)

    def table(self, key: str, required: bool = False) -> "Table":
        value = self._raw(key, _MISSING if required else {})
        if not isinstance(value, dict):
            raise self.error(key, f"expected a table, got {_type_name(value)}")
        return Table(value, self.file, key if not self.name else f"{self.name}.{key}")

    def tables(self, key: str) -> list["Table"]:
        """An array of tables (``[[key]]``); messages name them ``key[1]``, ``key[2]``..."""
        value = self._raw(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error(key, "expected an array of tables ([[%s]])" % key)
        return [Table(v, self.file, f"{key}[{k + 1}]") for k, v in enumerate(value)]

    def allow(self, *keys: str) -> None:
        """Reject at once any key outside ``keys`` (so a misspelt key is named as such before it
        can cause a confusing error about a missing one)."""
        for key in self.data:
            if key not in keys:
                raise self.error(key, f"unknown key (allowed: {', '.join(keys)})")

    def finish(self) -> None:
        """Reject keys that were never read (the contract: unknown keys are an error)."""
        for key in self.data:
            if key not in self._read:
                raise self.error(key, "unknown key")
