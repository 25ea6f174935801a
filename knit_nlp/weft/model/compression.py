"""The yarn's transverse compression law: a soft shell around a hard core.

Two yarn pieces whose centrelines are a distance d apart touch when d < 2R (R the yarn's outer
radius) and cannot come closer than 2R_c (R_c the core radius). Between the two, the shell
stores an energy density v per unit length of *each* piece: the contact energy of two yarns is
the double integral ∫∫ v(|x₁(s₁) − x₂(s₂)|) ds₁ ds₂ (stitch-by-stitch, Singal et al. 2024,
``code/fabric_simulations/stockinette.py``, ``contact_energy`` and ``floof``), with

    v(z) = k Δ² / (p (p − 1)) · (z^(1−p) − 1 + (1 − p)(1 − z)),   z = (d − 2R_c) / Δ,  Δ = 2R − 2R_c,

with k the contact rigidity (energy per length⁴: N/mm³ in millimetres and newtons) and p > 1 the
exponent. v(1) = v'(1) = 0 (the shell starts to load smoothly at touch) and v → ∞ as z → 0 (the
core), so an energy minimiser never lets two yarns pass through each other's core. Its
derivative f(d) = −dv/dd = (k Δ / p) · (z^(−p) − 1) is ≥ 0; beyond touch (d ≥ 2R) both are 0.

The source's double loop visits every pair of pieces twice (once from each side), so its
``contact_rigidity`` k_s stores the energy of k = 2 k_s counted once per pair, as here.

**A crossing.** Two straight yarns crossing at angle α whose centrelines pass a distance h apart
(the length of the common normal) store, from the double integral above (the offset
u = s₁t₁ − s₂t₂ sweeps the plane with Jacobian sin α, so ds₁ds₂ = du/sin α, and
|x₁ − x₂|² = h² + |u|²),

    E(h, α) = (2π / sin α) ∫_h^{2R} v(d) d dd                                    (C1)

in closed form (:meth:`SoftShell.crossing_energy`), and press on each other with

    F(h, α) = −∂E/∂h = 2π h v(h) / sin α.                                         (C2)

**A contact pressed at rest** (a tight fabric's natural pairs and wraps, closer than touch at
d₀ < 2R): its law starts at d₀ and keeps the core, the shell thinned to d₀ − 2R_c. The law
sees the distance

    d′ = 2R_c + a (d + c − 2R_c),   a = Δ / (d₀ − 2R_c) ≥ 1                        (C3)

(:meth:`SoftShell.seen`, :meth:`SoftShell.thinning`): d₀ ↦ 2R (touch, no force at rest) and
2R_c ↦ 2R_c (the hard core where the check puts it). c ≥ 0 is a shift for a pair that must start
inside the shell (a pair first found at a distance the law would call the core), a = 1 then.

This module is the one definition of the law: the numpy functions serve results and the
compression fit, the CasADi ones the NLPs.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np


@dataclass(frozen=True)
class SoftShell:
    """Parameters of the law (module docstring), lengths in the problem's unit.

    ``radius`` R (outer: yarns touch at centreline distance 2R), ``core_radius`` R_c < R,
    ``rigidity`` k > 0, ``exponent`` p > 1.
    """

    radius: float
    core_radius: float
    rigidity: float
    exponent: float

    def __post_init__(self) -> None:
        if not 0.0 < self.core_radius < self.radius:
            raise ValueError(f"the core radius must lie in (0, radius = {self.radius:g}); "
                             f"got {self.core_radius:g}")
        if not self.rigidity > 0.0:
            raise ValueError(f"the contact rigidity must be positive; got {self.rigidity:g}")
        if not self.exponent > 1.0:
            raise ValueError(f"the contact exponent must exceed 1; got {self.exponent:g}")

    @property
    def shell(self) -> float:
        """Δ = 2R − 2R_c, the range of centreline distance over which the shell loads."""
        return 2.0 * (self.radius - self.core_radius)

    def thinning(self, start: np.ndarray | float) -> np.ndarray:
        """a of (C3): Δ/(d₀ − 2R_c) for a contact at rest at d₀ = ``start`` closer than touch,
        1 from touch on; d₀ at or inside the core is refused."""
        d0 = np.asarray(start, dtype=float)
        if np.any(d0 <= 2.0 * self.core_radius):
            raise ValueError(f"a contact at rest inside the core 2R_c = {2 * self.core_radius:g}: "
                             f"smallest {float(np.min(d0)):g}")
        return np.maximum(1.0, self.shell / (d0 - 2.0 * self.core_radius))

    def seen(self, d, scale, shift=0.0):
        """d′ of (C3), the distance the law sees (numbers or CasADi expressions)."""
        return 2.0 * self.core_radius + scale * (d + shift - 2.0 * self.core_radius)

    def reduced(self, d: np.ndarray | float) -> np.ndarray:
        """z = (d − 2R_c)/Δ (1 at touch, 0 at the core)."""
        return (np.asarray(d, dtype=float) - 2.0 * self.core_radius) / self.shell

    def energy(self, d: np.ndarray | float) -> np.ndarray:
        """v(d), energy per unit length of contact; 0 beyond touch, +inf at or inside the core."""
        z = np.minimum(self.reduced(d), 1.0)
        p, k, D = self.exponent, self.rigidity, self.shell
        with np.errstate(divide="ignore", invalid="ignore"):
            v = k * D ** 2 / (p * (p - 1)) * (z ** (1 - p) - 1 + (1 - p) * (1 - z))
        return np.where(z > 0, v, np.inf)

    def force(self, d: np.ndarray | float) -> np.ndarray:
        """f(d) = −dv/dd, force per unit length pushing the pieces apart (≥ 0)."""
        z = np.minimum(self.reduced(d), 1.0)
        p, k, D = self.exponent, self.rigidity, self.shell
        with np.errstate(divide="ignore", invalid="ignore"):
            f = k * D / p * (z ** (-p) - 1)
        return np.where(z > 0, f, np.inf)

    def distance_at(self, force: np.ndarray | float) -> np.ndarray:
        """The centreline distance at which the shell carries ``force`` per unit length (f⁻¹)."""
        f = np.asarray(force, dtype=float)
        if np.any(f < 0):
            raise ValueError("a compression force per length must be >= 0")
        z = (1.0 + f * self.exponent / (self.rigidity * self.shell)) ** (-1.0 / self.exponent)
        return 2.0 * self.core_radius + self.shell * z

    def crossing_energy(self, h: np.ndarray | float, sin_angle: np.ndarray | float = 1.0,
                        ) -> np.ndarray:
        """E(h, α) of eq. (C1) in closed form: the energy of two straight yarns crossing at
        angle α (given as sin α) whose centrelines pass h apart; +inf at or inside the core."""
        z0 = np.minimum(self.reduced(h), 1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            e = self._crossing_integral(z0, np) * 2.0 * np.pi / np.asarray(sin_angle, dtype=float)
        return np.where(z0 > 0, e, np.inf)

    def crossing_force(self, h: np.ndarray | float, sin_angle: np.ndarray | float = 1.0,
                       ) -> np.ndarray:
        """F(h, α) = −∂E/∂h = 2π h v(h) / sin α (eq. C2), the push between two crossing yarns."""
        return 2.0 * np.pi * np.asarray(h, dtype=float) * self.energy(h) / np.asarray(sin_angle)

    def casadi_crossing_energy(self, h: ca.SX | ca.MX, sin_angle: ca.SX | ca.MX | float = 1.0,
                               ) -> ca.SX | ca.MX:
        """E(h, α) of eq. (C1) as a CasADi expression (0 beyond touch, NaN inside the core)."""
        z0 = ca.fmin((h - 2.0 * self.core_radius) / self.shell, 1.0)
        return self._crossing_integral(z0, ca) * 2.0 * np.pi / sin_angle

    def _crossing_integral(self, z0, lib):
        """∫_h^{2R} v(d) d dd with d = 2R_c + Δz, from z0 to 1, for numpy or casadi (lib).

        v(z)·d = C (z^(1−p) − 1 + (1−p)(1−z)) (a + b z), C = kΔ²/(p(p−1)), a = 2R_c, b = Δ,
        integrated term by term; ∫_{z0}^1 z^(q−1) dz = (1 − z0^q)/q (−ln z0 when q = 0).
        """
        p, k, D = self.exponent, self.rigidity, self.shell
        a, b = 2.0 * self.core_radius, D
        C = k * D ** 2 / (p * (p - 1))

        def powint(q: float):
            return -lib.log(z0) if abs(q) < 1e-12 else (1 - z0 ** q) / q
        poly = (-p * a * (1 - z0) - (p * b + (1 - p) * a) * (1 - z0 ** 2) / 2
                - (1 - p) * b * (1 - z0 ** 3) / 3)
        return C * D * (a * powint(2 - p) + b * powint(3 - p) + poly)

    def casadi_energy(self, d: ca.SX | ca.MX) -> ca.SX | ca.MX:
        """v(d) as a CasADi expression (0 beyond touch; NaN inside the core, so IPOPT's line
        search cuts back any step that reaches it)."""
        p, k, D = self.exponent, self.rigidity, self.shell
        z = ca.fmin((d - 2.0 * self.core_radius) / D, 1.0)
        return k * D ** 2 / (p * (p - 1)) * (z ** (1 - p) - 1 + (1 - p) * (1 - z))


# The acrylic yarn of stitch-by-stitch (code/fabric_simulations/stockinetteconfig.dat), mm and N:
# yarn_radius 0.74, core_radius 0.325, contact_exponent 2.4, contact_rigidity 0.0006 counted
# twice per pair there (module docstring), so k = 0.0012 N/mm³ here.
ACRYLIC = SoftShell(radius=0.74, core_radius=0.325, rigidity=2 * 0.0006, exponent=2.4)
