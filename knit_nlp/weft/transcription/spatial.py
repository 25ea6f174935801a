"""The 3-D weft NLP (docs/weft3d.md): minimise U_bend (S4) + U_crossings (S7) [+ U_spring,
eqs. 6-10, when asked] − W_loads subject to the chaining of eq. (1) in space (S2), continuity
(18)-(19) of θ and of the elevation φ, the closest-point rows of every interlock contact (S5)
and the clamps (x, y as the planar model; z held at its natural value at every held point).

Decision variables, by block (``Layout``):
- ``coeffs`` (2t+2 × N) and ``elev`` (2q+2 × N): every loop's θ and φ coefficients;
- ``starts`` (3 × N): every loop's start point;
- ``SL``, ``SR`` (2 × loops of courses 2..m): the paper's spring vectors, only with springs;
- ``sigma`` (2 × K): each crossing's material coordinate on its upper and lower loop
  (K = 4 crossings or 2 wraps, ``Natural3D.labels``, per loop of courses 2..m) and ``cp`` (12 × K): the lifted closest points
  and tangents (p_u, t_u, p_l, t_l) there, each tied to one loop's coefficients by (S3);
- ``PC`` (3 × specials): the clamped and loaded points.
With ``[yarn] friction`` μ > 0 the energy gains the lagged friction potential Σ_c D_c
(``model/spatial/friction.py``, F1-F3) of the σ block, and the NLP's parameter vector a lagged
block (4 × K: N̄, σ̄_u, σ̄_l, c̄ per crossing) after the ``WeftParams`` ones: the load path's
state (``FrictionPath``), set by the solver (``WeftSolver.parameters``), never interpolated.
The other contacts' sample points (``rp``, 3 × N·S) are built as a lifted block at the end of
a longer vector and condensed away (``elements.condensed_derivatives``): in the NLP they are
functions of their loops (S2), not variables, and their repulsion's Hessian is a block per
pair of neighbouring loops.
Every nonlinear function of the coefficients belongs to one loop (its integrals to the panel
points, its bending, its crossing segments), as in ``full``: the Lagrangian Hessian is block
diagonal in the loops (with their σ's) plus 12 × 12 blocks per crossing. The sparsity is fixed
by the fabric's topology: no inequality rows, no active set.

Derivatives (``Spatial.derivatives``, default ``"elements"``): every nonlinear term is a mapped
SX Function called through ``_Builder.elements`` (``elements.Elements.call``), whose Jacobian
and Lagrangian Hessian are assembled element by element (``elements.element_derivatives``; the
loops' in closed form, ``loop_hessians``). A new energy term: call its per-instance Function
through ``self.elements.call(name, fn, count, *inputs)`` (inputs: selections of the decision
variables, constants, parameters) and add its output to the energy; a term written directly in
the variables is still right (CasADi's AD of the part outside the elements), only slower.

``Spatial(elevation=False, contacts=False, springs=True)`` is the paper's limit (φ frozen at 0,
each course's start held at z = 0): the planar full model's NLP in other variables (tested).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from ...errors import ProblemError
from ...layout import Layout
from ..model.basis import continuity_rows, n_coeffs, phi
from ..model.compression import ACRYLIC
from ..model.energy import spring_pair_energy
from ..model.parametrisation import Full
from ..model.params import WeftParams, param_layout
from ..model.problem import WeftProblem
from ..model.spatial.crossing_contact import crossing_terms, natural_scales, read_crossings
from ..model.spatial.friction import (EPSILON, LAGGED_ROWS, Friction, FrictionPath, Lagged,
                                      friction_potential)
from ..model.spatial.curve3d import bending3d, loop_displacements3d, positions3d, segment
from ..model.spatial.natural3d import Natural3D, flat
from ..model.spatial.repulsion import Neighbours, natural_neighbours, repulsion_energy, sample_s
from ..model.centrelines import SAMPLES
from .elements import Elements, condensed_derivatives, element_derivatives
from .full import Constraints, clamp_constraints
from .loop_hessians import bending_hessian, displacement_hessian, displacement_jacobian
from .protocol import Assembled
from .rows import SPRINGS, ClampRows, ClampTable, loop_index, special_points

class PlanarOnly(ProblemError, ValueError):
    """A model or option that exists only in the plane (one line; exit 2 on the command line)."""


REDUCED_IS_PLANAR = "the reduced model is planar; solve the 3-D model in full"


def planar_only(problem: WeftProblem, what: str, why: str = REDUCED_IS_PLANAR) -> PlanarOnly:
    """The refusal of ``what`` (the reduced model, ``compare``, the inverse problems, ``check``)
    for a 3-D problem, with the reason ``why``."""
    return PlanarOnly(problem.source, "yarn", "geometry", f"{what}: {why}, or remove "
                      'geometry = "3d"')


SEGMENT_NODES = 8          # Gauss nodes on [s0, σ] (S3)
LIFTED = ("SL", "SR", "cp", "PC", "rp")


@dataclass(frozen=True)
class Spatial:
    """Switches of the 3-D builder: ``elevation`` (False: φ frozen at 0), ``contacts`` (the
    crossings' persistent contacts), ``springs`` (the paper's k_a, k_b; None: the file's
    ``[yarn] crossing_springs``), ``derivatives``: ``"elements"`` (assembled element by
    element, ``elements.element_derivatives``) or ``"casadi"`` (CasADi's AD of the whole NLP,
    for comparisons)."""

    elevation: bool = True
    contacts: bool = True
    springs: bool | None = None
    repulsion: bool = True        # the other contacts (repulsion.py), with the contacts
    derivatives: str = "elements"


@dataclass
class SpatialNLP(Assembled):
    """The 3-D NLP (module docstring), with the members of the ``WeftNLP`` protocol."""

    options: Spatial
    shape: Natural3D
    z_rows: dict[int, int]                 # special point -> its z row (held points)
    terms: ca.Function                     # (x, p) -> spring, contact, bend, work, h, sin α
    lifted: ca.Function                    # primary blocks -> lifted blocks
    signs: np.ndarray
    x0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    # CasADi's AD (expanding the graph to scalars cost 16-53 s of set-up on 6 x 6 for the same
    # time per iteration); a trial step into a yarn's core evaluates to NaN, which IPOPT's line
    # search cuts back (expected: not a warning for the user)
    nlpsol_options: dict[str, Any] = field(default_factory=lambda: {
        "show_eval_warnings": False})
    parametrisation: Full = Full()
    model: str = "full3d"
    neighbours: Neighbours | None = None   # the other contacts' list (repulsion.py)
    friction: Friction | None = None       # lagged friction at the crossings (friction.py)
    rounds: list[dict[str, Any]] = field(default_factory=list)   # rounds3d's, per round

    # -- the protocol ----------------------------------------------------------------
    def energy(self, x: np.ndarray, p: np.ndarray) -> tuple[float, float, float]:
        """(U_spring + U_crossings, U_bend, W_loads): in 3-D the crossings' contact energy
        (S7) is reported with the springs, the fabric's interlock energy."""
        spring, contact, bend, work = (float(v) for v in self.terms(x, p)[:4])
        return spring + contact, bend, work

    def coefficients(self, x: np.ndarray) -> np.ndarray:
        pr = self.problem
        return self.x.get(x, "coeffs").T.reshape(pr.courses, pr.wales, n_coeffs(pr.t))

    def elevations(self, x: np.ndarray) -> np.ndarray:
        """Every loop's elevation coefficients (m, n, 2q+2) (zeros when φ is frozen)."""
        pr, nq = self.problem, n_coeffs(self.shape.modes)
        if "elev" not in self.x.blocks:
            return np.zeros((pr.courses, pr.wales, nq))
        return self.x.get(x, "elev").T.reshape(pr.courses, pr.wales, nq)

    def starts(self, x: np.ndarray) -> np.ndarray:
        return self.starts3d(x)[..., :2]

    def starts3d(self, x: np.ndarray) -> np.ndarray:
        """Every loop's start point (m, n, 3)."""
        pr = self.problem
        return self.x.get(x, "starts").T.reshape(pr.courses, pr.wales, 3)

    def special_positions(self, x: np.ndarray) -> np.ndarray:
        return self.x.get(x, "PC")[:2] if self.clamp_table.specials else np.zeros((2, 0))

    def lift(self, coeffs: np.ndarray, starts: np.ndarray) -> np.ndarray:
        """Loops with planar coefficients and starts (2-D: z = 0), the natural elevation and
        the natural crossing coordinates; every lifted block computed from them."""
        pr = self.problem
        if starts.shape[-1] == 2:
            starts = np.concatenate([starts, np.zeros(starts.shape[:-1] + (1,))], axis=-1)
        elev = np.broadcast_to(self.shape.elevation, (pr.courses, pr.wales, n_coeffs(self.shape.modes)))
        return self.lift3d(coeffs, elev, starts)

    def lift3d(self, coeffs: np.ndarray, elev: np.ndarray, starts: np.ndarray,
               sigma: np.ndarray | None = None) -> np.ndarray:
        """The decision vector of loops (m, n, ·) with coefficients, elevations and 3-D starts
        and crossing coordinates ``sigma`` (2 × K; None: natural)."""
        pr, N = self.problem, self.problem.n_loops
        xv = np.zeros(self.x.size)
        self.x.put(xv, "coeffs", coeffs.reshape(N, -1).T)
        if "elev" in self.x.blocks:
            self.x.put(xv, "elev", elev.reshape(N, -1).T)
        self.x.put(xv, "starts", starts.reshape(N, 3).T)
        if "sigma" in self.x.blocks:
            if sigma is None:
                per = self.shape.s_upper.size
                K = self.x.blocks["sigma"][2][1]
                sigma = np.vstack([np.tile(self.shape.s_upper, K // per),
                                   np.tile(self.shape.s_lower, K // per)])
            self.x.put(xv, "sigma", sigma)
        for name, value in zip(self._lifted_names(), self.lifted.call([xv])):
            self.x.put(xv, name, np.asarray(value))
        return xv

    def representatives(self) -> None:
        return None

    def centrelines(self, x: np.ndarray, samples: int = SAMPLES) -> np.ndarray:
        """The deformed centrelines' projection (m, n, samples, 2) (planar readers)."""
        return self.centrelines3d(x, samples)[..., :2]

    # -- 3-D readers -----------------------------------------------------------------
    def centrelines3d(self, x: np.ndarray, samples: int = SAMPLES) -> np.ndarray:
        """Sampled deformed centrelines (m, n, samples, 3) (S2)."""
        return self._curves(self.coefficients(x), self.elevations(x), self.starts3d(x), samples)

    def natural_centrelines3d(self, samples: int = SAMPLES) -> np.ndarray:
        """Sampled natural 3-D centrelines (m, n, samples, 3)."""
        pr, sh = self.problem, self.shape
        nq = n_coeffs(sh.modes)
        return self._curves(np.broadcast_to(sh.coeffs, (pr.courses, pr.wales, n_coeffs(pr.t))),
                            np.broadcast_to(sh.elevation if self.options.elevation else
                                            np.zeros(nq), (pr.courses, pr.wales, nq)),
                            sh.starts(pr.courses, pr.wales), samples)

    def _curves(self, A: np.ndarray, B: np.ndarray, X: np.ndarray, samples: int) -> np.ndarray:
        pr, sh = self.problem, self.shape
        s = np.linspace(0.0, pr.L, samples)
        d = positions3d(A.reshape(pr.n_loops, -1), B.reshape(pr.n_loops, -1), s, pr.L, pr.t,
                        sh.modes)
        return d.reshape(pr.courses, pr.wales, samples, 3) + X[:, :, None, :]

    def sigmas(self, x: np.ndarray) -> np.ndarray | None:
        """Each crossing's material coordinates at x (2 × K: σ_u, σ_l, S5), None where the NLP
        has no crossings."""
        return self.x.get(x, "sigma") if "sigma" in self.x.blocks else None

    def crossing_state(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Per crossing (K): σ_u, σ_l, h, sin α, the compression h − d₀ (d₀ where its law starts:
        touch 2r, or its natural separation h₀ if that is closer; eq. C3), the contact force
        a·F(h′, α) of eqs. (C2, C3) (``SoftShell.crossing_force``) and the cosine between the
        yarns (``crossing_contact.read_crossings``)."""
        if "cp" not in self.x.blocks:
            return {}
        cp, sig = self.x.get(x, "cp"), self.x.get(x, "sigma")
        shell = self.problem.yarn.shell()
        a = natural_scales(shell, self.shape.h0, cp.shape[1])
        return {"sigma_upper": sig[0], "sigma_lower": sig[1],
                **read_crossings(shell, cp, self.signs, a)}

    # -- lagged friction (model/spatial/friction.py) --------------------------------------
    def lagged_at(self, x: np.ndarray) -> Lagged:
        """The lagged values a load step takes from the accepted state x (F1, F3): each
        crossing's normal force, material coordinates and the cosine between its tangents."""
        state = self.crossing_state(x)
        return Lagged(np.abs(state["force"]), np.array(state["sigma_upper"]),
                      np.array(state["sigma_lower"]), state["cosine"])

    def step_dissipation(self, x: np.ndarray, lagged: Lagged) -> float:
        """μ Σ N̄|Δ| (F4) of the step that reached x with these lagged values."""
        sig = self.x.get(x, "sigma")
        return self.friction.dissipation(lagged, sig[0], sig[1])

    def _friction_rows(self, x: np.ndarray, path: FrictionPath | None
                       ) -> tuple[dict[str, Any] | None, np.ndarray, np.ndarray]:
        """The ``spatial`` block's ``friction`` summary (μ, ε, the load steps of the path from
        the natural state, its dissipation F4: the steps before the last plus the last one's
        at x) and per crossing the friction force μN̄ and the slide |Δ| of the last step;
        (None, empty, empty) without friction or without the path that reached x."""
        if self.friction is None or path is None:
            return None, np.zeros(0), np.zeros(0)
        sig = self.x.get(x, "sigma")
        lag, fr = path.lagged, self.friction
        summary = {"mu": fr.mu, "epsilon": fr.eps, "load_steps": path.steps,
                   "dissipation": path.earlier + self.step_dissipation(x, lag)}
        return summary, fr.mu * lag.normal, lag.slides(sig[0], sig[1])

    def contact_points(self, x: np.ndarray) -> np.ndarray:
        """Per crossing, the midpoint of its two closest points (K, 3): where the yarns touch."""
        if "cp" not in self.x.blocks:
            return np.zeros((0, 3))
        cp = self.x.get(x, "cp")
        return 0.5 * (cp[0:3].T + cp[6:9].T)          # rows: x_u, t_u, x_l, t_l

    def spatial_block(self, x: np.ndarray, p: np.ndarray,
                      path: FrictionPath | None = None) -> dict[str, Any]:
        """The result JSON's ``spatial`` block (docs/weft3d.md, "Results"); with friction and
        the load path that reached x (``path``), its ``friction`` summary and each crossing's
        ``friction_force`` and ``slide`` (``_friction_rows``)."""
        spring, contact = (float(v) for v in self.terms(x, p)[:2])
        state = self.crossing_state(x)
        out: dict[str, Any] = {"geometry": "3d", "elevation_modes": self.shape.modes,
                               "contact_energy": contact, "spring_energy": spring,
                               "natural_projection_rms": self.shape.projection_rms}
        if not state:
            return {**out, "crossings": [], "smallest_separation": None, "flipped": 0}
        n = self.problem.wales
        summary, force, slide = self._friction_rows(x, path)
        if summary is not None:
            out["friction"] = summary
        rows = []
        for c, h in enumerate(state["h"]):
            k, kind = divmod(c, self.shape.s_upper.size)
            i, j = divmod(k + n, n)
            rows.append({"upper": [i + 1, j + 1], "lower": [i, j + 1],
                         "pair": self.shape.labels[kind],
                         "natural_separation": float(self.shape.h0[kind]),
                         "s_upper": float(state["sigma_upper"][c]),
                         "s_lower": float(state["sigma_lower"][c]),
                         "separation": float(h), "compression": float(state["compression"][c]),
                         "force": float(state["force"][c]),
                         "sin_angle": float(state["sin_angle"][c]),
                         **({"friction_force": float(force[c]), "slide": float(slide[c])}
                            if summary is not None else {})})
        sig = np.concatenate([state["sigma_upper"], state["sigma_lower"]])
        return {**out, "crossings": rows, "smallest_separation": float(np.min(state["h"])),
                "flipped": int(np.sum(state["h"] <= 0)),
                "slid_off_loop": int(np.sum((sig < 0) | (sig > self.problem.L)))}

    def sample_points(self, x: np.ndarray, samples: int) -> np.ndarray:
        """Every loop's repulsion samples (N, S, 3) at x (``repulsion.sample_s``, S2)."""
        pr = self.problem
        d = positions3d(self.coefficients(x).reshape(pr.n_loops, -1),
                        self.elevations(x).reshape(pr.n_loops, -1), sample_s(pr.L, samples),
                        pr.L, pr.t, self.shape.modes)
        return d + self.starts3d(x).reshape(pr.n_loops, 1, 3)

    def _lifted_names(self) -> list[str]:
        return [name for name in LIFTED if name in self.x.blocks]


def build_spatial(pr: WeftProblem, options: Spatial = Spatial(),
                  extra: Neighbours | None = None) -> SpatialNLP:
    """Assemble the 3-D NLP of a problem (module docstring); ``extra``: pairs of the other
    contacts added to the natural neighbour list (the solve's rounds)."""
    yarn = pr.yarn
    springs = options.springs if options.springs is not None else bool(
        yarn is not None and yarn.crossing_springs)
    springs = springs and pr.courses > 1 and pr.crossings is not None
    modes = yarn.elevation_modes if yarn is not None and yarn.spatial else 2
    if options.elevation:
        if yarn is None or not yarn.spatial:
            raise ValueError('the 3-D model with elevation needs [yarn] geometry = "3d"')
        shape = yarn.natural3d
    else:
        shape = flat(pr.natural, modes, yarn.radius if yarn is not None else 0.0)
    contacts = options.contacts and pr.courses > 1 and shape.s_upper.size > 0
    if options.contacts and contacts and not options.elevation:
        raise ValueError("crossing contacts need the elevation (a planar fabric's crossings "
                         "have h = 0)")
    if options.derivatives not in ("elements", "casadi"):
        raise ValueError(f"derivatives must be 'elements' or 'casadi'; got {options.derivatives!r}")
    pairs = None
    if contacts and options.repulsion:
        pairs = natural_neighbours(shape, pr.yarn.shell(), pr.courses, pr.wales,
                                   None if extra is None else extra.samples)
        pairs = pairs if extra is None else pairs.plus(extra)
    out = _Builder(pr, Spatial(options.elevation, contacts, springs, pairs is not None,
                               options.derivatives), shape, pairs).build()
    out.neighbours = pairs
    return out


class _Builder:
    """The blocks of :func:`build_spatial`, in order."""

    def __init__(self, pr: WeftProblem, options: Spatial, shape: Natural3D,
                 pairs: Neighbours | None = None) -> None:
        self.pr, self.opt, self.shape, self.pairs = pr, options, shape, pairs
        self.N, self.n = pr.n_loops, pr.wales
        self.nc, self.nq = n_coeffs(pr.t), n_coeffs(shape.modes)
        self.K = shape.s_upper.size * (self.N - self.n) if options.contacts else 0
        self.specials, self.clamp_pts, self.load_pts, self.rigid_pts = special_points(pr)
        pts = [pr.L]
        if options.contacts:
            pts += [*shape.s_upper, *shape.s_lower]
        if options.springs:
            pts += [pr.crossings.s[k] for k in ("B", "R", "E", "H")]
        pts += [sp.s for sp in self.specials]
        self.evals = list(dict.fromkeys(float(v) for v in pts))
        self.col = {s: q for q, s in enumerate(self.evals)}
        self.elements = Elements()          # every nonlinear term's mapped call (elements.py)
        mu = pr.yarn.friction if pr.yarn is not None else 0.0
        self.friction = Friction(mu, EPSILON * pr.L, self.K) if mu > 0 and self.K else None

    def build(self) -> SpatialNLP:
        pr = self.pr
        xl, xs, xb = self._variables()
        pl = param_layout(pr)
        n_lag = LAGGED_ROWS * self.K if self.friction is not None else 0
        ps = ca.MX.sym("p", pl.size + n_lag)
        pb = {name: ca.reshape(ps[pl.slice(name)], *shape)
              for name, (_, _, shape) in pl.blocks.items()}
        rows = Constraints()
        lifted = self._rows(xb, rows)
        clamp_rows, rigid_rows, z_rows = self._clamps(xb, pb, rows)
        spring, contact, bend, work, h, sin_a = self._energy(xb, pb)
        f, g = spring + contact + bend - work, rows.expression()
        if n_lag:
            f += self._friction(xb, ca.reshape(ps[pl.size:], LAGGED_ROWS, self.K))
        terms = ca.Function("terms", [xs, ps], [spring, contact, bend, work, h, sin_a])
        names = [n for n in LIFTED if n in xl.blocks]
        lift_fn = ca.Function("lifted", [xs], [lifted[n] for n in names])
        xs, f, g, terms, lift_fn, derivs = self._condensed(xs, ps, f, g, terms, lift_fn, xl.size)
        if n_lag:           # the terms do not use the lagged block: called with p as WeftParams'
            xt, pt = ca.MX.sym("x", xs.numel()), ca.MX.sym("p", pl.size)
            terms = ca.Function("terms", [xt, pt], terms(xt, ca.vertcat(pt, ca.DM.zeros(n_lag))))
        nlp = {"x": xs, "p": ps, "f": f, "g": g}
        npar = pr.courses * pr.wales * (self.nc + (self.nq if self.opt.elevation else 0)) + 3 * pr.courses
        table = ClampTable(self.specials, self.clamp_pts, self.load_pts, self.rigid_pts,
                           clamp_rows, rigid_rows)
        out = SpatialNLP(pr, nlp, xl, pl, rows.layout, rows.lower(), rows.upper(),
                         WeftParams.of(pr), table, npar, options=self.opt, shape=self.shape,
                         z_rows=z_rows, terms=terms, lifted=lift_fn, signs=self.signs)
        out.nlpsol_options = {**out.nlpsol_options, **derivs}
        out.friction = self.friction
        out.x0 = out.lift3d(np.broadcast_to(self.shape.coeffs, (pr.courses, pr.wales, self.nc)),
                            np.broadcast_to(self._b0(), (pr.courses, pr.wales, self.nq)),
                            self.shape.starts(pr.courses, pr.wales))
        return out

    def _condensed(self, xs: ca.MX, ps: ca.MX, f: ca.MX, g: ca.MX, terms: ca.Function,
                   lift_fn: ca.Function, nz: int) -> tuple:
        """The NLP on the decision variables (the first ``nz`` of xs): the samples rp, at the
        end of xs, substituted (``elements.condensed_derivatives``); f, g, the terms and the
        lifted blocks as Functions of them, and the derivative Functions for IPOPT (none with
        ``derivatives="casadi"``: CasADi's AD of the condensed NLP)."""
        elements = self.opt.derivatives == "elements"
        if self.pairs is None:
            derivs = element_derivatives(xs, ps, f, g, self.elements, nz) if elements else {}
            return xs, f, g, terms, lift_fn, derivs
        xc, derivs = ca.MX.sym("x", nz), {}
        zero_rp = ca.vertcat(xc, ca.DM.zeros(xs.numel() - nz))      # g and rp do not use rp
        x_of = ca.vertcat(xc, ca.Function("rp", [xs], [ca.vec(self.rp)])(zero_rp))
        if elements:
            xc, x_of, derivs = condensed_derivatives(xs, ps, f, g, self.elements, nz, self.rp,
                                                     self.repulsion)
            zero_rp = ca.vertcat(xc, ca.DM.zeros(xs.numel() - nz))
        return (xc, ca.Function("f", [xs, ps], [f])(x_of, ps),
                ca.Function("g", [xs, ps], [g])(zero_rp, ps),
                ca.Function("terms", [xc, ps], terms(x_of, ps)),
                ca.Function("lifted", [xc], lift_fn(x_of)), derivs)

    def _b0(self) -> np.ndarray:
        return self.shape.elevation if self.opt.elevation else np.zeros(self.nq)

    def _variables(self) -> tuple[Layout, ca.MX, dict[str, ca.MX]]:
        N, n = self.N, self.n
        xl = Layout()
        xl.add("coeffs", self.nc, N)
        if self.opt.elevation:
            xl.add("elev", self.nq, N)
        xl.add("starts", 3, N)
        if self.opt.springs:
            for name, _, _ in SPRINGS:
                xl.add(name, 2, N - n)
        if self.opt.contacts:
            xl.add("sigma", 2, self.K)
            xl.add("cp", 12, self.K)
        if self.specials:
            xl.add("PC", 3, len(self.specials))
        # the other contacts' samples: lifted at the end of xs, condensed in ``build``
        n_rp = 3 * N * self.pairs.samples if self.pairs is not None else 0
        xs = ca.MX.sym("x", xl.size + n_rp)
        xb = {name: ca.reshape(xs[xl.slice(name)], *shape)
              for name, (_, _, shape) in xl.blocks.items()}
        if n_rp:
            xb["rp"] = ca.reshape(xs[xl.size:], 3, N * self.pairs.samples)
        return xl, xs, xb

    def _rows(self, xb: dict[str, ca.MX], rows: Constraints) -> dict[str, ca.MX]:
        """Chaining (S2), the lifted blocks' rows, continuity, the crossings' closest points
        (S5); returns each lifted block's expression in the primary variables."""
        pr, N, n, P = self.pr, self.N, self.n, len(self.evals)
        A, X = xb["coeffs"], xb["starts"]
        Bel = xb["elev"] if self.opt.elevation else ca.DM.zeros(self.nq, N)
        rule = (pr.L, pr.t, self.shape.modes, np.array(self.evals), pr.quadrature_nodes)
        D = self.elements.call("loops", loop_displacements3d(*rule), N, A, Bel,
                               hessian=displacement_hessian(*rule),
                               jacobian=displacement_jacobian(*rule))[0]

        def at(s: float | np.ndarray, loops: np.ndarray) -> ca.MX:
            """Positions of material points s (one, or one per loop) on the given loops:
            start + per-loop integral (one indexing operation each)."""
            cols = np.vectorize(lambda v: self.col[float(v)])(np.broadcast_to(s, loops.shape))
            return X[:, loops.tolist()] + D[:, (loops * P + cols).tolist()]

        left = np.array([k for k in range(N) if k % n != n - 1], dtype=int)
        if left.size:
            rows.add("chain", X[:, (left + 1).tolist()] - at(pr.L, left))
        if not self.opt.elevation:
            rows.add("course_z", X[2, list(range(0, N, n))])
        lifted: dict[str, ca.MX] = {}
        up, low = np.arange(n, N), np.arange(0, N - n)
        if self.opt.springs:
            for name, upper, lower in SPRINGS:
                lifted[name] = (at(pr.crossings.s[lower], low) - at(pr.crossings.s[upper], up))[:2, :]
        if self.opt.contacts:
            lifted["cp"] = self._contact_points(A, Bel, xb["sigma"], at, up, low)
        if self.specials:
            lifted["PC"] = at(np.array([sp.s for sp in self.specials]),
                              np.array([sp.k for sp in self.specials]))
        if self.pairs is not None:
            self.rp = self._samples(A, Bel, X)          # condensed, not a lifted block
        for name, expr in lifted.items():
            rows.add(f"lift_{name}", xb[name] - expr)
        if n > 1:
            E, S = continuity_rows(pr.L, pr.t)
            rows.add("continuity", ca.mtimes(ca.DM(E), A[:, left.tolist()])
                     - ca.mtimes(ca.DM(S), A[:, (left + 1).tolist()]))
            if self.opt.elevation:
                E, S = continuity_rows(pr.L, self.shape.modes)
                rows.add("continuity_elev", ca.mtimes(ca.DM(E), Bel[:, left.tolist()])
                         - ca.mtimes(ca.DM(S), Bel[:, (left + 1).tolist()]))
        if self.opt.contacts:
            cp = xb["cp"]
            self.signs = self._signs()
            shell = self.pr.yarn.shell()
            self.crossing = self.elements.call(
                "crossings", crossing_terms(shell), self.K, cp[0:3, :],
                cp[3:6, :], cp[6:9, :], cp[9:12, :], ca.DM(self.signs).T,
                ca.DM(natural_scales(shell, self.shape.h0, self.K)).T)
            rows.add("closest", self.crossing[1])
        else:
            self.signs = np.zeros(0)
        return lifted

    def _contact_points(self, A: ca.MX, Bel: ca.MX, sigma: ca.MX, at: Any, up: np.ndarray,
                        low: np.ndarray) -> ca.MX:
        """(p_u, t_u, p_l, t_l) of every crossing (12 × K): the panel position at the natural
        crossing coordinate s0 plus the Gauss segment to σ (S3)."""
        sh, pr = self.shape, self.pr
        per = sh.s_upper.size
        ku = np.repeat(up, per)
        kl = np.repeat(low, per)
        s0u, s0l = np.tile(sh.s_upper, len(up)), np.tile(sh.s_lower, len(up))
        seg = segment(pr.L, pr.t, sh.modes, SEGMENT_NODES)
        parts = []
        for side, loops, s0, sig in (("upper", ku, s0u, sigma[0, :]), ("lower", kl, s0l, sigma[1, :])):
            delta, tang = self.elements.call(f"segment_{side}", seg, self.K, A[:, loops.tolist()],
                                             Bel[:, loops.tolist()], ca.DM(s0).T, sig)
            parts += [at(s0, loops) + delta, tang]
        return ca.vertcat(*parts)

    def _signs(self) -> np.ndarray:
        """ς per crossing (S6): h = +2r in the natural state (the same on every loop)."""
        return np.tile(self.shape.crossing_signs(), self.K // self.shape.s_upper.size)

    def _clamps(self, xb: dict[str, ca.MX], pb: dict[str, ca.MX], rows: Constraints
                ) -> tuple[list[ClampRows], list[slice], dict[int, int]]:
        """The planar clamp rows (``full.clamp_constraints``) on x, y, and z held at its natural
        value at every held point (unless φ is frozen: then each course's start)."""
        clamp_rows, rigid_rows = clamp_constraints(self.pr, xb, pb, self.clamp_pts,
                                                   self.rigid_pts, rows)
        held = sorted({sp for sp in self.clamp_pts} | {i for idx in self.rigid_pts for i in idx})
        z_rows: dict[int, int] = {}
        if self.opt.elevation and held:
            z0 = [self.shape.xyz([self.specials[k].s])[0, 2] for k in held]
            sl = rows.add("clamp_z", xb["PC"][2, held] - ca.DM(z0).T)
            z_rows = {k: sl.start + r for r, k in enumerate(held)}
        return clamp_rows, rigid_rows, z_rows

    def _energy(self, xb: dict[str, ca.MX], pb: dict[str, ca.MX]) -> tuple[ca.MX, ...]:
        pr, sh = self.pr, self.shape
        A = xb["coeffs"]
        Bel = xb["elev"] if self.opt.elevation else ca.DM.zeros(self.nq, self.N)
        rule = (pr.L, pr.t, sh.modes, pr.quadrature_nodes)
        bend = ca.sum2(self.elements.call(
            "bending", bending3d(*rule), self.N, A, Bel, ca.DM(sh.coeffs), ca.DM(self._b0()),
            pb["R_f"], hessian=bending_hessian(*rule))[0])
        spring = ca.MX(0)
        if self.opt.springs:
            k = ca.vertcat(pb["k_a"], pb["k_b"])
            c, M = pr.crossings, self.N - self.n
            spring = (ca.sum2(self.elements.call("springs_left", spring_pair_energy(), M, xb["SL"],
                                                 ca.DM(c.rest_left), ca.DM(c.frame_left), k)[0])
                      + ca.sum2(self.elements.call("springs_right", spring_pair_energy(), M,
                                                   xb["SR"], ca.DM(c.rest_right),
                                                   ca.DM(c.frame_right), k)[0]))
        contact, h, sin_a = ca.MX(0), ca.MX(0, 1), ca.MX(0, 1)
        if self.opt.contacts:
            out = self.crossing
            contact, h, sin_a = ca.sum2(out[0]), out[2].T, out[3].T
        self.repulsion = self._repulsion(xb)
        contact += self.repulsion
        work = ca.MX(0)
        for q, (ld, sp) in enumerate(zip(pr.loads, self.load_pts)):
            work += ca.dot(pb["forces"][:, q], xb["PC"][:2, sp] - ca.DM(pr.natural_position(ld.loop, ld.s)))
            dtheta = ca.mtimes(ca.DM(phi(ld.s, pr.L, pr.t)),
                               A[:, loop_index(pr, ld.loop)] - ca.DM(sh.coeffs))
            work += pb["moments"][q] * dtheta
        return spring, contact, bend, work, h, sin_a

    def _friction(self, xb: dict[str, ca.MX], lagged: ca.MX) -> ca.MX:
        """Σ_c D_c (F3) of the crossings' coordinates σ with the lagged block (4 × K), one
        element per crossing."""
        fr = self.friction
        return ca.sum2(self.elements.call("friction", friction_potential(fr.mu, fr.eps), self.K,
                                          xb["sigma"], lagged)[0])

    # -- the other contacts (model/spatial/repulsion.py, docs/weft3d.md) ------------------
    def _samples(self, A: ca.MX, Bel: ca.MX, X: ca.MX) -> ca.MX:
        """Every loop's repulsion samples (3 × N·S, column k·S + q): start + (S2), an element
        with the loops' closed-form Jacobian and Hessian (``loop_hessians``)."""
        pr, S = self.pr, self.pairs.samples
        rule = (pr.L, pr.t, self.shape.modes, sample_s(pr.L, S), pr.quadrature_nodes)
        D = self.elements.call("samples", loop_displacements3d(*rule), self.N, A, Bel,
                               hessian=displacement_hessian(*rule),
                               jacobian=displacement_jacobian(*rule))[0]
        return X[:, np.repeat(np.arange(self.N), S).tolist()] + D

    def _repulsion(self, xb: dict[str, ca.MX]) -> ca.MX:
        """U_other (R1) of the neighbour list, 0 without one."""
        if self.pairs is None:
            return ca.MX(0)
        return repulsion_energy(self.pr.yarn.shell(), self.pr.L / self.pairs.samples,
                                xb["rp"], self.pairs, self.elements.call)
