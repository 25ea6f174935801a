"""The weft NLP's parameters: everything a solve may change without rebuilding the NLP.

Clamp targets and angles, the stiffnesses k_a, k_b (eqs. 6-7) and R_f (eq. 11), point loads
(forces and moments) and rigid-clamp motions are CasADi parameters of the NLP, so one build
serves continuation, studies and inverse problems. :class:`WeftParams` is their one typed form;
``vector()`` packs them in the order of :func:`param_layout`, the only place that order lives.

Clamps, loads and rigid clamps are numbered from 1, as in problem files and results.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Mapping, Sequence

import numpy as np

from ...errors import shown
from ...layout import Layout
from ...tomlio import MAX_MAGNITUDE
from .basis import phi
from .problem import WeftProblem
from .reach import unreachable

MATERIAL = ("k_a", "k_b", "R_f")


def param_layout(pr: WeftProblem) -> Layout:
    """Blocks of the NLP's parameter vector: targets (2 × clamps), angles (one per clamp that
    holds an angle), k_a, k_b, R_f, forces (2 × loads), moments, rigid (tx, ty, φ per rigid clamp)."""
    pl = Layout()
    pl.add("targets", 2, len(pr.clamps))
    pl.add("angles", sum(c.angle is not None for c in pr.clamps), 1)
    for name in MATERIAL:
        pl.add(name, 1, 1)
    pl.add("forces", 2, len(pr.loads))
    pl.add("moments", len(pr.loads), 1)
    pl.add("rigid", 3, len(pr.rigid_clamps))
    return pl


def _index(k: int | str, count: int, what: str) -> int:
    """0-based position of a 1-based ``what`` number (an int, or its digits as JSON keys are), checked."""
    if isinstance(k, str) and k.isdigit():
        k = int(k)
    if not isinstance(k, int) or isinstance(k, bool) or not 1 <= k <= count:
        raise ValueError(f"{what} {shown(k)} does not exist: the problem has {count} {what}s, "
                         f"numbered from 1")
    return int(k) - 1


def _finite(value: Sequence[float] | float, shape: tuple[int, ...], what: str) -> np.ndarray:
    """``value`` as finite numbers of ``shape`` with magnitude <= MAX_MAGNITUDE, as the file
    reader accepts them (tomlio)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        arr = np.full(shape, np.nan)
    if arr.shape != shape or not np.all(np.isfinite(arr)) or np.any(np.abs(arr) > MAX_MAGNITUDE):
        raise ValueError(f"{what} must be {'a number' if not shape else f'{shape[0]} numbers'}, "
                         f"finite, of magnitude <= {MAX_MAGNITUDE:g}; got {shown(value)}")
    return arr


@dataclass(frozen=True)
class WeftParams:
    """Parameter values of one solve (arrays are copies; use :meth:`with_` to change them).

    ``targets`` (clamps, 2) absolute clamp targets; ``angles`` (clamps,) the held tangent angle,
    NaN for a clamp that holds none; ``forces`` (loads, 2); ``moments`` (loads,); ``rigid``
    (rigid clamps, 3) translation x, y and rotation.
    """

    problem: WeftProblem = field(repr=False, compare=False)
    targets: np.ndarray
    angles: np.ndarray
    k_a: float
    k_b: float
    R_f: float
    forces: np.ndarray
    moments: np.ndarray
    rigid: np.ndarray

    @classmethod
    def of(cls, pr: WeftProblem) -> "WeftParams":
        """The problem file's own values."""
        return cls(pr, np.array([c.target for c in pr.clamps]).reshape(-1, 2),
                   np.array([np.nan if c.angle is None else c.angle for c in pr.clamps]),
                   pr.k_a, pr.k_b, pr.R_f,
                   np.array([ld.force for ld in pr.loads]).reshape(-1, 2),
                   np.array([ld.moment for ld in pr.loads], dtype=float),
                   np.array([[*r.translation, r.rotation] for r in pr.rigid_clamps]).reshape(-1, 3))

    @classmethod
    def natural(cls, pr: WeftProblem) -> "WeftParams":
        """Values that leave the natural configuration in equilibrium: targets at the natural
        positions, held angles at the natural angles, no loads, rigid clamps unmoved; the
        stiffnesses are the problem's."""
        own = cls.of(pr)
        angles = np.array([np.nan if c.angle is None else float(phi(c.s, pr.L, pr.t)[0]
                                                               @ pr.natural.coeffs)
                           for c in pr.clamps])
        return replace(own, targets=np.array([pr.natural_position(c.loop, c.s)
                                              for c in pr.clamps]).reshape(-1, 2),
                       angles=angles, forces=np.zeros_like(own.forces),
                       moments=np.zeros_like(own.moments), rigid=np.zeros_like(own.rigid))

    def with_(self, *, targets: Mapping[int, Sequence[float]] | None = None,
              displacements: Mapping[int, Sequence[float]] | None = None,
              angles: Mapping[int, float] | None = None,
              material: Mapping[str, float] | None = None,
              forces: Mapping[int, Sequence[float]] | None = None,
              moments: Mapping[int, float] | None = None,
              rigid: Mapping[int, Sequence[float]] | None = None) -> "WeftParams":
        """A copy with the named values changed, checked as a problem file is.

        ``targets`` / ``displacements``: clamp number (from 1) -> absolute target / displacement
        from the point's natural position; ``angles``: clamp number -> held angle (rad);
        ``material``: any of k_a, k_b, R_f (finite, >= 0); ``forces`` / ``moments``: load number
        -> value; ``rigid``: rigid-clamp number -> (tx, ty, rotation).
        """
        pr = self.problem
        tgt, ang = self.targets.copy(), self.angles.copy()
        for k, v in (targets or {}).items():
            tgt[_index(k, len(pr.clamps), "clamp")] = _finite(v, (2,), f"target of clamp {k}")
        for k, v in (displacements or {}).items():
            c = pr.clamps[_index(k, len(pr.clamps), "clamp")]
            tgt[_index(k, len(pr.clamps), "clamp")] = pr.natural_position(c.loop, c.s) + _finite(
                v, (2,), f"displacement of clamp {k}")
        for k, v in (angles or {}).items():
            q = _index(k, len(pr.clamps), "clamp")
            if pr.clamps[q].angle is None:
                raise ValueError(f"clamp {k} holds no angle (add angle = ... to its table)")
            ang[q] = _finite(v, (), f"angle of clamp {k}")
        mat = {}
        for name, v in (material or {}).items():
            if name not in MATERIAL:
                raise ValueError(f"unknown material value {name!r}; use {', '.join(MATERIAL)}")
            value = float(_finite(v, (), name))
            if value < 0 or (name == "R_f" and value == 0):   # R_f = 0: loops bend freely
                raise ValueError(f"{name} must be {'positive' if name == 'R_f' else '>= 0'}; "
                                 f"got {value!r}")
            mat[name] = value
        frc, mom, rig = self.forces.copy(), self.moments.copy(), self.rigid.copy()
        for k, v in (forces or {}).items():
            frc[_index(k, len(pr.loads), "load")] = _finite(v, (2,), f"force of load {k}")
        for k, v in (moments or {}).items():
            mom[_index(k, len(pr.loads), "load")] = _finite(v, (), f"moment of load {k}")
        for k, v in (rigid or {}).items():
            rig[_index(k, len(pr.rigid_clamps), "rigid clamp")] = _finite(
                v, (3,), f"motion (tx, ty, rotation) of rigid clamp {k}")
        found = unreachable(pr, tgt, rig, frc)
        if found:
            raise ValueError(f"{found[0]} {found[1]} {found[2]}")
        return replace(self, targets=tgt, angles=ang, forces=frc, moments=mom, rigid=rig, **mat)

    def vector(self) -> np.ndarray:
        """The NLP's parameter vector (order of :func:`param_layout`)."""
        pl = param_layout(self.problem)
        p = np.zeros(pl.size)
        pl.put(p, "targets", self.targets.T)
        pl.put(p, "angles", self.angles[~np.isnan(self.angles)])
        for name in MATERIAL:
            pl.put(p, name, getattr(self, name))
        pl.put(p, "forces", self.forces.T)
        pl.put(p, "moments", self.moments)
        pl.put(p, "rigid", self.rigid.T)
        return p

    @classmethod
    def from_vector(cls, pr: WeftProblem, p: np.ndarray) -> "WeftParams":
        """The typed form of an NLP parameter vector."""
        pl = param_layout(pr)
        angles = np.full(len(pr.clamps), np.nan)
        angles[[c.angle is not None for c in pr.clamps]] = pl.get(p, "angles").ravel()
        return cls(pr, pl.get(p, "targets").T.copy(), angles,
                   *(float(pl.get(p, name)[0, 0]) for name in MATERIAL),
                   pl.get(p, "forces").T.copy(), pl.get(p, "moments").ravel().copy(),
                   pl.get(p, "rigid").T.copy())
