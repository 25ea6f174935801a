"""Wall time of one study on 1 and 2 local workers: the process pool and a Dask LocalCluster.

    python scripts/bench_study_scaling.py [--size 16] [--paths 4] [--steps 3] [--dask]

The study: ``--paths`` independent loading paths on an N x N diagonal pull (eq. 28 scaled, as
problems/diagonal_pull.toml), one per k_b value, each stepping the pulled clamp through
``--steps`` displacements (warm-started). Every run starts from an empty cache in a temporary
folder; a LocalCluster's start-up is timed separately from the study. Prints each wall time and
the 2-worker / 1-worker ratios, measured within this one run.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Sequence

import numpy as np

from knit_nlp.studies import LoadPath, open_executor, run_study
from knit_nlp.weft.model.cases import diagonal_pull


def paths(n: int, count: int, steps: int) -> list[LoadPath]:
    """``count`` paths (k_b from 0.01 to 1), each pulling clamp 2 in ``steps`` steps to eq. 28."""
    doc = diagonal_pull(n)
    target = np.array(doc["clamp"][1]["position"])
    out = []
    for kb in np.geomspace(0.01, 1.0, count):
        points = [{"material": {"k_b": float(kb)},
                   "targets": {"2": (target * (0.7 + 0.3 * k / max(steps - 1, 1))).tolist()}}
                  for k in range(steps)]
        out.append(LoadPath(f"kb{kb:.3g}", doc, points))
    return out


def timed(study: list[LoadPath], scheduler: str | None, workers: int) -> tuple[float, float]:
    """(start-up s, study s) on a fresh cache."""
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        with open_executor(scheduler, workers) as executor:
            t1 = time.perf_counter()
            summary = run_study("bench", study, Path(tmp), executor=executor)
            t2 = time.perf_counter()
        assert all(r["success"] for r in summary["points"]), "a point did not converge"
    return t1 - t0, t2 - t1


def main(argv: Sequence[str] | None = None) -> dict[str, float]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=16)
    ap.add_argument("--paths", type=int, default=4)
    ap.add_argument("--steps", type=int, default=3)
    ap.add_argument("--dask", action="store_true", help="also time a LocalCluster of 1 and 2")
    ap.add_argument("--repeat", type=int, default=1, help="alternate 1 and 2 workers this often")
    args = ap.parse_args(argv)
    study = paths(args.size, args.paths, args.steps)
    kinds = [("pool", None)] + ([("dask", "local")] if args.dask else [])
    ratios: dict[str, list[float]] = {kind: [] for kind, _ in kinds}
    for _ in range(args.repeat):
        for kind, scheduler in kinds:
            walls = []
            for workers in (1, 2):
                start, wall = timed(study, scheduler and f"{scheduler}:{workers}", workers)
                walls.append(wall)
                print(f"{kind:5s} {workers} worker(s): study {wall:6.2f} s  "
                      f"(start-up {start:5.2f} s)", flush=True)
            ratios[kind].append(walls[0] / walls[1])
            print(f"{kind}: 1 -> 2 workers speed-up {ratios[kind][-1]:.2f}x", flush=True)
    for kind, values in ratios.items():
        print(f"{kind}: speed-ups {' '.join(f'{r:.2f}' for r in values)}; "
              f"median {np.median(values):.2f}x")
    return {kind: float(np.median(v)) for kind, v in ratios.items()}


if __name__ == "__main__":
    main(sys.argv[1:])
