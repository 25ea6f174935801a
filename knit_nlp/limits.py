"""Size limits: problems whose estimated peak memory exceeds a documented limit are refused
before anything is built (docs/limits.md).

The estimates are linear fits to measured peak memory (docs/measurements.md and
docs/jacquard.md, one process each on the 2-core, 24 GiB development machine):

- weft, t = 3, 8 quadrature nodes: 5 × 5 109 MB, 50 × 50 259 MB, 100 × 100 758 MB, i.e. about
  110 MB of Python, CasADi and IPOPT plus 65 kB per loop. Per loop the Hessian block grows with
  the square of the 2t + 2 loop parameters and the quadrature work with the nodes per panel, so
  the per-loop figure is scaled by ((2t + 2)/8)² · max(1, nodes/8) (an extrapolation: only
  t = 3, 8 nodes was measured at scale).
- check's gap search (``model/contact/pairs.py``, chunked by ``near.neighbours``): its memory is
  bounded by its chunks (10 x 10 at r = 1.0: 246 MB; the paper's 100 x 100 pull judged at
  r = 0.15: 580 MB), its time is not; it is refused above ``CHECK_ROWS`` estimated sample pairs.
  Its pace, measured on a loaded 2-core machine (load average 5): 1.8e6 sample pairs in 5.7 s
  (10 x 10, r = 1.0), 4.8e7 in 127 s (100 x 100, r = 0.15, 1.6 million short gaps), about
  3e5 a second (``ROWS_PER_SECOND``): the limit is some 5 minutes of searching.
- jacquard, static solver: 500 × 500 (250 000 particles) 1.9 GB, i.e. about 110 MB plus
  7.2 kB per particle. The explicit solver needs less; the same estimate bounds both.
"""
from __future__ import annotations

from .tomlio import Table

MEMORY_LIMIT_BYTES = 8 * 2 ** 30      # a third of the development machine's 24 GiB
BASE_BYTES = 110e6
WEFT_LOOP_BYTES = 65e3                # t = 3, 8 nodes per panel
JACQUARD_PARTICLE_BYTES = 7.2e3


def weft_bytes(courses: int, wales: int, harmonics: int, nodes: int) -> float:
    """Estimated peak memory of a weft solve (module docstring)."""
    per_loop = WEFT_LOOP_BYTES * ((2 * harmonics + 2) / 8) ** 2 * max(1.0, nodes / 8)
    return BASE_BYTES + float(courses) * float(wales) * per_loop


def jacquard_bytes(wales: int, courses: int) -> float:
    """Estimated peak memory of a jacquard solve (module docstring)."""
    return BASE_BYTES + float(wales) * float(courses) * JACQUARD_PARTICLE_BYTES


def check_memory(table: Table, key: str, estimate: float, what: str) -> None:
    """Refuse, naming ``key`` of ``table``, a problem estimated above the memory limit."""
    if estimate > MEMORY_LIMIT_BYTES:
        raise table.error(key, f"{what} needs an estimated {estimate / 2 ** 30:.3g} GiB; the "
                          f"limit is {MEMORY_LIMIT_BYTES / 2 ** 30:g} GiB (docs/limits.md)")


CHECK_ROWS = 1e8                      # sample pairs check's gap search may look at (docstring)
ROWS_PER_SECOND = 3e5                 # the gap search's pace (docstring)


def too_large(rows: float, radius: float, per_loop: int) -> str:
    """The one-line refusal of a gap search estimated at ``rows`` sample pairs."""
    return (f"r = {radius:g} at {per_loop} samples per loop needs an estimated {rows:.3g} sample "
            f"pairs (about {rows / ROWS_PER_SECOND / 60:.2g} min); the limit is "
            f"{CHECK_ROWS:.3g} (docs/limits.md): a radius this large against the fabric's "
            "spacing makes every piece a neighbour of every other")
