"""The designed crossings as persistent sliding contacts (docs/weft3d.md, eqs. S5-S7; after
Cirio, Lopez-Moreno, Miraut and Otaduy, *Yarn-level simulation of woven cloth*, 2014: a contact
between two yarns is kept for good, at material coordinates that are unknowns, so yarns slide
through it).

At a crossing the upper yarn's point p_u = x_u(σ_u) and the lower's p_l = x_l(σ_l), with unit
tangents t_u, t_l there, are the closest points of the two centrelines (S5):

    (p_u − p_l)·t_u = 0,    (p_u − p_l)·t_l = 0.

Their signed separation along the common normal n = t_u × t_l is (S6)

    h = ς (p_u − p_l)·n / |n|,    sin α = |n|,

with ς = ±1 fixed once, from the natural state, so that h = +h₀ > 0 there: the topology (which
side of the lower yarn the upper one wraps) fixes the sign, and h cannot pass through 0 while the energy (S7), the soft-shell
crossing energy ``SoftShell.crossing_energy(h, sin α)`` (eq. C1 of ``compression``), is finite
(it is +∞, NaN in CasADi, at h ≤ 2R_c). No inequality rows and no active set: every crossing is
two equality rows and one energy term, whether its yarns touch (h < 2r) or not (energy 0).

**The natural compression.** A tight fabric's natural wraps are closer than touch (h₀ < 2r:
the knitting pressed the yarn). The law then starts where the natural fabric puts it and keeps
its core: E is evaluated at h′ = 2R_c + a (h − 2R_c), a = Δ/(h₀ − 2R_c) per contact (eq. C3 of
``compression``; ``natural_scales``), as the other contacts' law is (``repulsion``, R1), so that
every natural wrap just touches and carries no force, and no wrap passes the hard core 2R_c at
which the independent check (``proximity``) judges.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from ..compression import SoftShell


def natural_scales(shell: SoftShell, h0: np.ndarray, count: int) -> np.ndarray:
    """a of the module docstring (C3) for ``count`` contacts, the shape's contacts (natural
    separations h0, one per contact of a loop) repeated loop by loop: 1 where a contact is at
    rest beyond touch."""
    return np.tile(shell.thinning(h0), count // max(len(h0), 1))


def crossing_terms(shell: SoftShell) -> ca.Function:
    """Function (p_u, t_u, p_l, t_l, ς, a) -> (E (S7) at h′ (C3), closest-point rows (S5, 2),
    h, sin α)."""
    pu, tu, pl, tl = (ca.SX.sym(n, 3) for n in ("p_u", "t_u", "p_l", "t_l"))
    sign, scale = ca.SX.sym("sign"), ca.SX.sym("scale")
    d = pu - pl
    n = ca.cross(tu, tl)
    sin_a = ca.norm_2(n)
    h = sign * ca.dot(d, n) / sin_a
    energy = shell.casadi_crossing_energy(shell.seen(h, scale), sin_a)
    rows = ca.vertcat(ca.dot(d, tu), ca.dot(d, tl))
    return ca.Function("crossing_terms", [pu, tu, pl, tl, sign, scale],
                       [energy, rows, h, sin_a],
                       ["p_u", "t_u", "p_l", "t_l", "sign", "scale"], ["E", "rows", "h", "sin_angle"])


def separation(pu: np.ndarray, tu: np.ndarray, pl: np.ndarray, tl: np.ndarray,
               sign: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(h, sin α) of (S6) on numbers, points and tangents as (K, 3) arrays."""
    n = np.cross(tu, tl)
    sin_a = np.linalg.norm(n, axis=1)
    return sign * np.einsum("ki,ki->k", pu - pl, n) / sin_a, sin_a


def normal_force(shell: SoftShell, h: np.ndarray, sin_a: np.ndarray, scale: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(the compression h − d₀, the push a·F(h′, α)) of crossings at separation h (S6) with
    scales a (C3): d₀ where the law starts (touch 2r, or the natural separation if closer),
    F of eq. (C2) (``SoftShell.crossing_force``), 0 beyond touch."""
    hc = shell.seen(h, scale)
    with np.errstate(invalid="ignore"):
        force = np.where(hc < 2 * shell.radius, scale * shell.crossing_force(hc, sin_a), 0.0)
    return (hc - 2 * shell.radius) / scale, force


def read_crossings(shell: SoftShell, cp: np.ndarray, signs: np.ndarray, scales: np.ndarray
                   ) -> dict[str, np.ndarray]:
    """Crossings read back from their closest points ``cp`` (12 × K: p_u, t_u, p_l, t_l per
    column): h, sin α (S6), the compression and the push (``normal_force``, C2, C3) and the
    cosine t_u·t_l between the yarns (friction's c̄, F1)."""
    h, sin_a = separation(cp[0:3].T, cp[3:6].T, cp[6:9].T, cp[9:12].T, signs)
    compression, force = normal_force(shell, h, sin_a, scales)
    return {"h": h, "sin_angle": sin_a, "compression": compression, "force": force,
            "cosine": np.einsum("ik,ik->k", cp[3:6], cp[9:12])}
