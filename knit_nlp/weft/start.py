"""Starting points for the full weft NLP.

The natural configuration violates a moved clamp by the whole pull (182 units on the 100 × 100
diagonal pull) and IPOPT's filter line search then takes 1/128 of its first steps.
``rigid_start`` removes the rigid part of that violation: it turns and moves the natural fabric
by the rigid motion that best fits the clamp targets (2-D Kabsch over the fully clamped
points). Every loop's angle gains the turn (θ → θ + φ, the constant basis coefficient of
eq. 15), loop starts are turned and moved with it, and the lifted spring vectors and points are
recomputed from those (``WeftNLP.lift``), so chaining (eq. 1), continuity (18)-(19) and all
lifted constraints hold exactly; only the clamps (and angle clamps) keep a residual.
"""
from __future__ import annotations

import numpy as np

from .basis import n_coeffs
from .nlp import WeftNLP, rigid_natural_points

STARTS = ("rigid", "natural")


def clamp_pairs(wnlp: WeftNLP, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Natural positions (k × 2) and targets (k × 2) of every point held in both coordinates at
    parameters p: point clamps fixing x and y, and every point of every rigid clamp."""
    pr, pl = wnlp.problem, wnlp.p
    targets, rigid = pl.get(p, "targets"), pl.get(p, "rigid")
    nat, tgt = [], []
    for q, c in enumerate(pr.clamps):
        if all(c.fix):
            nat.append(pr.natural_position(c.loop, c.s))
            tgt.append(targets[:, q])
    for q, (rc, P0) in enumerate(zip(pr.rigid_clamps, rigid_natural_points(pr))):
        tx, ty, rot = rigid[:, q]
        R = _rotation(rot)
        for X in P0:
            nat.append(X)
            tgt.append(rc.centre + R @ (X - rc.centre) + np.array([tx, ty]))
    return np.reshape(nat, (-1, 2)), np.reshape(tgt, (-1, 2))


def best_rigid_motion(nat: np.ndarray, tgt: np.ndarray) -> tuple[float, np.ndarray]:
    """Angle φ and translation b minimising Σ|R(φ)X + b − x|² (2-D Kabsch); φ = 0 for fewer
    than two points, b = 0 for none."""
    if len(nat) == 0:
        return 0.0, np.zeros(2)
    cn, ct = nat.mean(axis=0), tgt.mean(axis=0)
    u, v = nat - cn, tgt - ct
    phi = float(np.arctan2(np.sum(u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]), np.sum(u * v))) \
        if len(nat) > 1 else 0.0
    return phi, ct - _rotation(phi) @ cn


def rigid_start(wnlp: WeftNLP, p: np.ndarray) -> np.ndarray:
    """The natural fabric turned by φ and moved by b, the best rigid fit to the clamp targets."""
    pr = wnlp.problem
    phi, b = best_rigid_motion(*clamp_pairs(wnlp, p))
    coeffs = np.broadcast_to(pr.natural.coeffs, (pr.courses, pr.wales, n_coeffs(pr.t))).copy()
    coeffs[..., -1] += phi
    return wnlp.lift(coeffs, pr.natural_starts() @ _rotation(phi).T + b)


def start_point(wnlp: WeftNLP, p: np.ndarray, start: str) -> np.ndarray:
    """The decision vector a solve starts from: ``natural`` or ``rigid`` (the reduced model
    always starts natural: its map fixes the turn in every loop's parameters)."""
    if start not in STARTS:
        raise ValueError(f"unknown start {start!r}; use one of {', '.join(STARTS)}")
    if start == "natural" or wnlp.coeff_map is not None:
        return wnlp.x0
    return rigid_start(wnlp, p)


def _rotation(phi: float) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    return np.array([[c, -s], [s, c]])
