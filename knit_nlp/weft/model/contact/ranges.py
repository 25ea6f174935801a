"""Index ranges flattened: the vectorised "for each query, every candidate in its sorted range"
that the pair search, the designed zones and the rounds' pair matching share."""
from __future__ import annotations

import numpy as np


def expand(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every index of the half-open ranges [lo_i, hi_i), in order, and the i it belongs to:
    (owner, rows), each of length Σ (hi − lo)."""
    lo, hi = np.asarray(lo), np.asarray(hi)
    counts = hi - lo
    owner = np.repeat(np.arange(lo.size), counts)
    rows = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + \
        np.repeat(lo, counts)
    return owner, rows
