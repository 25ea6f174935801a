"""Benchmarks of the inverse commands, all ratios measured within one run.

    python scripts/bench_inverse.py            # place_stitch, formulation (a) vs (b), fit, 30 x 30
    python scripts/bench_inverse.py --without-a   # the same without (a), which runs 300 s

1. place_stitch (10 x 10): control end to end in a fresh process (``knit-nlp control``) and in
   process, against one forward solve of the same problem (build + solve from the natural state
   at the answer's targets; also ``knit-nlp solve`` end to end in a fresh process).
2. Formulation (a), measured against the shipped (b): one IPOPT NLP over (x, λ, u) whose
   constraints are the forward first-order conditions ∇ₓL = 0, g = 0 (exact second derivatives,
   i.e. third derivatives of the energy, by CasADi), objective the goal misfit.
3. fit of k_a, k_b, R_f from problems/fit_example (three 10 x 10 load cases).
4. 30 x 30 control: place_stitch scaled (corner held, H of (1, 30) actuated, H of (15, 15) moved
   by (3, 2.5)).
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from knit_nlp.tomlio import load_toml  # noqa: E402
from knit_nlp.weft.inverse.control import Controller  # noqa: E402
from knit_nlp.weft.inverse.fit import fit  # noqa: E402
from knit_nlp.weft.inverse.observations import load_observations  # noqa: E402
from knit_nlp.weft.inverse.spec import parse_control  # noqa: E402
from knit_nlp.weft.model.parametrisation import Full
from knit_nlp.weft.transcription.factory import transcribe  # noqa: E402
from knit_nlp.weft.model.problem import load_problem  # noqa: E402
from knit_nlp.weft.model.params import WeftParams  # noqa: E402
from knit_nlp.weft.solving.solve import WeftSolver, solve_nlp  # noqa: E402

PLACE = ROOT / "problems" / "place_stitch.toml"


def fresh(args: list[str]) -> float:
    """Wall time of a CLI command in a fresh process."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "knit_nlp.cli", *args], cwd=ROOT, check=False,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def forward_once(cp, u: np.ndarray) -> tuple[float, int]:
    """Build + solve the forward problem from the natural state at targets u."""
    t0 = time.perf_counter()
    wnlp = transcribe(cp.problem, Full())
    solver = WeftSolver(wnlp)
    ctl_p = wnlp.p0.copy()
    k = 0
    for a in cp.actuated:
        ctl_p[wnlp.p.slice("targets").start + 2 * a.index:][:2] = u[k:k + 2]
        k += 2
    rep = solve_nlp(wnlp, solver, params=WeftParams.from_vector(cp.problem, ctl_p))
    return time.perf_counter() - t0, rep.iterations


def control_in_process(path: Path) -> tuple[float, Controller, object]:
    """Build + optimise + stability + forward check (reading the file excluded, as for the
    forward solve it is compared with)."""
    cp = parse_control(path, load_toml(path))
    t0 = time.perf_counter()
    ctl = Controller(cp)
    ans = ctl.run()
    return time.perf_counter() - t0, ctl, ans


def kkt_nlp(ctl: Controller) -> dict:
    """Formulation (a): min goal misfit over (x, λ, u) s.t. ∇ₓL(x, λ, p(u)) = 0, g = 0."""
    wnlp = ctl.eq.wnlp
    nlp = wnlp.nlp
    x, p, g = nlp["x"], nlp["p"], nlp["g"]
    lam = ca.MX.sym("lam", g.numel())
    u = ca.MX.sym("u", len(ctl.idx))
    E = ca.DM(ctl.E)
    p_u = ca.DM(wnlp.p0) + ca.mtimes(E, u - ca.DM(ctl.u0))
    F = ca.vertcat(ca.gradient(nlp["f"] + ca.dot(lam, g), x), g)
    F_u = ca.substitute([F], [p], [p_u])[0]
    goals = ctl._goals                       # the same point Function the shipped command uses
    P = ca.vec(goals(x)[0])
    tgt = np.concatenate([gl.target for gl in ctl.cp.goals])
    w = ca.DM(ctl._w)
    res = w * (P - ca.DM(tgt))
    obj = ca.dot(res, res) + ctl.cp.travel_weight * ca.sumsqr(u - ca.DM(ctl.u0))
    z = ca.vertcat(x, lam, u)
    t0 = time.perf_counter()
    solver = ca.nlpsol("kkt_nlp", "ipopt", {"x": z, "f": obj, "g": F_u},
                       {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "max_iter": 500,
                                                       "max_wall_time": 300.0, "tol": 1e-8}})
    setup = time.perf_counter() - t0
    rep0 = ctl.equilibrium(ctl.u0)
    z0 = np.r_[rep0.x, rep0.lam_g, ctl.u0]
    lbz = np.r_[np.full(len(rep0.x) + len(rep0.lam_g), -np.inf), ctl.lower]
    ubz = np.r_[np.full(len(rep0.x) + len(rep0.lam_g), np.inf), ctl.upper]
    t1 = time.perf_counter()
    sol = solver(x0=z0, lbg=0, ubg=0, lbx=lbz, ubx=ubz)
    solve_s = time.perf_counter() - t1
    zs = np.asarray(sol["x"]).ravel()
    n, m = len(rep0.x), len(rep0.lam_g)
    stab = ctl.eq.stability(zs[:n], zs[n:n + m], ctl.params(zs[n + m:]))
    return {"status": solver.stats()["return_status"], "iterations": solver.stats()["iter_count"],
            "setup_s": setup, "solve_s": solve_s, "u": zs[n + m:], "objective": float(sol["f"]),
            "stable": stab.stable, "min_eig": stab.min_eigenvalue}


def thirty(tmp: Path) -> Path:
    text = PLACE.read_text()
    text = (text.replace('name = "place_stitch"', 'name = "place_stitch_30"')
            .replace("courses = 10", "courses = 30").replace("wales = 10", "wales = 30")
            .replace("loop = [1, 10]", "loop = [1, 30]").replace("loop = [5, 5]", "loop = [15, 15]")
            .replace("bounds = [[0.0, 60.0], [-10.0, 40.0]]", "bounds = [[0.0, 200.0], [-10.0, 120.0]]"))
    doc_path = tmp / "place_stitch_30.toml"
    doc_path.write_text(text)
    cp = parse_control(doc_path, load_toml(doc_path))
    h = cp.problem.natural_position((15, 15), cp.problem.crossings.s["H"])
    doc_path.write_text(text.replace("position = [13.93, 13.414]",
                                     f"position = [{h[0] + 3.0:.4f}, {h[1] + 2.5:.4f}]"))
    return doc_path


def main() -> None:
    import tempfile
    print("1. place_stitch (10 x 10)")
    cli_control = fresh(["control", "place_stitch", "--out", tempfile.mkdtemp()])
    cli_solve = fresh(["solve", "place_stitch", "--out", tempfile.mkdtemp()])
    t_ctl, ctl, ans = control_in_process(PLACE)
    t_fwd, it_fwd = forward_once(ctl.cp, ans.state.u)
    print(f"   control: {ans.status}, {ans.iterations} outer iterations, "
          f"{ctl.eq.forward_solves} forward solves (incl. start and check), stable {ans.stability.stable}")
    print(f"   timings {({k: round(v, 3) for k, v in ans.timings.items()})}")
    print(f"   end to end (fresh process): control {cli_control:.2f} s, solve {cli_solve:.2f} s, "
          f"ratio {cli_control / cli_solve:.2f}")
    print(f"   in process: control {t_ctl:.3f} s, one forward build + solve {t_fwd:.3f} s "
          f"({it_fwd} iterations), ratio {t_ctl / t_fwd:.2f} forward-solve equivalents")
    print("2. formulation (a): one NLP with the first-order conditions as constraints")
    if "--without-a" in sys.argv:
        print("   skipped (--without-a)")
    else:
        formulation_a(ctl, ans)
    _rest()


def formulation_a(ctl: Controller, ans) -> None:
    a = kkt_nlp(ctl)
    print(f"   {a['status']}, {a['iterations']} iterations, setup {a['setup_s']:.2f} s, solve "
          f"{a['solve_s']:.2f} s, objective {a['objective']:.3g}, u {np.round(a['u'], 4).tolist()}, "
          f"stable {a['stable']} (min eig {a['min_eig']:.3g})")
    print(f"   (b) optimise phase {ans.timings['optimise_s']:.3f} s against (a) setup + solve "
          f"{a['setup_s'] + a['solve_s']:.3f} s: ratio {(a['setup_s'] + a['solve_s']) / ans.timings['optimise_s']:.1f}")


def _rest() -> None:
    import tempfile
    print("3. fit of k_a, k_b, R_f from three 10 x 10 cases (problems/fit_example)")
    t0 = time.perf_counter()
    folder = ROOT / "problems" / "fit_example"
    probs = [load_problem(folder / f"{n}.toml") for n in ("fit_course_pull", "fit_wale_pull", "fit_shear")]
    f = fit(probs, load_observations(folder / "observations.csv", {p.name: p for p in probs}))
    t_fit = time.perf_counter() - t0
    print(f"   {f.status}, {f.iterations} iterations, {t_fit:.2f} s; values "
          f"{dict(zip(f.names, np.round(f.values, 6).tolist()))}")
    print("4. 30 x 30 control")
    path = thirty(Path(tempfile.mkdtemp()))
    t30, ctl30, ans30 = control_in_process(path)
    print(f"   {ans30.status}, {ans30.iterations} outer iterations, {ctl30.eq.forward_solves} forward "
          f"solves, {t30:.2f} s, stable {ans30.stability.stable}; timings "
          f"{({k: round(v, 3) for k, v in ans30.timings.items()})}")


if __name__ == "__main__":
    main()
