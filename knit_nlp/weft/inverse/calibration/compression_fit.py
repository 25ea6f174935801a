"""The yarn's soft-shell compression law (``model.compression.SoftShell``) fitted on its
compression tests (stitch-by-stitch ``data/Yarn_compression/compressionTests.xls``, issue 40
item 2; ``scripts/fit_compression.py`` runs it on the shipped acrylic sheets).

**The test's geometry.** A straight yarn segment of length ℓ lies between two flat, rigid,
frictionless plates a gap g apart (the probe and the stage matched to it). A plate is a mirror:
the yarn pressed on it deforms as it would against its own image across the plate, a yarn
parallel to it at centreline distance g (the image of a centreline g/2 from the plate). So each
plate contact holds half the energy of that parallel pair, and the two plates together hold
ℓ·E∥(g), with E∥(d) the energy per unit length of two parallel yarns d apart from the law's
double integral (``model.compression``: ∫∫ v(|x₁ − x₂|) ds₁ ds₂):

    E∥(d) = ∫ v(√(d² + u²)) du over |u| < √(4R² − d²)                          (P1)
    F(g)  = −d(ℓ E∥)/dg = ℓ F∥(g),   F∥(d) = 2d ∫_d^{2R} f(r) / √(r² − d²) dr     (P2)

(f = −dv/dd, ``SoftShell.force``; P2 is P1's derivative, the boundary term vanishing with v at
touch), evaluated with r = d + (2R − d)s², which removes the inverse square root:

    F∥(d) = 4d √(2R − d) ∫₀¹ f(r) / √(r + d) ds                                 (P3)

by Gauss–Legendre quadrature in s (``NODES`` nodes).
The machine records the plates' travel c from an arbitrary start, so g = g₀ − c with the gap at
zero travel g₀ fitted per sample. The plates touch the yarn at g = 2R and would meet the core at
g = 2R_c.

**What is fitted.** Per sample g₀; shared by the samples (a pooled fit) or per sample: the
core radius R_c, the exponent p and k·ℓ — only the product of the rigidity and the contact
length is in the data (the force is linear in both), and ℓ, the probe's width along the yarn, is
not recorded in the source: :meth:`CompressionFit.law` takes it. The outer radius R is held at
half the sample's free diameter (the source's ``Yarn Diameters`` sheet): fitted with the rest it
runs away (to the bound, 10 mm, on every acrylic sample: a long soft shell imitates the data's
slow start), because g₀, R and R_c are three positions the curve pins down only two of (where
the force starts and how it grows). Residuals: log(model force / measured force) on the loading
ramp, from ``min_force`` (above the load cell's noise, ±0.3 mN at rest) to the first frame at
the test's largest force or ``max_force``; all values are fitted in their logarithms (positive,
bounded). Standard errors σ²(JᵀJ)⁻¹ as the calibration's (``fit.uncertainty``); a value at its
bound has none and is reported as a bound.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from ...model.compression import SoftShell
from .fit import uncertainty

NODES = 96                         # Gauss–Legendre nodes of (P2) in s
MIN_FORCE = 0.005                  # N: the fit's lowest force (noise floor ±0.3 mN)
LAW = ("core_radius", "rigidity_length", "exponent")
BOUNDS = {"core_radius": (1e-4, None), "rigidity_length": (1e-10, 1e4), "exponent": (1.0001, 50.0),
          "gap0": (None, 50.0)}    # None: set from the data (the radius, the largest travel)
STARTS = {"core_radius": (0.3,), "exponent": (1.5, 2.5, 4.0), "gap0": (0.1, 0.6)}

_S, _W = np.polynomial.legendre.leggauss(NODES)
_S, _W = (_S + 1.0) / 2.0, _W / 2.0


def plate_force_per_length(law: SoftShell, gap: np.ndarray | float) -> np.ndarray:
    """F∥(g) of (P2): the force per unit length of yarn between two flat plates a gap g apart
    (N/mm in mm and N); 0 at and beyond touch (g ≥ 2R), +inf at or inside the core."""
    d = np.atleast_1d(np.asarray(gap, dtype=float))[:, None]
    span = np.maximum(2.0 * law.radius - d, 0.0)
    r = d + span * _S ** 2                      # dr = 2 span s ds, √(r² − d²) = s √span √(r + d)
    with np.errstate(invalid="ignore"):
        f = 2.0 * d * np.sqrt(span) * 2.0 * law.force(r) / np.sqrt(r + d)
    out = (f * _W).sum(axis=1)
    return np.where(d[:, 0] <= 2.0 * law.core_radius, np.inf, out)


@dataclass(frozen=True)
class Sample:
    """One compression test: the plates' travel (mm) and force (N) on its loading ramp, and the
    yarn's free diameter (mm)."""

    name: str
    travel: np.ndarray
    force: np.ndarray
    free_diameter: float


@dataclass
class CompressionFit:
    """The fitted law: values and standard errors (None: at a bound, or undetermined)."""

    samples: list[str]
    radii: list[float]                           # held: half the free diameters (mm)
    values: dict[str, float]                     # LAW keys and gap0_<sample>
    std_errors: dict[str, float | None]
    at_bound: list[str]
    rms_log: float                               # RMS of log(model / measured force)
    points: int
    residual: np.ndarray = field(repr=False)
    warnings: list[str] = field(default_factory=list)

    def law(self, contact_length: float, sample: int = 0) -> SoftShell:
        """The SoftShell of sample ``sample``'s radius for a contact ``contact_length`` mm long
        (the rigidity is k·ℓ / ℓ)."""
        return SoftShell(self.radii[sample], self.values["core_radius"],
                         self.values["rigidity_length"] / contact_length, self.values["exponent"])

    def model_force(self, sample: int, travel: np.ndarray) -> np.ndarray:
        """ℓ F∥(g₀ − c), N, for sample ``sample`` at travels ``travel`` (ℓ cancels)."""
        law = self.law(1.0, sample)
        return plate_force_per_length(law, self.values[f"gap0_{self.samples[sample]}"] - travel)


def read_sample(path: Path, free_diameter: float, max_force: float | None = None,
                min_force: float = MIN_FORCE) -> Sample:
    """A converted sheet (``time_s,force_mN,compression_mm,...``): the loading ramp from the
    first frame above ``min_force`` to the first frame at the largest force (or ``max_force``),
    forces in N."""
    with open(path, newline="") as fh:
        rows = [r for r in csv.reader(line for line in fh if not line.startswith("#"))]
    head, data = rows[0], np.array([[float(x) for x in r] for r in rows[1:]])
    force = data[:, head.index("force_mN")] / 1000.0
    travel = data[:, head.index("compression_mm")]
    top = int(np.argmax(force >= force.max()))
    keep = np.arange(len(force)) <= top
    keep &= force > min_force
    if max_force is not None:
        keep &= force <= max_force
    return Sample(path.stem, travel[keep], force[keep], free_diameter)


def fit_compression(samples: list[Sample]) -> CompressionFit:
    """The pooled fit (module doc): one law, one g₀ per sample, R held per sample."""
    names = [*LAW, *(f"gap0_{s.name}" for s in samples)]
    radii = [s.free_diameter / 2.0 for s in samples]
    lo = [BOUNDS["core_radius"][0], *BOUNDS["rigidity_length"], BOUNDS["exponent"][0]]
    lower = np.log([lo[0], lo[1], lo[3], *(s.travel.max() + 1e-6 for s in samples)])
    upper = np.log([min(radii) * 0.999, lo[2], BOUNDS["exponent"][1],
                    *(BOUNDS["gap0"][1] for _ in samples)])

    def residual(z: np.ndarray) -> np.ndarray:
        v = np.exp(z)
        parts = []
        for k, s in enumerate(samples):
            law = SoftShell(radii[k], v[0], v[1], v[2])
            with np.errstate(divide="ignore", invalid="ignore"):
                r = np.log(plate_force_per_length(law, v[3 + k] - s.travel)) - np.log(s.force)
            parts.append(np.where(np.isfinite(r), r, 10.0))
        return np.concatenate(parts)

    best = None
    for rc in STARTS["core_radius"]:
        for p in STARTS["exponent"]:
            for dg in STARTS["gap0"]:
                z0 = np.log([rc * min(radii), 0.01, p, *(s.travel.max() + dg for s in samples)])
                z0 = np.clip(z0, lower + 1e-9, upper - 1e-9)
                sol = least_squares(residual, z0, bounds=(lower, upper), method="trf",
                                    x_scale=1.0, xtol=1e-12, ftol=1e-12, gtol=1e-12)
                if best is None or sol.cost < best.cost:
                    best = sol
    return _outcome(names, radii, samples, best, lower, upper, residual)


def _outcome(names, radii, samples, sol, lower, upper, residual) -> CompressionFit:
    values = np.exp(sol.x)
    r = residual(sol.x)
    at_bound = [n for n, z, a, b in zip(names, sol.x, lower, upper) if min(z - a, b - z) < 1e-4]
    free = [q for q, n in enumerate(names) if n not in at_bound]
    std: dict[str, float | None] = {n: None for n in names}
    warnings = [f"{n} at its bound ({values[q]:.4g}): the data set only a bound on it"
                for q, n in enumerate(names) if n in at_bound]
    if free:
        se, _, more = uncertainty([names[q] for q in free], values[free], r, sol.jac[:, free])
        for q, s in zip(free, se):
            std[names[q]] = s
        warnings += more
    return CompressionFit([s.name for s in samples], radii, dict(zip(names, map(float, values))),
                          std, at_bound, float(np.sqrt(np.mean(r ** 2))), len(r), r, warnings)
