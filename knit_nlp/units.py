"""Units of a problem: names only. Numbers in a file are taken in the units it names and come
out in them; nothing is converted (docs/conventions.md, "Units", is the one description)."""
from __future__ import annotations

from dataclasses import dataclass
from .tomlio import Table

DEFAULT_LENGTH = "units"
DEFAULT_FORCE = "force units"


@dataclass(frozen=True)
class Units:
    """The length and force unit a problem's numbers are in (the ``[units]`` table)."""

    length: str = DEFAULT_LENGTH
    force: str = DEFAULT_FORCE

    @property
    def energy(self) -> str:
        """Force × length, or "energy units" when neither is named."""
        if (self.length, self.force) == (DEFAULT_LENGTH, DEFAULT_FORCE):
            return "energy units"
        return f"{self.force}·{self.length}"

    def to_json(self) -> dict[str, str]:
        return {"length": self.length, "force": self.force, "energy": self.energy}


def read_units(tab: "Table") -> Units:
    """The ``[units]`` table: ``length`` and ``force``, short printable names (e.g. "mm", "N")."""
    names = []
    for key, default in (("length", DEFAULT_LENGTH), ("force", DEFAULT_FORCE)):
        value = tab.string(key, default)
        if not value.strip() or len(value) > 16 or not value.isprintable():
            raise tab.error(key, f"must be a short printable unit name (1-16 characters), "
                            f"got {value!r}")
        names.append(value)
    tab.finish()
    return Units(*names)
