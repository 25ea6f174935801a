"""The results contract every solve answer keeps (weft, jacquard, control, fit), and what the
models' ``[solver]`` tables share.

A result is a plain dataclass with (SciPy-like, as ``scipy.optimize.OptimizeResult``):

- ``success``: converged (IPOPT's ``Solve_Succeeded``, or the command's own criterion);
- ``status``: a short machine-readable code: IPOPT's return status, or a code of the same form
  (``Converged``, ``Maximum_Steps_Exceeded``, ...); running out of time is
  :data:`OUT_OF_TIME` for every model and command;
- ``message``: one sentence for people (:func:`describe` of the status unless the solver says
  more);
- ``nit``: iterations (IPOPT's, outer iterations of an inverse problem, or explicit steps);
- ``energy``: an :class:`Energy`, also in the JSON (``Energy.to_json``; readers accept the
  older plain number through :meth:`Energy.from_json`);
- ``to_json()``: the result JSON (its only producer); ``save(out_dir)``: the files the command
  line writes (the writing and drawing themselves live in each model's output modules).

Bad Python arguments raise ``ValueError`` naming the argument; bad files raise
:class:`~knit_nlp.errors.ProblemError` naming the file, table and key.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

OUT_OF_TIME = "Maximum_WallTime_Exceeded"   # IPOPT's name; every solver's status when its
#                                             [solver] max_time is spent
MESSAGES = {
    "Solve_Succeeded": "converged",
    "Converged": "converged",
    "Maximum_Iterations_Exceeded": "the iteration limit ([solver] max_iter) was reached",
    "Maximum_CpuTime_Exceeded": "the CPU time limit was reached",
    "Infeasible_Problem_Detected": "the constraints cannot be met (locally infeasible)",
    "Restoration_Failed": "IPOPT's restoration phase failed",
    "Error_In_Step_Computation": "IPOPT could not compute a step",
    "Solved_To_Acceptable_Level": "only IPOPT's acceptable tolerance was reached",
    "Diverging_Iterates": "the iterates diverged",
    "Invalid_Number_Detected": "a non-finite number was met",
}


def out_of_time(max_time: float) -> str:
    """The message of :data:`OUT_OF_TIME`, the same for every model."""
    return f"out of time: the [solver] max_time budget of {max_time:g} s is spent"


def describe(status: str, max_time: float | None = None) -> str:
    """The sentence for a status code (the code itself, spelled out, when unknown)."""
    if status == OUT_OF_TIME and max_time is not None:
        return out_of_time(max_time)
    return MESSAGES.get(status, status.replace("_", " ").lower() or "not solved")


@dataclass(frozen=True)
class SolverOptions:
    """What every model's ``[solver]`` table holds: IPOPT's tolerance ``tol`` and iteration
    limit ``max_iter``, and ``max_time``, the wall-clock budget in seconds of one solve (all its
    solver calls together). Each model extends it with its own keys and defaults."""

    tol: float = 1e-8
    max_iter: int = 3000
    max_time: float = 3600.0


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

    @classmethod
    def from_json(cls, value: Any) -> "Energy":
        """An energy from result JSON: the object ``to_json`` writes, or a plain number (the
        jacquard JSON before the contract was shared: all of it spring energy)."""
        if isinstance(value, dict):
            return cls(float(value["total"]), float(value.get("spring", value["total"])),
                       float(value.get("bending", 0.0)), float(value.get("load_work", 0.0)))
        total = float(value)
        return cls(total, total)


class Outcome:
    """Base of every result class: the contract's derived members and a readable ``repr``.

    Subclasses are dataclasses holding ``success``, ``status`` and ``energy`` (fields or
    properties) and ``iterations``; they implement ``to_json`` and ``save``.
    """

    success: bool
    status: str
    iterations: int | None
    energy: Energy

    @property
    def message(self) -> str:
        """One sentence for people (module docstring)."""
        return describe(self.status)

    @property
    def nit(self) -> int:
        """Iterations (SciPy's name)."""
        return int(self.iterations or 0)

    def to_json(self) -> dict[str, Any]:
        raise NotImplementedError

    def save(self, out_dir: Path | str) -> list[Path]:
        raise NotImplementedError

    def _repr_fields(self) -> dict[str, object]:
        return {}

    def _name(self) -> str:
        return self.problem.name            # type: ignore[attr-defined]

    def __repr__(self) -> str:
        fields = {"problem": self._name(), "success": self.success, "status": self.status,
                  "energy": float(self.energy), "nit": self.nit, **self._repr_fields()}
        width = max(len(k) for k in fields)
        body = "\n".join(f"  {k:>{width}}: {v!r}" if not isinstance(v, float)
                         else f"  {k:>{width}}: {v:.6g}" for k, v in fields.items())
        return f"{type(self).__name__}(\n{body}\n)"
