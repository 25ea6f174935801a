"""Reference copies the tests check the package against (not used by the package).

- :func:`dense_reduction_map`: the reduction of eqs. 22-27 as one dense matrix T,
  vec(coeffs) = T·z, stacked from the course maps the condensed model uses block by block.
- :func:`lifted_reduced_solve`: the reduced model as the *lifted* NLP (the full NLP with its
  coefficients replaced by T·z and its continuity rows, which then hold by construction,
  dropped), solved with CasADi's own derivatives. It was the package's reduced model before the
  condensed one; it is an independent formulation of the same minimum.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from knit_nlp.ipopt import ipopt_options
from knit_nlp.weft.model.basis import n_coeffs
from knit_nlp.weft.model.parametrisation import Full, Reduced
from knit_nlp.weft.model.problem import WeftProblem
from knit_nlp.weft.transcription.factory import transcribe
from knit_nlp.weft.transcription.full import FullNLP
from knit_nlp.weft.transcription.reduction import course_maps, n_reduced


def dense_reduction_map(pr: WeftProblem, reduced: Reduced) -> np.ndarray:
    """T with vec(coeffs) = T·z, coeffs (2t+2 × N) column-major by loop k = (i−1)·n + (j−1)."""
    red = reduced.resolve(pr.courses, pr.wales)
    n, nc = pr.wales, n_coeffs(pr.t)
    T = np.zeros((nc * pr.n_loops, n_reduced(red, pr.t)))
    for i, cm in enumerate(course_maps(pr, red)):
        T[i * n * nc:(i + 1) * n * nc, cm.cols] = cm.T.reshape(n * nc, -1)
    return T


@dataclass
class LiftedSolution:
    success: bool
    objective: float
    coefficients: np.ndarray        # (m, n, 2t+2)
    starts: np.ndarray              # (m, n, 2)
    lam_g: np.ndarray               # multipliers in the full NLP's row layout (continuity: 0)
    full: FullNLP


def lifted_reduced_solve(pr: WeftProblem, reduced: Reduced) -> LiftedSolution:
    """Solve the lifted reduced NLP from the natural state (module docstring)."""
    full = transcribe(pr, Full(), derivatives="casadi")
    T = dense_reduction_map(pr, reduced)
    coeffs = full.x.slice("coeffs")
    z, rest = ca.MX.sym("z", T.shape[1]), ca.MX.sym("y", full.x.size - coeffs.stop)
    x = ca.vertcat(ca.mtimes(ca.DM(T), z), rest)
    fg = ca.Function("fg", [full.nlp["x"], full.nlp["p"]], [full.nlp["f"], full.nlp["g"]])
    f, g = fg(x, full.nlp["p"])
    drop = full.g.slice("continuity") if "continuity" in full.g.blocks else slice(0, 0)
    keep = np.setdiff1d(np.arange(full.g.size), np.arange(full.g.size)[drop])
    solver = ca.nlpsol("lifted", "ipopt", {"x": ca.vertcat(z, rest), "p": full.nlp["p"], "f": f,
                                           "g": g[keep.tolist()]},
                       ipopt_options(pr.solver.tol, pr.solver.max_iter))
    z0, *_ = np.linalg.lstsq(T, full.x0[coeffs], rcond=None)
    sol = solver(x0=np.concatenate([z0, full.x0[coeffs.stop:]]), p=full.p0, lbg=0, ubg=0)
    xs = np.concatenate([T @ np.asarray(sol["x"]).ravel()[:T.shape[1]],
                         np.asarray(sol["x"]).ravel()[T.shape[1]:]])
    lam = np.zeros(full.g.size)
    lam[keep] = np.asarray(sol["lam_g"]).ravel()
    return LiftedSolution(solver.stats()["success"], float(sol["f"]), full.coefficients(xs),
                          full.starts(xs), lam, full)
