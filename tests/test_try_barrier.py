"""The barrier energy of scripts/try_barrier_contact.py (docs/contact.md, "Tried and not
kept": IPC's barrier in IPOPT's objective): its closed-form gradient and the Hessian of
the normal gap against central differences, so the measured iteration counts are those of
correct derivatives."""
from __future__ import annotations

import importlib.util
from pathlib import Path

SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "try_barrier_contact.py"


def test_barrier_derivatives_match_finite_differences():
    spec = importlib.util.spec_from_file_location("_try_barrier_contact", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    grad_err, hess_err = module.check(n=3)
    assert grad_err < 1e-6
    assert hess_err < 1e-6
