"""Studies: many solves of one problem, on a local process pool or a Dask cluster.

- :mod:`.runner`, the submitting side: :class:`LoadPath`, :func:`run_study` (paths in
  parallel, points along a path in order and warm-started, a cache that makes a study
  resumable, failures and timeouts recorded per point).
- :mod:`.points`, the worker side: one point rebuilt from plain data and solved.
- :mod:`.executors`: the local pool, Dask (``--scheduler``), the shared command-line options.
- :mod:`.sweep`: grids over problem-file keys (``knit-nlp sweep``).
"""
from .executors import add_executor_arguments, open_executor
from .runner import (LoadPath, Progress, point_solution, print_table, run_study,
                     run_with_options)

__all__ = ["LoadPath", "Progress", "add_executor_arguments", "open_executor", "point_solution",
           "print_table", "run_study", "run_with_options"]
