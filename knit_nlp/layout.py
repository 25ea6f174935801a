"""Named blocks of a flat vector (decision variables, parameters, constraints of an NLP)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Layout:
    """Where each block lives in a flat vector: name -> (start, stop) and block shape."""

    blocks: dict[str, tuple[int, int, tuple[int, int]]] = field(default_factory=dict)
    size: int = 0

    def add(self, name: str, rows: int, cols: int) -> slice:
        """Append a block; returns its slice."""
        self.blocks[name] = (self.size, self.size + rows * cols, (rows, cols))
        self.size += rows * cols
        return self.slice(name)

    def slice(self, name: str) -> slice:
        start, stop, _ = self.blocks[name]
        return slice(start, stop)

    def get(self, vec: np.ndarray, name: str) -> np.ndarray:
        """The block of ``vec`` as an array of its shape (column-major, like CasADi)."""
        start, stop, shape = self.blocks[name]
        return np.asarray(vec, dtype=float).ravel()[start:stop].reshape(shape, order="F")

    def put(self, vec: np.ndarray, name: str, value: np.ndarray) -> None:
        start, stop, _ = self.blocks[name]
        vec[start:stop] = np.asarray(value, dtype=float).ravel(order="F")
