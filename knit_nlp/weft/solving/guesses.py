"""Starting points of the weft NLP: perturbations of the natural shape where it is degenerate.

Where the natural yarn is straight, a compressive clamp leaves IPOPT at a point where the end
position does not depend, to first order, on the shape (the Jacobian loses rank); the solve then
starts from a few smooth perturbations and keeps the lowest-energy solution (``solve``).
"""
from __future__ import annotations

import numpy as np

from ..model.basis import n_coeffs, phi
from ..transcription.full import WeftNLP
from ..model.params import WeftParams
from ..model.quadrature import positions


def perturbed_starts(wnlp: WeftNLP, amplitude: float = 0.05) -> list[tuple[str, np.ndarray]]:
    """Smooth low-mode perturbations of the natural shape, as decision vectors.

    Along each course (global arc length S in [0, ℓ], ℓ = n·L) θ gets + ε·f(πS/ℓ) with f one of
    cos, sin and their second harmonics; each loop's share is fitted to the basis by least
    squares and the loop starts are re-chained so the start is consistent.
    """
    pr = wnlp.problem
    m, n, L, t = pr.courses, pr.wales, pr.L, pr.t
    ell = n * L
    s = np.linspace(0.0, L, 8 * n_coeffs(t))
    basis = phi(s, L, t)
    out = []
    for name, f in (("cos1", lambda u: np.cos(u)), ("sin1", lambda u: np.sin(u)),
                    ("cos2", lambda u: np.cos(2 * u)), ("sin2", lambda u: np.sin(2 * u))):
        coeffs = np.broadcast_to(pr.natural.coeffs, (m, n, n_coeffs(t))).copy()
        for j in range(n):
            fit, *_ = np.linalg.lstsq(basis, amplitude * f(np.pi * (j * L + s) / ell), rcond=None)
            coeffs[:, j] += fit
        starts = pr.natural_starts().copy()
        ends = positions(coeffs.reshape(-1, n_coeffs(t)), [L], L, t).reshape(m, n, 2)
        for j in range(1, n):
            starts[:, j] = starts[:, j - 1] + ends[:, j - 1]
        out.append((name, wnlp.lift(coeffs, starts)))
    return out


def needs_perturbation(wnlp: WeftNLP, p: np.ndarray) -> bool:
    """A straight natural yarn with any clamp moved off its natural position (or any load) is
    degenerate at parameters p."""
    if not wnlp.problem.natural.is_straight:
        return False
    return not np.allclose(WeftParams.natural(wnlp.problem).vector(), p)
