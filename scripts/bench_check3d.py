"""The 3-D check's broad phase against the IPC toolkit's, and its cost on a large fabric
(docs/weft3d.md, "Check"; figures in docs/measurements.md).

    python scripts/bench_check3d.py [--skip-solve] [N ...]        (default N = 100)

1. The shipped ``diagonal_pull_3d`` solved (about 15-60 s), its deformed centrelines sampled
   as the check samples them: every pair of segments closer than 2r (the check's reach), not
   sharing a sample, found (a) by the check's broad phase (``contact.near.close_pairs`` on the
   segments' midpoints, radius 2r + the longest segment) and (b) by ipctk's (``Candidates.build``
   on a CollisionMesh of the polylines, boxes inflated by r, its default broad phase and its
   HashGrid, BVH and SweepAndPrune), each followed by the same exact segment distance
   (``proximity.segment_distance``): the two sets must be equal; the seconds of each (second
   call of each, the first pays imports and set-up). Then the
   whole check's verdict on that answer. ``--skip-solve`` takes the natural 6 x 6 fabric.
2. An N x N natural 3-D acrylic fabric built with numpy (the natural loop placed on its
   lattice, ``output.check.spatial_natural``'s shape): the whole check's seconds and its peak
   memory (the child process's maximum resident set, ``resource``).

ipctk is not a dependency of knit_nlp: ``pip install ipctk`` (1.6.1 measured). Timings are
wall-clock on a shared machine: compare ratios of one run.
"""
from __future__ import annotations

import multiprocessing as mp
import resource
import sys
import time

import numpy as np

from knit_nlp.weft.model.contact.near import close_pairs
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.model.spatial.proximity import ROWS, Courses, segment_distance
from knit_nlp.weft.model.spatial.proximity import spatial_natural, spatial_samples, spatial_state
from knit_nlp.problems import resolve
from knit_nlp.tomlio import load_toml


def acrylic(n: int):
    """The shipped 3-D pull's problem resized to n x n (for its natural loop and yarn)."""
    doc = load_toml(resolve("diagonal_pull_3d"))
    doc["fabric"] = {"courses": n, "wales": n}
    doc["clamp"] = doc["clamp"][:1]
    return parse_problem(doc, "acrylic.toml")


def natural_fabric(pr, S: int) -> np.ndarray:
    """The natural 3-D fabric's centrelines (m, n, S, 3): one course placed course by course."""
    one = spatial_natural(pr, S)[:1, :pr.wales]
    rows = np.arange(pr.courses)[:, None, None, None] * np.array(
        [0.0, pr.natural.course_spacing, 0.0])
    return one + rows


def ours(courses: Courses, reach: float) -> tuple[set, float, float]:
    """The check's pairs within ``reach``, the seconds in all and in the broad phase alone."""
    t0 = time.perf_counter()
    p, d = courses.segments()
    length = float(np.sqrt(np.max(np.einsum("ki,ki->k", d, d))))
    candidates = list(close_pairs(p + d / 2, reach + length + 1e-12, ROWS))
    t_broad = time.perf_counter() - t0
    found = [_narrow(courses, p, d, uv, reach) for uv in candidates]
    return (set(map(tuple, np.concatenate(found).tolist())), time.perf_counter() - t0,
            t_broad)


def theirs(courses: Courses, reach: float, broad: str) -> tuple[set, float, float]:
    import ipctk
    m, K1 = courses.points.shape[:2]
    V = np.asfortranarray(courses.points.reshape(-1, 3))
    k = np.arange(m * K1).reshape(m, K1)
    E = np.asfortranarray(np.stack([k[:, :-1].ravel(), k[:, 1:].ravel()], 1).astype(np.int32))
    t0 = time.perf_counter()
    mesh = ipctk.CollisionMesh(V, E)
    cand = ipctk.Candidates()
    phase = {"default": None, "HashGrid": ipctk.HashGrid, "BVH": ipctk.BVH if hasattr(ipctk, "BVH")
             else ipctk.LBVH, "SweepAndPrune": ipctk.SweepAndPrune}[broad]
    if phase is None:
        cand.build(mesh, V, reach / 2)
    else:
        cand.build(mesh, V, reach / 2, phase())
    t_build = time.perf_counter() - t0
    uv = np.array([(c.edge0_id, c.edge1_id) for c in cand.ee_candidates], dtype=np.int64)
    p, d = courses.segments()
    found = _narrow(courses, p, d, uv.reshape(-1, 2), reach)
    return set(map(tuple, found.tolist())), time.perf_counter() - t0, t_build


def _narrow(courses: Courses, p, d, uv: np.ndarray, reach: float) -> np.ndarray:
    """Pairs (u < v) within ``reach`` that do not share a sample (neighbours along a course)."""
    K = courses.per_course
    u, v = np.minimum(uv[:, 0], uv[:, 1]), np.maximum(uv[:, 0], uv[:, 1])
    keep = ~((u // K == v // K) & (v - u <= 1))
    u, v = u[keep], v[keep]
    dist, _, _ = segment_distance(p[u], d[u], p[v], d[v])
    return np.stack([u[dist < reach], v[dist < reach]], 1)


def compare(skip_solve: bool) -> None:
    if skip_solve:
        pr = acrylic(6)
        S = spatial_samples(pr)
        lines = natural_fabric(pr, S)
        what = "natural 6 x 6"
    else:
        import knit_nlp
        pr = parse_problem(load_toml(resolve("diagonal_pull_3d")), resolve("diagonal_pull_3d"))
        t0 = time.perf_counter()
        res = knit_nlp.solve(pr)
        print(f"diagonal_pull_3d: {res.status} in {time.perf_counter() - t0:.1f} s")
        S = spatial_samples(pr)
        lines = res.nlp.centrelines3d(res.x, S)
        what = "diagonal_pull_3d solved"
    courses = Courses.of(lines, pr.L)
    reach = 2 * pr.yarn.radius
    ours(courses, reach)                    # the first call imports scipy's k-d tree
    mine, t_mine, t_broad = ours(courses, reach)
    print(f"{what}: {lines.shape[0]} x {lines.shape[1]} loops, {S} samples per loop, "
          f"{len(courses.segments()[0])} segments; pairs within 2r = {reach:g} mm")
    print(f"  check's broad phase (k-d tree, close_pairs) + exact distance: {len(mine)} pairs, "
          f"{t_mine:.3f} s (its broad phase {t_broad:.3f} s)")
    for broad in ("default", "HashGrid", "BVH", "SweepAndPrune"):
        theirs(courses, reach, broad)
        got, t, t_build = theirs(courses, reach, broad)
        print(f"  ipctk {broad} + exact distance: {len(got)} pairs, {t:.3f} s (its broad phase "
              f"{t_build:.3f} s, the rest reading its candidates into numpy and the distances), "
              "same pairs: "
              f"{got == mine} (only ours {len(mine - got)}, only ipctk's {len(got - mine)})")
        if got != mine:                     # what differs, to look at
            p, d = courses.segments()
            for name, uv in (("only ours", mine - got), ("only ipctk's", got - mine)):
                uv = np.array(sorted(uv)[:3], dtype=np.int64).reshape(-1, 2)
                dist = segment_distance(p[uv[:, 0]], d[uv[:, 0]], p[uv[:, 1]], d[uv[:, 1]])[0]
                print(f"    {name}: {uv.tolist()} at {np.round(dist, 4).tolist()} mm")
            np.save("bench_check3d_mismatch.npy", lines)
    t0 = time.perf_counter()
    rep = spatial_state(pr, lines)
    print(f"  check ({time.perf_counter() - t0:.2f} s):", rep.verdict("mm"))


def _large(n: int, queue) -> None:
    pr = acrylic(n)
    S = spatial_samples(pr)
    t0 = time.perf_counter()
    lines = natural_fabric(pr, S)
    t1 = time.perf_counter()
    rep = spatial_state(pr, lines)
    t2 = time.perf_counter()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    queue.put((S, t1 - t0, t2 - t1, peak, rep.verdict("mm")))


def large(n: int) -> None:
    queue = mp.get_context("fork").Queue()
    proc = mp.get_context("fork").Process(target=_large, args=(n, queue))
    proc.start()
    S, build, check, peak, verdict = queue.get()
    proc.join()
    print(f"natural {n} x {n} acrylic, {S} samples per loop: geometry {build:.2f} s, check "
          f"{check:.2f} s, peak resident memory {peak:.0f} MB")
    print("  check:", verdict)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    compare("--skip-solve" in sys.argv)
    for n in [int(a) for a in args] or [100]:
        large(n)
