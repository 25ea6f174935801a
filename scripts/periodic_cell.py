"""The 3-D weft model's loop as a periodic cell pulled along the courses or the wales: the same
physics as the free-edged specimens of ``knit-nlp calibrate`` with no edges (issue 40's
question: is it the specimen's free edges that make the model ~10 times too soft?).

One loop repeated on its lattice (w, c), as the natural 3-D construction has it
(``natural_fit``): the loop closes on the lattice (x(L) − x(0) = (w, 0, 0)), θ, θ′, φ, φ′
periodic (N2), and its energy per cell is

    U = U_bend (S4, from the natural loop, or with ``--straight`` from a straight yarn as
        stitch-by-stitch bends it) + Σ over the two wraps E(h′, sin α) (S5-S7, C3: the model's
        persistent contacts with the loop one course up, p_u + (0, c, 0))
        + Σ over the other sample pairs w_s² v(d′) (R1, C3: every pair of sample points of the
        loop and its images within two courses and two wales naturally closer than 1.25·2r,
        but one piece of yarn and the wraps' own windows, as ``repulsion``'s list).

The pull fixes the lattice spacing along it, w = (1 + ε) w₀ (courses) or c = (1 + ε) c₀
(wales), by one row whose multiplier is the force through one cell, F = dU/dw (the envelope
theorem: checked by ``tests/test_periodic_cell.py`` against differences of U); the other
spacing is free (no lateral force, as a uniaxial pull). Per width: F / c₀ (courses) or F / w₀
(wales); at a specimen's real width: times the width, the test file's width in clamps times
35.5 mm (66.6 mm along the courses, 95.9 mm along the wales; docs/real_fabric.md).
With ``--straight`` the cell is first relaxed at zero force (w and c free) and the pull starts
there, its force relative to that state's.

    python scripts/periodic_cell.py [--spec real_fabric/acrylic_3d_source] [--straight]
                                    [--to 0.6] [--step 0.025] [--samples 80] [--reach 2.5]
                                    [--rigidity-factor K] [--bending-factor B]

Prints one line per strain node and, per direction, ``calibrate``'s checks of the curve at the
test's real width (``calibration.checks``: F at 10 % and 30 %, the stiffness per width at 10 %,
the tangent stiffening from 5 % to 45 %), model beside measured, and its metric
(``calibration.metric``: the RMS axial and lateral strain errors at 2-25 N; n/a where the
curve does not reach 25 N).
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from knit_nlp.tomlio import load_toml  # noqa: E402
from knit_nlp.weft.inverse.calibration.checks import outcome_checks  # noqa: E402
from knit_nlp.weft.inverse.calibration.measured import (MeasuredTest,  # noqa: E402
                                                        read_stitch_by_stitch)
from knit_nlp.weft.inverse.calibration.metric import METRIC_FORCES, metric  # noqa: E402
from knit_nlp.weft.inverse.calibration.spec import CLAMP_WIDTH_MM  # noqa: E402
from knit_nlp.weft.model.basis import continuity_rows, n_coeffs  # noqa: E402
from knit_nlp.weft.model.compression import SoftShell  # noqa: E402
from knit_nlp.weft.model.problem import parse_problem  # noqa: E402
from knit_nlp.weft.model.spatial.crossing_contact import crossing_terms  # noqa: E402
from knit_nlp.weft.model.spatial.curve3d import (bending3d, loop_displacements3d,  # noqa: E402
                                                 positions3d, segment)
from knit_nlp.weft.model.spatial.natural3d import Natural3D  # noqa: E402
from knit_nlp.weft.model.spatial.natural_fit import natural_check  # noqa: E402
from knit_nlp.weft.model.spatial.repulsion import natural_neighbours, sample_s  # noqa: E402

GAUSS = 16                       # Gauss nodes of a wrap's segment to σ
TESTS = {"courses": "acrylic_stockinette_x.csv", "wales": "acrylic_stockinette_y.csv"}


@dataclass
class Cell:
    """The periodic cell's NLP: x = (a, b, σ_u (2), σ_l (2), w, c), parameter the pulled
    spacing; ``solver`` IPOPT; ``energy`` U(x); ``pairs`` the other contacts' sample pairs."""

    shape: Natural3D
    natural: Natural3D
    core: float                  # R_c
    direction: str
    solver: ca.Function
    energy: ca.Function
    rows: int
    pairs: int

    @property
    def spacing0(self) -> float:
        return self.shape.wale_spacing if self.direction == "courses" else self.shape.course_spacing

    @property
    def x0_lattice(self) -> np.ndarray:
        """The reference lattice (w, c)."""
        return np.array([self.shape.wale_spacing, self.shape.course_spacing])

    @property
    def across0(self) -> float:
        return self.shape.course_spacing if self.direction == "courses" else self.shape.wale_spacing


def sample_pairs(shape: Natural3D, law: SoftShell, samples: int,
                 reach: float = 2.5) -> tuple[np.ndarray, ...]:
    """The other contacts' pairs of the cell: the 3-D model's own neighbour list
    (``repulsion.natural_neighbours``: one piece of yarn and the wraps' windows left out, each
    pair's thinning scale, C3) read from one loop of a 3 × 5 fabric, which holds every lattice
    offset of the list, to its images: sample coordinates s, sample k on the loop, m on its
    image at (dj·w, di·c), di, dj and the scale. The model lists pairs naturally closer than
    REACH·2r (1.25) and its rounds add those that come close; the cell has no rounds, so its
    list reaches ``reach``·2r (the law is zero beyond touch: a listed pair that stays apart
    costs only its evaluation)."""
    wales, loop = 5, 2                   # loop (course 1, wale 3); kb − ka = di·wales + dj
    nb = natural_neighbours(shape, law, 3, wales, samples, reach)
    sel = nb.ka == loop
    DI, DJ = np.divmod(nb.kb[sel] - loop + 2, wales)
    return sample_s(shape.length, samples), nb.qa[sel], nb.qb[sel], DI, DJ - 2, nb.scale[sel]


def build(shape: Natural3D, law: SoftShell, R_f: float, direction: str, samples: int = 80,
          straight: bool = False, reach: float = 2.5) -> Cell:
    """The cell's NLP (module docstring) along ``direction``."""
    L, t, q = shape.length, shape.harmonics, shape.modes
    nc, nq = n_coeffs(t), n_coeffs(q)
    xs = ca.MX.sym("x", nc + nq + 6)
    pulled = ca.MX.sym("spacing")
    a, b = xs[:nc], xs[nc:nc + nq]
    su, sl = xs[nc + nq:nc + nq + 2], xs[nc + nq + 2:nc + nq + 4]
    w, c = xs[-2], xs[-1]
    a0 = np.zeros(nc) if straight else shape.coeffs
    b0 = np.zeros(nq) if straight else shape.elevation
    energy = bending3d(L, t, q, 8)(a, b, ca.DM(a0), ca.DM(b0), R_f)
    seg, terms = segment(L, t, q, GAUSS), crossing_terms(law)
    shift = ca.vertcat(0, c, 0)
    rows = [seg(a, b, 0.0, L)[0] - ca.vertcat(w, 0, 0)]                         # closure
    for deg, coef in ((q, b), (t, a)):                                          # N2
        E, S = continuity_rows(L, deg)
        rows.append(ca.mtimes(ca.DM(E - S), coef))
    signs, scales = shape.crossing_signs(), law.thinning(shape.h0)
    for k in range(len(shape.s_upper)):                                         # S5-S7
        pu, tu = seg(a, b, 0.0, su[k])
        pl, tl = seg(a, b, 0.0, sl[k])
        e, r, *_ = terms(pu + shift, tu, pl, tl, signs[k], scales[k])
        energy += e
        rows.append(r)
    s, K, M, DI, DJ, scale = sample_pairs(shape, law, samples, reach)           # R1
    G = loop_displacements3d(L, t, q, s, 8)(a, b)
    off = ca.vertcat(ca.DM(DJ).T * w, ca.DM(DI).T * c, ca.DM.zeros(1, K.size))
    diff = G[:, M.tolist()] - G[:, K.tolist()] + off
    d = ca.sqrt(ca.sum1(diff ** 2)).T
    weight = (L / samples) ** 2
    energy += weight * ca.sum1(law.casadi_energy(law.seen(d, ca.DM(scale))))
    rows.append((w if direction == "courses" else c) - pulled)                  # the pull
    g = ca.vertcat(*rows)
    solver = ca.nlpsol("periodic_cell", "ipopt", {"x": xs, "p": pulled, "f": energy, "g": g},
                       {"print_time": False, "show_eval_warnings": False,   # NaN: in a core
                        "ipopt": {"print_level": 0, "sb": "yes", "tol": 1e-10,
                                  "max_iter": 500}})
    return Cell(shape, shape, law.core_radius, direction, solver,
                ca.Function("U", [xs], [energy]), g.numel(), int(K.size))


def natural_x(shape: Natural3D) -> np.ndarray:
    return np.concatenate([shape.coeffs, shape.elevation, shape.s_upper, shape.s_lower,
                           [shape.wale_spacing, shape.course_spacing]])


def solve(cell: Cell, spacing: float, x0: np.ndarray, free: bool = False) -> dict:
    """The cell at the pulled spacing (``free``: both spacings free, the pull's row dropped by
    loose bounds), from x0: x, U, F = dU/d(spacing) (the pull row's multiplier)."""
    n = x0.size
    lbx = np.full(n, -np.inf)
    ubx = np.full(n, np.inf)
    L = cell.shape.length
    lbx[-6:-2], ubx[-6:-2] = 0.0, L
    lbx[-2:] = 0.3 * np.array([cell.shape.wale_spacing, cell.shape.course_spacing])
    lbg = np.zeros(cell.rows)
    ubg = np.zeros(cell.rows)
    if free:
        lbg[-1], ubg[-1] = -np.inf, np.inf
    sol = cell.solver(x0=x0, p=spacing, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    st = cell.solver.stats()
    x = np.asarray(sol["x"]).ravel()
    return {"x": x, "U": float(sol["f"]), "F": -float(sol["lam_g"][-1]),
            "success": bool(st["success"]), "status": st["return_status"],
            "iterations": int(st["iter_count"])}


def check(cell: Cell, x: np.ndarray, core: float):
    """The independent all-pairs check of 4 x 4 loops of the periodic fabric at x, the designed
    crossings read on the natural fabric (``natural_fit.natural_check``): no pair of pieces
    inside the hard core, no crossing flipped."""
    from dataclasses import replace
    sh = cell.shape
    nc, nq = n_coeffs(sh.harmonics), n_coeffs(sh.modes)
    now = replace(sh, coeffs=x[:nc], elevation=x[nc:nc + nq], wale_spacing=float(x[-2]),
                  course_spacing=float(x[-1]))
    return natural_check(now, core, reference=cell.natural)


def pull(cell: Cell, strains: np.ndarray, x0: np.ndarray, say=print) -> list[dict]:
    """The cell pulled through ``strains`` (each node from the last), the first from x0 at 0;
    each node checked (:func:`check`)."""
    out, x, base = [], x0, None
    for e in strains:
        rep = solve(cell, (1 + e) * cell.spacing0, x)
        if not rep["success"]:
            say(f"  {cell.direction} {e:+.3f}: {rep['status']} ({rep['iterations']} it): stop")
            break
        x = rep["x"]
        across = x[-1] if cell.direction == "courses" else x[-2]
        verdict = check(cell, x, cell.core)
        rep.update(strain=float(e), lateral=float(across / cell.across0 - 1), clean=verdict.ok)
        out.append(rep)
        say(f"  {cell.direction} {e:+.3f}: F {rep['F']:.5g} N per cell, lateral "
            f"{rep['lateral']:+.4f}, U {rep['U']:.6g} N mm ({rep['iterations']} it); "
            f"{verdict.verdict()}")
    return out


def measured(direction: str) -> MeasuredTest:
    """The measured pull along ``direction`` (problems/real_fabric, stitch-by-stitch's data)."""
    name = TESTS[direction]
    return read_stitch_by_stitch(ROOT / "problems" / "real_fabric" / name, name)


def curve(cell: Cell, nodes: list[dict], f0: float, width: float) -> tuple[np.ndarray, ...]:
    """(axial strain, force at the real ``width`` (N), lateral strain) from the unloaded
    state on: the force per cell less ``f0``, per mm of the cell's reference width, times
    the width."""
    e = np.array([0.0] + [n["strain"] for n in nodes])
    F = np.array([0.0] + [n["F"] - f0 for n in nodes]) / cell.across0 * width
    lat = np.array([0.0] + [n["lateral"] for n in nodes])
    return e, F, lat


def at_forces(e: np.ndarray, F: np.ndarray, y: np.ndarray, forces) -> np.ndarray:
    """y at the first point of the curve whose force reaches each force (linear between
    nodes), NaN where it never does: the model's side of calibrate's metric."""
    out = np.full(len(forces), np.nan)
    for k, force in enumerate(forces):
        hits = np.flatnonzero(F >= force)
        if hits.size and hits[0] > 0:
            i = int(hits[0])
            out[k] = y[i - 1] + (y[i] - y[i - 1]) * (force - F[i - 1]) / (F[i] - F[i - 1])
    return out


def compare(cell: Cell, nodes: list[dict], f0: float, test: MeasuredTest) -> dict:
    """calibrate's checks (``checks.outcome_checks``, model beside measured) and its metric
    (``metric.metric`` at METRIC_FORCES: RMS axial and lateral strain errors, None where the
    curve does not reach every force) of the cell's curve at the test's real width."""
    width = test.width_clamps * CLAMP_WIDTH_MM
    e, F, lat = curve(cell, nodes, f0, width)
    checks = outcome_checks((e, F), [(r.axial, r.force) for r in test.runs], width)
    pts = metric(test, METRIC_FORCES, at_forces(e, F, e, METRIC_FORCES),
                 at_forces(e, F, lat, METRIC_FORCES))
    return {"checks": checks, "rms_axial": pts.rms_axial, "rms_lateral": pts.rms_lateral,
            "width_mm": width, "top_N": float(F.max())}


def _show(v: float | None, fmt: str = ".3g") -> str:
    return "n/a" if v is None else f"{v:{fmt}}"


def summary(direction: str, seconds: float, nodes: list[dict], spacing0: float, c: dict) -> str:
    """One line: how far and how clean the pull went, the checks model (measured) and the
    metric."""
    dirty = next((n["strain"] for n in nodes if not n["clean"]), None)
    reached = nodes[-1]["strain"] if nodes else 0.0
    clean = "every node clean" if dirty is None else f"not clean from {dirty:.3f}"
    mo, me = c["checks"]["model"], c["checks"]["measured"]

    def pair(key: str, sub: str | None = None) -> str:
        a, b = (d[key] if sub is None else d[key][sub] for d in (mo, me))
        return f"{_show(a)} ({_show(b)})"
    return (f"{direction} ({seconds:.0f} s, reached {reached:.3f} from {spacing0:.4f} mm, {clean}"
            f"; at {c['width_mm']:.1f} mm, up to {c['top_N']:.3g} N), model (measured): "
            f"F(10 %) {pair('force_N', '0.1')} N, F(30 %) {pair('force_N', '0.3')} N, K/W(10 %) "
            f"{pair('stiffness_per_width')} N/mm, stiffening 5 -> 45 % {pair('stiffening')}; "
            f"RMS strain error axial {_show(c['rms_axial'], '.4f')}, lateral "
            f"{_show(c['rms_lateral'], '.4f')}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", default="real_fabric/acrylic_3d_source",
                    help="a calibration spec under problems/ whose [loop], [material] and "
                         "[yarn] give the yarn")
    ap.add_argument("--straight", action="store_true")
    ap.add_argument("--to", type=float, default=0.6, help="the largest strain (the measured "
                    "course pulls end near 60 %)")
    ap.add_argument("--step", type=float, default=0.025)
    ap.add_argument("--samples", type=int, default=80, help="repulsion samples per loop")
    ap.add_argument("--rigidity-factor", type=float, default=1.0,
                    help="the contact rigidity k times this (a lever, not a fit)")
    ap.add_argument("--bending-factor", type=float, default=1.0, help="R_f times this")
    ap.add_argument("--reach", type=float, default=2.5,
                    help="the other pairs listed: naturally closer than REACH x 2r")
    ap.add_argument("--directions", default="courses,wales")
    args = ap.parse_args(argv)
    spec = load_toml(ROOT / "problems" / f"{args.spec}.toml")
    doc = {k: spec[k] for k in ("loop", "material", "yarn", "units") if k in spec}
    doc["fabric"] = {"courses": 2, "wales": 2}
    pr = parse_problem(doc, f"{args.spec}.toml")
    shape, law = pr.yarn.natural3d, pr.yarn.shell()
    law = SoftShell(law.radius, law.core_radius, law.rigidity * args.rigidity_factor,
                    law.exponent)
    R_f = pr.R_f * args.bending_factor
    print(f"{args.spec}: natural lattice w = {shape.wale_spacing:.4f} mm, c = "
          f"{shape.course_spacing:.4f} mm; bending from "
          f"{'a straight yarn' if args.straight else 'the natural loop'}; k = {law.rigidity:g} "
          f"N/mm^3, R_f = {R_f:g} N mm^2")
    strains = np.round(np.arange(args.step, args.to + 1e-9, args.step), 6)
    for direction in args.directions.split(","):
        t0 = time.perf_counter()
        cell = build(shape, law, R_f, direction, args.samples, args.straight, args.reach)
        x0 = natural_x(shape)
        rest = solve(cell, cell.spacing0, x0, free=args.straight)
        if not rest["success"]:
            print(f"{direction}: the cell at rest did not converge ({rest['status']})")
            continue
        x0 = rest["x"]
        spacing0 = x0[-2] if direction == "courses" else x0[-1]
        print(f"{direction}: {cell.pairs} other pairs; at rest F {rest['F']:.3g} N, U "
              f"{rest['U']:.6g} N mm, lattice ({x0[-2]:.4f}, {x0[-1]:.4f}) mm")
        if args.straight:
            cell.shape = _relaxed(shape, x0)
        nodes = pull(cell, strains, x0)
        c = compare(cell, nodes, rest["F"] if args.straight else 0.0, measured(direction))
        print(summary(direction, time.perf_counter() - t0, nodes, spacing0, c))
    return 0


def _relaxed(shape: Natural3D, x: np.ndarray) -> Natural3D:
    """The shape whose lattice is the relaxed cell's (the pull's reference spacings)."""
    from dataclasses import replace
    return replace(shape, wale_spacing=float(x[-2]), course_spacing=float(x[-1]))


if __name__ == "__main__":
    sys.exit(main())
