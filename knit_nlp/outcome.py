"""What both models' results share: SciPy-like attributes, one ``Energy`` type and a readable repr."""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Energy:
    """Stored energy ``total = spring + bending`` and the loads' work from the natural state (the
    NLP minimises ``total − load_work``). ``float(energy)`` is the total."""

    total: float
    spring: float
    bending: float = 0.0
    load_work: float = 0.0

    def __float__(self) -> float:
        return self.total

    def to_json(self) -> dict[str, float]:
        return {"total": self.total, "spring": self.spring, "bending": self.bending,
                "load_work": self.load_work}


class Outcome:
    """Mixin for solve results, in the manner of ``scipy.optimize.OptimizeResult``.

    Subclasses provide ``success``, ``status`` (the solver's own text), ``iterations`` and
    ``energy``; this adds ``message`` and ``nit`` and a short ``repr``.
    """

    success: bool
    status: str

    @property
    def message(self) -> str:
        """The solver's status text (SciPy's name for it)."""
        return self.status

    @property
    def nit(self) -> int:
        """Iterations (IPOPT's, or explicit steps) (SciPy's name)."""
        return int(self.iterations or 0)        # type: ignore[attr-defined]

    def _repr_fields(self) -> dict[str, object]:
        return {}

    def __repr__(self) -> str:
        fields = {"problem": self.problem.name, "success": self.success,   # type: ignore[attr-defined]
                  "status": self.status, "energy": float(self.energy),     # type: ignore[attr-defined]
                  "nit": self.nit, **self._repr_fields()}
        width = max(len(k) for k in fields)
        body = "\n".join(f"  {k:>{width}}: {v!r}" if not isinstance(v, float)
                         else f"  {k:>{width}}: {v:.6g}" for k, v in fields.items())
        return f"{type(self).__name__}(\n{body}\n)"
