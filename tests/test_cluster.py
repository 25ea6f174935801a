"""Studies on other executors: a local process pool, a Dask LocalCluster, a thread pool; lost
workers and per-point timeouts (knit_nlp.studies)."""
from __future__ import annotations

import json
import os
import signal
from concurrent.futures import Executor, Future, ThreadPoolExecutor

import pytest

from knit_nlp.studies import LoadPath, open_executor, run_study
from knit_nlp.weft.model.cases import diagonal_pull
from knit_nlp.weft.model.problem import parse_problem
from knit_nlp.weft.study import WeftStudy

from test_study import _paths


def _summary(root, name="s"):
    return json.loads((root / name / "summary.json").read_text())


def _in_process(path: LoadPath) -> list[tuple[float, int]]:
    """(energy, iterations) of each point, solved here in order, each warm-started."""
    study, x, out = WeftStudy(parse_problem(path.doc, "<ref>")), None, []
    for point in path.points:
        p = study.params.with_(**point)
        rep = study.solve(p, x0=x)
        x = rep.x
        out.append((study.result(rep, p).energy.total, rep.iterations))
    return out


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The summary of the test_study paths on the local pool, uninterrupted."""
    root = tmp_path_factory.mktemp("reference")
    run_study("s", _paths(), root, workers=2)
    return _summary(root)


@pytest.fixture(scope="module")
def cluster():
    pytest.importorskip("distributed")
    with open_executor("local:2") as executor:
        yield executor


def test_pool_cluster_and_threads_give_the_same_summary_as_warm_started_solves(tmp_path, cluster,
                                                                              reference):
    """The same study on the local pool, a 2-worker LocalCluster and a thread pool: identical
    summaries, and each point's energy and iteration count are those of solving the path here,
    in order, warm-started (a cold start takes other iteration counts)."""
    half = run_study("s", _paths(), tmp_path / "dask", executor=cluster, limit=1)
    assert not half["complete"]
    run_study("s", _paths(), tmp_path / "dask", executor=cluster)       # resumed on the cluster
    with ThreadPoolExecutor(2) as threads:
        run_study("s", _paths(), tmp_path / "threads", executor=threads)
    assert reference == _summary(tmp_path / "dask") == _summary(tmp_path / "threads")
    for path in _paths():
        rows = [r for r in reference["points"] if r["path"] == path.name]
        got = [(r["energy"]["total"], r["iterations"]) for r in rows]
        assert got == _in_process(path)


def _slow_path() -> LoadPath:
    """One point that takes far longer than a quick one (a 16 x 16 pull from the natural state)."""
    return LoadPath("slow", diagonal_pull(16), [{}])


def _kill_test(tmp_path, executor, pids, reference):
    killed = []

    def kill_once(row):
        if not killed:                  # the first quick point is back; the slow one still runs
            killed.extend(pids())
            for pid in killed:
                os.kill(pid, signal.SIGKILL)

    paths = [_slow_path()] + _paths()
    summary = run_study("k", paths, tmp_path / "k", executor=executor, on_point=kill_once)
    assert killed and summary["lost_points"] >= 1
    assert summary["complete"] and all(r["success"] for r in summary["points"]), [(r["path"], r["index"], r["status"], r.get("reason")) for r in summary["points"]]
    quick = [r for r in summary["points"] if r["path"] != "slow"]
    assert quick == reference["points"]


def test_killed_pool_processes_are_survived(tmp_path, reference):
    """Killing every process of the local pool mid-study: the pool is rebuilt, the points it
    held are rerun, and every point ends as in an undisturbed run."""
    with open_executor(None, 2) as pool:
        _kill_test(tmp_path, pool, lambda: list(pool._processes), reference)


def test_killed_dask_workers_are_survived(tmp_path, cluster, reference):
    """Killing both Dask workers mid-study: the nannies restart them, the lost points are rerun."""
    client = cluster._client
    _kill_test(tmp_path, cluster, lambda: list(client.run(os.getpid).values()), reference)


def test_a_point_past_its_timeout_is_recorded_and_the_study_goes_on(tmp_path):
    """A 100 x 100 pull (tens of seconds) with a 5 s timeout: its worker is stopped (twice:
    once with company, once alone), it is recorded as timed out, and the other paths finish."""
    paths = [LoadPath("hang", diagonal_pull(100), [{}])] + _paths()
    summary = run_study("t", paths, tmp_path, workers=2, timeout=5.0)
    assert summary["complete"]
    hang, *quick = summary["points"]
    assert not hang["success"] and hang["status"] == "Study_Timeout"
    assert "5 s per-point timeout; worker stopped" in hang["reason"]
    assert all(r["success"] for r in quick) and len(quick) == 6
    assert not list((tmp_path / "t" / "points").glob("hang.*"))     # not cached: a rerun retries


class _Unpicklable(Executor):
    """An executor whose every task fails as on a Dask cluster without knit_nlp."""

    submitted = 0

    def submit(self, fn, /, *args, **kwargs):
        type(self).submitted += 1
        failed = Future()
        failed.set_exception(RuntimeError("Error during deserialization of the task graph"))
        return failed


def test_an_executor_error_is_recorded_once_not_rerun(tmp_path):
    """Not a lost worker: each point is tried once and recorded as Executor_Error."""
    with _Unpicklable() as executor:
        summary = run_study("e", _paths(), tmp_path, executor=executor, timeout=None)
    assert summary["complete"] and _Unpicklable.submitted == 6
    assert {r["status"] for r in summary["points"]} == {"Executor_Error"}
    assert "deserialization" in summary["points"][0]["reason"]
