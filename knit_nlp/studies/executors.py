"""Where study points run: a local process pool (the default) or a Dask cluster.

``open_executor(scheduler, workers)`` gives a :class:`concurrent.futures.Executor`:

- ``None``: a :class:`~concurrent.futures.ProcessPoolExecutor` of ``workers`` processes (all
  cores by default);
- ``"local:N"``: a Dask ``LocalCluster`` of N single-threaded worker processes started here
  (and stopped at the end), through ``Client.get_executor()``;
- an address (``tcp://host:8786`` or ``host:8786``): the Dask scheduler running there.

Dask (``pip install 'knit_nlp[cluster]'``) is imported only when a scheduler is asked for.
"""
from __future__ import annotations

import argparse
import logging
import multiprocessing as mp
import os
import re
import sys
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager
from typing import Iterator

from ..errors import ArgumentError

CONNECT_TIMEOUT_S = 10
WORKERS_PER_CORE = 4       # --workers above this many per core is refused (max_workers)
_ADDRESS = re.compile(r"^(tcp|tls|inproc|ucx)://\S+$|^[A-Za-z0-9_.\-\[\]:]+:\d+$")


def max_workers() -> int:
    """The most local worker processes a study may ask for: four per core (a forked pool
    starts them all at once, so ``--workers 1000000000`` would fork until the machine stops)."""
    return WORKERS_PER_CORE * (os.cpu_count() or 1)


def local_pool(workers: int | None = None) -> ProcessPoolExecutor:
    """A process pool of ``workers`` processes (default: all cores; 1 to :func:`max_workers`,
    else ValueError); forked where possible."""
    if workers is not None and not 1 <= workers <= max_workers():
        raise ValueError(f"workers must be from 1 to {max_workers()} (four per core); "
                         f"got {workers}")
    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    return ProcessPoolExecutor(max_workers=workers or os.cpu_count() or 1, mp_context=ctx)


def capacity(executor: Executor) -> int:
    """How many points the executor runs at once: a process pool's size, a Dask cluster's
    worker threads (asked again each time: workers come and go), otherwise the cores here."""
    if isinstance(executor, ProcessPoolExecutor):
        return executor._max_workers                     # no public accessor
    client = getattr(executor, "_client", None)          # distributed.client.ClientExecutor
    if client is not None:
        return max(1, sum(client.nthreads().values()))
    return os.cpu_count() or 1


def _bad(value: str, message: str) -> ArgumentError:
    return ArgumentError(f"--scheduler {value}".rstrip(), message)


def parse_scheduler(value: str) -> tuple[str, int | str]:
    """``("local", N)`` for ``local:N`` (N >= 1), ``("address", value)`` for a scheduler address;
    anything else is an :class:`ArgumentError` naming ``--scheduler``."""
    _distributed()
    if value.startswith("local"):
        count = value[len("local:"):] if value.startswith("local:") else ""
        if not count.isdigit() or int(count) < 1:
            raise _bad(value, "use local:N with N >= 1 workers, e.g. local:2")
        return "local", int(count)
    if not _ADDRESS.match(value):
        raise _bad(value, "not a scheduler address; use tcp://HOST:PORT, HOST:PORT or local:N")
    return "address", value


def _distributed():
    try:
        import distributed
    except ImportError:
        raise _bad("", "dask.distributed is not installed; pip install 'knit_nlp[cluster]'") from None
    return distributed


@contextmanager
def _dask_executor(kind: str, value: int | str) -> Iterator[Executor]:
    distributed = _distributed()
    import dask

    # a task on a worker that dies fails at once: the study reruns it alone and decides
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        if kind == "local":
            cluster = distributed.LocalCluster(n_workers=int(value), threads_per_worker=1,
                                               processes=True, dashboard_address=":0",
                                               silence_logs=logging.ERROR)
            with cluster, distributed.Client(cluster) as client:
                yield client.get_executor()
            return
        try:
            client = distributed.Client(str(value), timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError) as err:
            raise _bad(str(value), f"cannot reach the scheduler ({' '.join(str(err).split())})") \
                from None
        with client:
            yield client.get_executor()


@contextmanager
def open_executor(scheduler: str | None = None, workers: int | None = None) -> Iterator[Executor]:
    """The executor a study runs on (module docstring); closed (or the cluster stopped) on exit."""
    if scheduler is None:
        with local_pool(workers) as pool:
            yield pool
        return
    with _dask_executor(*parse_scheduler(scheduler)) as executor:
        yield executor


def _scheduler_argument(value: str) -> str:
    """argparse ``type`` of ``--scheduler``: checked at parse time (one line, exit 2)."""
    try:
        parse_scheduler(value)
    except ArgumentError as err:
        raise argparse.ArgumentTypeError(f"{value!r}: {err.message}") from None
    return value


def _workers_argument(value: str) -> int:
    """argparse ``type`` of ``--workers``: a whole number from 1 to :func:`max_workers`."""
    try:
        workers = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{value!r}: use a whole number of processes") from None
    if not 1 <= workers <= max_workers():
        raise argparse.ArgumentTypeError(f"{value!r}: use 1 to {max_workers()} processes "
                                         f"(at most {WORKERS_PER_CORE} per core)")
    return workers


def _timeout_argument(value: str) -> float:
    try:
        seconds = float(value)
    except ValueError:
        seconds = -1.0
    if not 0 < seconds < float("inf"):
        raise argparse.ArgumentTypeError(f"{value!r}: use a positive number of seconds")
    return seconds


def add_executor_arguments(ap: argparse.ArgumentParser) -> None:
    """``--workers``, ``--scheduler`` and ``--timeout``, the same on every study command."""
    ap.add_argument("--workers", type=_workers_argument, default=None,
                    help=f"local processes, 1 to {WORKERS_PER_CORE} per core (default: all "
                         "cores; ignored with --scheduler)")
    ap.add_argument("--scheduler", type=_scheduler_argument, default=None, metavar="ADDRESS",
                    help="run on Dask: a scheduler address (tcp://HOST:PORT) or local:N for a "
                         "local cluster of N workers (needs knit_nlp[cluster])")
    ap.add_argument("--timeout", type=_timeout_argument, default=600.0, metavar="SECONDS",
                    help="a point without a result after this long is recorded as failed and "
                         "its worker stopped (default 600)")
