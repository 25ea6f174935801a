"""The natural 3-D loop (docs/weft3d.md, "Natural 3-D shape").

Every loop has the same unloaded shape (θ₀, φ₀). It is found once per (loop, q, r) by a small
NLP (IPOPT): the projection stays as near as it can to the paper's natural loop (least squares
over the loop), the loop closes on the planar fabric's lattice (x(L) − x(0) = w, y(L) = y(0),
z(L) = z(0), so every course lies flat and loops repeat), and at every designed crossing of
plain knit (``crossings``: A/D, C/F, Q/G, S/P) the two yarns pass one over the other in the
plain-knit order and touch: their closest points are 2r apart (centreline distance 2r, zero
contact force in the natural state).

**The order.** A stitch is drawn through the loop below from the back to the front (+z is the
technical face). Its legs therefore lie in front of the head of the loop below (C/F and Q/G:
upper over), and its foot, the sinker loop, lies behind the legs of the loop below (A/D and S/P:
upper under). Legs in front, heads and sinker loops behind: the face shows the V's, the back the
purl bumps.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..basis import continuity_rows, dphi, n_coeffs, phi
from ..crossing_points import Crossings
from ..natural_loop import NaturalLoop
from .curve3d import positions3d, segment

# (upper label, lower label, order): +1 where the upper course's yarn is in front (+z)
PAIRS = (("A", "D", -1), ("C", "F", +1), ("Q", "G", +1), ("S", "P", -1))
SAMPLES = 41               # projection least-squares samples along the loop
GAUSS = 48                 # nodes of the Gauss rule on [0, σ] in the natural solve
SMOOTH = 1e-3              # weight of ∫φ′² ds against the projection's mean squared distance


class NaturalShapeError(ValueError):
    """No natural 3-D loop with touching crossings was found for these values."""


@dataclass(frozen=True)
class Natural3D:
    """The natural 3-D loop: θ coefficients ``coeffs`` (2t+2), elevation coefficients
    ``elevation`` (2q+2), the crossings' material coordinates on the upper and lower loop
    (``s_upper``, ``s_lower``, 4 each, in :data:`PAIRS` order), each one's ``order`` (+1: upper
    over) and the lattice (w, c) of the planar natural fabric; ``projection_rms``: the RMS
    distance of the projection from the paper's loop."""

    length: float
    harmonics: int
    modes: int
    radius: float
    coeffs: np.ndarray
    elevation: np.ndarray
    s_upper: np.ndarray
    s_lower: np.ndarray
    order: np.ndarray
    wale_spacing: float
    course_spacing: float
    projection_rms: float

    def xyz(self, s: np.ndarray | list[float]) -> np.ndarray:
        """Positions (len(s), 3) along the natural loop from its start."""
        return positions3d(self.coeffs, self.elevation, s, self.length, self.harmonics,
                           self.modes)

    def starts(self, m: int, n: int) -> np.ndarray:
        """Natural loop starts (m, n, 3): the planar lattice at z = 0."""
        i, j = np.meshgrid(np.arange(m), np.arange(n), indexing="ij")
        return np.stack([j * self.wale_spacing, i * self.course_spacing, 0.0 * i], axis=-1)

    def separations(self) -> np.ndarray:
        """Centreline distance at each crossing's closest points (the check: 2r)."""
        up = self.xyz(self.s_upper) + [0.0, self.course_spacing, 0.0]
        return np.linalg.norm(up - self.xyz(self.s_lower), axis=1)


def flat(natural: NaturalLoop, modes: int, radius: float) -> Natural3D:
    """The planar natural loop with φ₀ = 0, for fabrics without crossings (one course)."""
    return Natural3D(natural.length, natural.harmonics, modes, radius, natural.coeffs.copy(),
                     np.zeros(n_coeffs(modes)), np.zeros(0), np.zeros(0), np.zeros(0),
                     natural.wale_spacing, natural.course_spacing, 0.0)


def natural_3d(natural: NaturalLoop, crossings: Crossings, modes: int, radius: float) -> Natural3D:
    """The natural 3-D loop of a planar natural loop and its crossings (module docstring),
    memoised per (loop, q, r)."""
    return _solve(natural.coeffs.tobytes(), natural.length, natural.harmonics,
                  natural.wale_spacing, natural.course_spacing, modes, float(radius),
                  tuple(float(crossings.s[u]) for u, _, _ in PAIRS),
                  tuple(float(crossings.s[lo]) for _, lo, _ in PAIRS))


@functools.lru_cache(maxsize=32)
def _solve(coeffs: bytes, L: float, t: int, w: float, c: float, q: int, r: float,
           su0: tuple[float, ...], sl0: tuple[float, ...]) -> Natural3D:
    a_plan = np.frombuffer(coeffs).copy()
    nc, nq = n_coeffs(t), n_coeffs(q)
    a, b = ca.SX.sym("a", nc), ca.SX.sym("b", nq)
    su, sl = ca.SX.sym("su", 4), ca.SX.sym("sl", 4)
    seg = segment(L, t, q, GAUSS)

    def point(s):
        d, tan = seg(a, b, 0.0, s)
        return d, tan
    s = np.linspace(0.0, L, SAMPLES)
    target = positions3d(a_plan, np.zeros(nq), s, L, t, q)[:, :2]
    misfit = 0
    for k in range(1, SAMPLES):
        misfit += ca.sumsqr(point(s[k])[0][:2] - ca.DM(target[k]))
    rows, lo, hi = [], [], []
    end = point(L)[0]
    rows += [end[0] - w, end[1], end[2]]
    lo += [0.0] * 3
    hi += [0.0] * 3
    shift = ca.DM([0.0, c, 0.0])
    for k, (_, _, order) in enumerate(PAIRS):
        pu, tu = point(su[k])
        pl, tl = point(sl[k])
        d = pu + shift - pl
        rows += [ca.dot(d, tu), ca.dot(d, tl), ca.dot(d, d) - 4 * r * r, order * d[2]]
        lo += [0.0, 0.0, 0.0, 0.0]
        hi += [0.0, 0.0, 0.0, ca.inf]
    E, S = continuity_rows(L, q)
    rows += list(ca.vertsplit(ca.mtimes(ca.DM(E - S), b)))   # φ, φ′ periodic: loops join
    Et, St = continuity_rows(L, t)
    rows += list(ca.vertsplit(ca.mtimes(ca.DM(Et - St), a)))
    lo += [0.0] * 4
    hi += [0.0] * 4
    nodes = np.linspace(0.0, L, 200)
    smooth = ca.sumsqr(ca.mtimes(ca.DM(dphi(nodes, L, q)), b)) * (L / nodes.size)
    f = misfit / (SAMPLES - 1) + SMOOTH * L * smooth
    x = ca.vertcat(a, b, su, sl)
    solver = ca.nlpsol("natural3d", "ipopt", {"x": x, "f": f, "g": ca.vertcat(*rows)},
                       {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-12,
                                                       "max_iter": 500}})
    b0 = np.zeros(nq)
    if q >= 2:       # legs in front, head and foot behind: z ≈ −α cos(4πs/L)
        b0[1] = 4 * np.pi * (2 * r / 1.77) / L
    big = np.full(nc + nq, np.inf)
    sol = solver(x0=np.concatenate([a_plan, b0, su0, sl0]), lbg=lo, ubg=hi,
                 lbx=np.concatenate([-big, np.zeros(8)]), ubx=np.concatenate([big, np.full(8, L)]))
    xs = np.asarray(sol["x"]).ravel()
    if not solver.stats()["success"]:
        raise NaturalShapeError(f"no natural 3-D loop with touching crossings for radius {r:g} "
                                f"and {q} elevation modes (IPOPT: {solver.stats()['return_status']})")
    a3, b3 = xs[:nc], xs[nc:nc + nq]
    proj = positions3d(a3, b3, s, L, t, q)[:, :2]
    rms = float(np.sqrt(np.mean(np.sum((proj - target) ** 2, axis=1))))
    return Natural3D(L, t, q, r, a3, b3, xs[nc + nq:nc + nq + 4], xs[nc + nq + 4:],
                     np.array([o for _, _, o in PAIRS], dtype=float), w, c, rms)
