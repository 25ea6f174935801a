"""Which gap rows of a contact solve hold a contact (the result's active contacts, the rounds'
held and settling contacts, the equality rows of the control's KKT system)."""
from __future__ import annotations

import numpy as np

ACTIVE = 1e-6      # a contact pushes when −λ exceeds this fraction of the largest (or tol)


def active_gaps(gap: np.ndarray, required: np.ndarray, lam_gap: np.ndarray, used: np.ndarray,
                tol: float, scale: float) -> np.ndarray:
    """Gap rows that hold their contact: used, pushing (force −λ above ACTIVE of the largest
    and 10 tol), and nearer their bound than they push: (gap − required) / scale below
    force / largest. ``gap`` is the rows' own value (the signed normal gap of the slot's
    points), ``scale`` a length (2r). At IPOPT's solution every gap row has force × slack ≈ μ,
    the last barrier parameter, so rows off their bound keep a small force; the test
    λ_i > s_i (here with force and slack each relative to its scale) is the usual
    identification of the active set at an interior-point solution. Measured: on the squeezed
    loop (tests/test_contact_control.py) rows 1.8e-3 off their bound with forces 2.6e-6 of the
    largest, taken as active, made the control's K singular (cond 2e18, dx/dp off by 200 %);
    on the shipped diagonal pull, forces of 3e-7 on rows up to 1e-2 off their bound were half
    of the 92 contacts that the force alone counted; along the straight rods' line contact rows
    1e-4 off their bound carry 2 % of the push (tests/test_contact.py)."""
    force = np.where(used, -lam_gap, 0.0)
    largest = float(force.max(initial=0.0))
    if largest <= 0:
        return np.zeros(len(force), dtype=bool)
    slack = np.maximum(gap - required, 0.0) / scale
    return used & (force > max(ACTIVE * largest, 10 * tol)) & (force / largest > slack)
