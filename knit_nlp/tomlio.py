"""Reading TOML problem files with typed, key-checked access (docs/weft_files.md, docs/jacquard.md).

Every read goes through :class:`Table`, which knows the file and table it reads from, checks each
value's type, and rejects keys nobody asked for. Nothing in a problem file is ever executed.
"""
from __future__ import annotations

import difflib
import json
import math
import os
import re
import stat
import tomllib
from pathlib import Path
from typing import Any, Iterable

from .errors import ProblemError, quoted

_MISSING = object()

MAX_PROBLEM_BYTES = 1 << 20      # a problem file is at most 1 MiB (docs/limits.md)
MAX_MAGNITUDE = 1e9              # every number in a problem file has |value| <= 1e9
MAX_INTEGER = 10 ** 9            # and every integer, unless its key says less


def read_regular_file(path: Path, limit: int) -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes, or :class:`ProblemError`.

    Devices, FIFOs, sockets and folders are refused from their ``stat`` before anything is
    opened (so nothing blocks or streams for ever), and at most ``limit + 1`` bytes are read.
    """
    try:
        info = os.stat(path)
        if not stat.S_ISREG(info.st_mode):
            raise ProblemError(path, "", "", "not a regular file (a folder, device or FIFO)")
        if info.st_size > limit:
            raise ProblemError(path, "", "", f"{info.st_size} bytes; the limit is {limit} bytes")
        with open(path, "rb") as fh:
            data = fh.read(limit + 1)
    except FileNotFoundError:
        raise ProblemError(path, "", "", "no such file") from None
    except (OSError, ValueError) as err:     # ValueError: a NUL in the path
        reason = err.strerror if isinstance(err, OSError) and err.strerror else str(err)
        raise ProblemError(path, "", "", f"cannot read it ({reason})") from None
    if len(data) > limit:
        raise ProblemError(path, "", "", f"more than {limit} bytes")
    return data


def load_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; unreadable, oversized or malformed files raise :class:`ProblemError`."""
    data = read_regular_file(path, MAX_PROBLEM_BYTES)
    try:
        return tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as err:
        raise ProblemError(path, "", "", f"not UTF-8 text (byte {err.start})") from None
    except tomllib.TOMLDecodeError as err:
        raise ProblemError(path, "", "", f"not valid TOML ({err})") from None
    except (ValueError, RecursionError) as err:  # e.g. an integer of more than 4300 digits
        raise ProblemError(path, "", "", f"not a usable TOML document ({type(err).__name__}: "
                           f"{str(err)[:80]})") from None


def finite_number(value: Any, limit: float = MAX_MAGNITUDE) -> float:
    """``value`` as a float if it is a (non-boolean) finite number with |value| <= ``limit``;
    else ``ValueError`` with the one-line reason (also used to check Python API arguments)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"expected a number, got {type_name(value)}")
    if isinstance(value, int) and abs(value) > limit:     # before float(): no OverflowError
        raise ValueError(f"must have magnitude <= {limit:g}; got an integer of "
                         f"{len(str(abs(value)))} digits")
    if not math.isfinite(value):
        raise ValueError(f"must be finite, got {value}")
    if abs(value) > limit:
        raise ValueError(f"must have magnitude <= {limit:g}, got {value:g}")
    return float(value)


STEM = re.compile(r"\w[\w .+-]{0,99}")
STEM_RULE = ("a plain file stem: up to 100 letters, digits, '_', '-', '+', '.' or spaces, "
             "starting with a letter, digit or '_', without '..' or a trailing space")


def is_plain_stem(name: str) -> bool:
    """True when ``name`` can name output files inside ``--out`` and nowhere else."""
    return bool(STEM.fullmatch(name)) and ".." not in name and not name.endswith(" ")


def derived_stem(path: Path | str) -> str:
    """A plain stem from a file name: characters outside the stem rule become ``_``."""
    text = re.sub(r"[^\w .+-]", "_", Path(str(path)).stem)[:100].replace("..", "__").rstrip(" ")
    text = text if text and re.match(r"\w", text) else "_" + text
    return text[:100]


def type_name(value: Any) -> str:
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
        self._known: set[str] = set()       # keys asked for (read or tested with ``has``)

    def error(self, key: str, message: str) -> ProblemError:
        return ProblemError(self.file, self.name, key, message)

    def has(self, key: str) -> bool:
        self._known.add(key)
        return key in self.data

    def _raw(self, key: str, default: Any, kind: str = "key") -> Any:
        self._read.add(key)
        self._known.add(key)
        if key not in self.data:
            if default is _MISSING:
                raise self.error(key, f"missing required {kind}{self._found_instead(key)}")
            return default
        return self.data[key]

    def _found_instead(self, key: str) -> str:
        """`` (found unknown table 'fabirc': misspelt?)`` when a key not asked for looks like
        the missing ``key``; else ``""``."""
        unasked = [k for k in self.data if k not in self._known]
        close = difflib.get_close_matches(key, unasked, n=1, cutoff=0.6)
        if not close:
            return ""
        return f" (found unknown {_kind(self.data[close[0]])} {quoted(close[0])}: misspelt?)"

    def integer(self, key: str, default: Any = _MISSING, minimum: int | None = None,
                maximum: int = MAX_INTEGER) -> int:
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected an integer, got {type_name(value)}")
        if minimum is not None and value < minimum:
            raise self.error(key, f"must be >= {minimum}, got {value}")
        if value > maximum:
            raise self.error(key, f"must be <= {maximum}, got {value}")
        return value

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {type_name(value)}")
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
        try:
            return finite_number(value)
        except ValueError as err:
            raise self.error(key, str(err)) from None

    def string(self, key: str, default: Any = _MISSING, choices: Iterable[str] | None = None) -> str:
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        if not isinstance(value, str):
            raise self.error(key, f"expected a string, got {type_name(value)}")
        if choices is not None and value not in choices:
            raise self.error(key, f"must be one of {', '.join(sorted(choices))}; got {quoted(value)}")
        return value

    def stem(self, key: str) -> str:
        """A name for output files (``name``): given, it must be a plain stem
        (:data:`STEM_RULE`); missing, it is derived from the file name."""
        if not self.has(key):
            self._read.add(key)
            return derived_stem(self.file)
        value = self.string(key)
        if not is_plain_stem(value):
            raise self.error(key, f"must be {STEM_RULE}; got {quoted(value)}")
        return value

    def numbers(self, key: str, default: Any = _MISSING, length: int | None = None) -> list[float]:
        """An array of numbers, optionally of a given length."""
        value = self._raw(key, default)
        if value is default and key not in self.data:
            return value
        if not isinstance(value, list):
            raise self.error(key, f"expected an array of numbers, got {type_name(value)}")
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
        if any(abs(v) > MAX_INTEGER for v in value):
            raise self.error(key, f"entries must lie in [-{MAX_INTEGER}, {MAX_INTEGER}]")
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
                raise self.error(key, f"unknown entry {quoted(bad[0])}; allowed: {', '.join(choices)}")
        return list(value)

    def value(self, key: str, default: Any = _MISSING) -> Any:
        """The raw value, for keys whose type the caller checks (e.g. string-or-number)."""
        return self._raw(key, default)

    def table(self, key: str, required: bool = False) -> "Table":
        value = self._raw(key, _MISSING if required else {}, "table")
        if not isinstance(value, dict):
            got = (f"an array of tables ([[{key}]]): write [{key}]" if _kind(value) == "table"
                   else type_name(value))
            raise self.error(key, f"expected a table, got {got}")
        return Table(value, self.file, key if not self.name else f"{self.name}.{key}")

    def tables(self, key: str) -> list["Table"]:
        """An array of tables (``[[key]]``); messages name them ``key[1]``, ``key[2]``..."""
        value = self._raw(key, [])
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            hint = f": write [[{key}]], not [{key}]" if isinstance(value, dict) else ""
            raise self.error(key, f"expected an array of tables ([[{key}]]){hint}")
        return [Table(v, self.file, f"{key}[{k + 1}]") for k, v in enumerate(value)]

    def allow(self, *keys: str) -> None:
        """Reject at once any key outside ``keys`` (so a misspelt key is named as such before it
        can cause a confusing error about a missing one)."""
        for key in self.data:
            if key not in keys:
                raise self.error(key, f"unknown key (allowed: {', '.join(keys)})")

    def finish(self) -> None:
        """Reject keys that were never read (the contract: unknown keys are an error), naming
        the nearest known key and the keys allowed here."""
        for key in self.data:
            if key not in self._read:
                raise self.error(key, self._unknown(key))

    def _unknown(self, key: str) -> str:
        """``unknown table (misspelt 'fabric'?; allowed: ...)`` for a key nobody asked for."""
        known = sorted(self._known - set(self.data)) or sorted(self._known)
        close = difflib.get_close_matches(key, known, n=1, cutoff=0.6)
        hint = f"misspelt {quoted(close[0])}?; " if close else ""
        allowed = f"allowed: {', '.join(sorted(self._known))}" if self._known else "no keys allowed here"
        return f"unknown {_kind(self.data[key])} ({hint}{allowed})"


def _kind(value: Any) -> str:
    """How a message calls a file's entry: a ``table`` (``[x]``, ``[[x]]``) or a ``key``."""
    if isinstance(value, dict) or (isinstance(value, list) and value
                                   and all(isinstance(v, dict) for v in value)):
        return "table"
    return "key"


def toml_text(doc: dict[str, Any]) -> str:
    """A problem document as TOML: top-level values, then tables, then arrays of tables
    (values: strings, booleans, numbers and arrays of them, as problem files hold)."""
    lines = [f"{k} = {_value(v)}" for k, v in doc.items() if not isinstance(v, (dict, list))
             or (isinstance(v, list) and not all(isinstance(e, dict) for e in v))]
    for key, value in doc.items():
        if isinstance(value, dict):
            lines += ["", f"[{key}]", *(f"{k} = {_value(v)}" for k, v in value.items())]
    for key, value in doc.items():
        if isinstance(value, list) and value and all(isinstance(e, dict) for e in value):
            for table in value:
                lines += ["", f"[[{key}]]", *(f"{k} = {_value(v)}" for k, v in table.items())]
    return "\n".join(lines) + "\n"


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)             # Python's shortest round-trip form, valid TOML for finite
    if isinstance(v, str):
        return json.dumps(v)       # a JSON string is a TOML basic string
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(e) for e in v) + "]"
    raise TypeError(f"no TOML form for {type(v).__name__}")
