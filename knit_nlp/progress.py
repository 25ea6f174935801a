"""IPOPT's progress on one updating line of stderr, through CasADi's ``iteration_callback``.

With ``--verbose`` every iterate is shown. Otherwise the line stays silent for the first
:data:`QUIET_FOR` seconds (a quick solve prints nothing), then is refreshed at most once a
second, so no solve runs silently for long; once half the ``[solver] max_time`` budget is
spent it says so once, naming the budget, so a user whose solve is heading for its time limit
knows before it gets there.

The line tells the time since the solve began (its ``[solver] max_time`` budget's start, shared
by every IPOPT solve of one answer: a contact solve's paper-model start, load steps and rounds
each have their own line object), and, while a continuation or contact load steps run
(:meth:`IterationLine.at`), the share of the load reached and an estimate of the time left at
the pace so far: elapsed on the path × (1 − f) / f.
"""
from __future__ import annotations

import sys
import time
import weakref
from typing import TextIO

import casadi as ca
import numpy as np

QUIET_FOR = 3.0    # seconds a solve runs before its progress line appears (without --verbose)


class Clock:
    """When a progress line is due: not before ``quiet_for`` seconds from :meth:`start`, then at
    most once every ``every`` seconds (every time when ``quiet_for`` is 0: ``--verbose``)."""

    def __init__(self, quiet_for: float, every: float = 1.0) -> None:
        self.quiet_for, self.every = quiet_for, every
        self.start()

    def start(self) -> None:
        self.t0 = self.shown = time.perf_counter()

    def due(self) -> float | None:
        """The seconds since :meth:`start` when a line is due (and it is then counted as
        shown), else None."""
        now = time.perf_counter()
        if now - self.t0 < self.quiet_for or (self.quiet_for and now - self.shown < self.every):
            return None
        self.shown = now
        return now - self.t0


class IterationLine(ca.Callback):
    """Called by ``nlpsol`` after every IPOPT iteration with the current iterate; rewrites one
    line: iterates so far (each solve's first is its start), objective, largest violation of the
    rows' bounds.
    It also stops IPOPT (``User_Requested_Stop``) once the clock passes :attr:`deadline` (a
    ``time.perf_counter`` value set by the caller before each solve): several solves sharing one
    ``[solver] max_time`` budget each get IPOPT's own ``max_wall_time`` of the whole budget, so
    without it a solve started late overran the budget by up to that much."""

    def __init__(self, nx: int, ng: int, stream: TextIO | None = None, *,
                 quiet_for: float = 0.0, budget: float = float("inf")) -> None:
        ca.Callback.__init__(self)
        self.nx, self.ng, self.count = nx, ng, 0
        self.stream = stream or sys.stderr
        self.clock, self.budget = Clock(quiet_for), budget
        self.deadline = float("inf")
        self.stage = ""                  # what this solve is for (yarn contact: its load step)
        self.bounds: tuple[np.ndarray, np.ndarray] | None = None   # the rows' lbg, ubg
        self.start()
        self.construct("iteration_line", {})

    def start(self) -> None:
        """Restart the clock (a new solve, or a new ``max_time`` budget)."""
        self.clock.start()
        self.warned = False

    def at(self, fraction: float) -> None:
        """:func:`loading` (for a solver's own line)."""
        loading(fraction)

    def elapsed(self, took: float) -> float:
        """Seconds since the solve began: since its ``max_time`` budget started (the deadline
        less the budget) when both are known, else since this line's clock started."""
        if np.isfinite(self.deadline) and np.isfinite(self.budget):
            return max(took, time.perf_counter() - (self.deadline - self.budget))
        return took

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "ret"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        if name in ("x", "lam_x"):
            return ca.Sparsity.dense(self.nx)
        if name in ("g", "lam_g"):
            return ca.Sparsity.dense(self.ng)
        return ca.Sparsity(0, 0)

    def eval(self, arg: list[ca.DM]) -> list[int]:
        self.count += 1
        if time.perf_counter() >= self.deadline:
            return [1]
        took = self.clock.due()
        if took is None:
            return [0]
        took = self.elapsed(took)
        if not self.warned and took > self.budget / 2:
            self.warned = True
            warning = (f"  warning: this solve has used {took:.0f} s, half its [solver] "
                       f"max_time of {self.budget:g} s; it may end without converging (exit 1)")
            width = _OPEN.get(self.stream, 0)
            self.stream.write(f"{chr(13) if width else ''}{warning.ljust(width)}\n")
            _OPEN[self.stream] = 0
        g = np.asarray(arg[2]).ravel()
        line = (f"  {self.stage}IPOPT iterate {self.count:5d}  objective "
                f"{float(arg[1]):.10g}  max violation {self.violation(g):.2e}  elapsed "
                f"{duration(took)}{path_told()}  ")
        # over the line open on this stream, blanking the rest of a longer one (another solve's)
        self.stream.write("\r" + line.ljust(_OPEN.get(self.stream, 0)))
        _OPEN[self.stream] = len(line)
        self.stream.flush()
        return [0]

    def violation(self, g: np.ndarray) -> float:
        """The largest violation of the rows' bounds (:attr:`bounds`, set by the solver before
        each solve; without them every row is taken as an equation g = 0). Inequality rows (yarn
        contact's gaps) count only where they are outside their bounds."""
        if not g.size:
            return 0.0
        if self.bounds is None:
            return float(np.max(np.abs(g)))
        lbg, ubg = self.bounds
        return float(np.max(np.maximum(np.maximum(lbg - g, g - ubg), 0.0)))

    def done(self) -> None:
        """End the updating line (if one is open on this line's stream) and the loading path."""
        no_path()
        if _OPEN.get(self.stream, 0):
            self.stream.write("\n")
            self.stream.flush()
            _OPEN[self.stream] = 0


def loading(fraction: float) -> None:
    """A loading path has reached ``fraction`` of its load (0 at its start): the progress lines
    add the share reached and the time left at the pace so far (shared by every line, as a
    path's solves may use several: contact's load steps and rounds)."""
    if _PATH.get("t0") is None or fraction <= 0 or fraction < _PATH["fraction"]:
        _PATH["t0"] = time.perf_counter()
    _PATH["fraction"] = float(fraction)


def no_path() -> None:
    """No loading path runs any more (a single solve follows, which must not be told as a
    share of the last path's load)."""
    _PATH.clear()


def duration(seconds: float) -> str:
    """``42 s``, ``3 min 05 s``, ``2 h 07 min``."""
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def path_told() -> str:
    """``; 62% of the load reached, about 1 min 30 s left`` while a loading path runs
    (:meth:`IterationLine.at`), else ''."""
    f, t0 = _PATH.get("fraction"), _PATH.get("t0")
    if f is None or t0 is None:
        return ""
    if f <= 0:
        return "; load path starting (estimate after its first step)"
    left = (time.perf_counter() - t0) * (1 - f) / f
    return f"; {f:.0%} of the load reached, about {duration(left)} left"


def end_lines() -> None:
    """End every updating line still open (before a command prints its answer on stdout,
    which a terminal shows on the same screen: ``knit-nlp control``'s summary was glued onto
    its last IPOPT line)."""
    for stream, width in list(_OPEN.items()):
        if width:
            stream.write("\n")
            stream.flush()
            _OPEN[stream] = 0


# the length of the updating line open on each stream (0 or absent: none). Shared by every
# IterationLine writing there: the solves of yarn contact each have their own line object, and
# each must overwrite (and blank) what the last one wrote, and end the line once
_OPEN: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


# the loading path under way (IterationLine.at): its start time ``t0`` and the share of the load
# reached ``fraction``; empty when none runs
_PATH: dict[str, float] = {}
