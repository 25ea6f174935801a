"""The yarn's compression law fitted on plate tests (issue 40 item 2,
``calibration/compression_fit.py``): the plate force is the derivative of the parallel-yarn
energy (P1, P2), and the fit gives back a law it did not make itself (the data from SciPy's
adaptive quadrature, with noise) within its standard errors."""
from __future__ import annotations

import hashlib
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from knit_nlp.weft.inverse.calibration.compression_fit import (Sample, fit_compression,
                                                                plate_force_per_length)
from knit_nlp.weft.model.compression import SoftShell

LAW = SoftShell(radius=1.2, core_radius=0.35, rigidity=0.02, exponent=2.4)   # ℓ = 1 mm


def _energy_per_length(law: SoftShell, d: float) -> float:
    """E∥(d) of (P1): ∫ v(√(d² + u²)) du over |u| < √(4R² − d²), SciPy's quad."""
    top = np.sqrt(4 * law.radius ** 2 - d ** 2)
    return 2 * quad(lambda u: float(law.energy(np.hypot(d, u))), 0.0, top, limit=200,
                    epsabs=0, epsrel=1e-12)[0]


def _force_quad(law: SoftShell, g: float) -> float:
    """(P2) in its first form, 2g ∫_g^{2R} f(r)/√(r² − g²) dr, by SciPy's quad (weight
    'alg' takes the inverse square root at r = g exactly)."""
    return 2 * g * quad(lambda r: float(law.force(r)) / np.sqrt(r + g), g, 2 * law.radius,
                        weight="alg", wvar=(-0.5, 0.0), limit=200)[0]


@pytest.mark.parametrize("gap", [2.3, 1.6, 1.0, 0.8])
def test_the_plate_force_is_the_derivative_of_the_parallel_yarns_energy(gap):
    """F∥ = −dE∥/dd: the quadrature of (P3) against central differences of (P1)."""
    h = 1e-5
    fd = -(_energy_per_length(LAW, gap + h) - _energy_per_length(LAW, gap - h)) / (2 * h)
    assert plate_force_per_length(LAW, gap)[0] == pytest.approx(fd, rel=1e-6)
    assert plate_force_per_length(LAW, 2 * LAW.radius + 0.1)[0] == 0.0


def test_the_fit_gives_back_a_law_made_by_another_quadrature_within_its_errors():
    """80 travels from just past touch to near the core (g0 = 3.5 mm, so the gap runs from
    2.35 to 0.8 mm), forces from SciPy's quad with 3 % log-normal noise: R_c, k·ℓ, p and g0
    back within 3 standard errors, each known to better than 10 %."""
    g0 = 3.5
    travel = np.linspace(g0 - 2.35, g0 - 0.8, 80)
    rng = np.random.default_rng(3)
    force = np.array([_force_quad(LAW, g0 - c) for c in travel]) * np.exp(rng.normal(0, 0.03, 80))
    fit = fit_compression([Sample("synthetic", travel, force, 2 * LAW.radius)])
    truth = {"core_radius": LAW.core_radius, "rigidity_length": LAW.rigidity,
             "exponent": LAW.exponent, "gap0_synthetic": g0}
    assert not fit.at_bound and fit.rms_log == pytest.approx(0.03, rel=0.3)
    for name, value in truth.items():
        se = fit.std_errors[name]
        assert se is not None and se < 0.1 * value, (name, se)
        assert abs(fit.values[name] - value) < 3 * se, (name, fit.values[name], value, se)


def test_the_shipped_compression_data_are_the_published_bytes_with_their_licence():
    folder = Path(__file__).resolve().parent.parent / "problems" / "real_fabric" / "yarn_compression"
    recorded = dict(re.findall(r"\| `([^`]+)` \| `([0-9a-f]{64})` \|",
                               (folder / "SOURCE.md").read_text()))
    assert set(recorded) == {"acrylic_1.csv", "acrylic_2.csv", "acrylic_3.csv",
                             "yarn_diameters.csv", "LICENSE"}
    for name, digest in recorded.items():
        assert hashlib.sha256((folder / name).read_bytes()).hexdigest() == digest, name
