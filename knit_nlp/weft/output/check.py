"""``knit-nlp check RESULT.json`` (the command is in ``weft.commands``): do the yarns of a weft result pass through each other, and
(with a yarn radius) are non-crossing pieces closer than 2r?

Works on any weft result JSON (with or without contact): the loops are rebuilt from the
result's course starts and coefficients (eq. 1) on the problem's loop length. Crossings are
counted on polylines of ``samples`` segments per loop (at least 200, the solver's count:
crossings.crossing_samples), the gaps searched at ``samples`` per loop but no finer than four
samples per radius (pairs.check_samples; a search estimated above limits.CHECK_ROWS sample pairs
is refused in one line). Crossings are counted per pair of loops against the natural fabric
(crossings.judge: new crossings are yarns that passed through each other; designed crossings
that vanished are reported as lost). Gaps: every local minimum of the distance between two
pieces of yarn that are not one piece (pairs.find_pairs, polished on the continuous
centrelines) closer than 2r·(1 − ``GAP_TOL``) is counted, and one closer than its requirement
min(2r, natural gap)·(1 − ``GAP_TOL``) (natural.py, "Thick yarn") is a violation (the
``LISTED`` shortest of those are listed). Pieces in a designed box, natural or around a
designed crossing that slid (zones.py, as the solver has them), have no required gap.
"""
from __future__ import annotations

import gc
import json
import math
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from ...errors import ProblemError, shown
from ...limits import CHECK_ROWS, too_large
from ...jsonio import write_json
from ...tomlio import read_regular_file
from ..model.basis import n_coeffs
from ..model.contact.crossings import (Crossings, Verdict, crossing_samples, designed_zones,
                                       find_crossings, judge)
from ..model.contact.curves import Curves
from ..model.contact.natural import NaturalFabric
from ..model.contact.near import TooLarge
from ..model.contact.pairs import (CHECK_REACH, GAP_TOL, SAMPLES, Grid, Pairs, check_samples,
                                   checked_pairs, short as short_of)
from ..model.problem import WeftProblem
from ..model.quadrature import positions
from ..model.spatial.curve3d import positions3d
from ..model.spatial.proximity import ProximityReport
from ..model.spatial.state import spatial_samples, spatial_state

REACH = CHECK_REACH        # pairs within this many r of their required gap are looked at
#                            (GAP_TOL: no gap below its requirement·(1 − 1e-3); both shared
#                            with the contact rounds' last word, pairs.checked_pairs)
# the report lists at most this many short gaps, the shortest (relative to their requirement)
# first, and counts them all: the paper's 100 x 100 pull judged at r = 0.15 has 2.3 million
LISTED = 1000
MAX_RESULT_BYTES = 256 * 2 ** 20


@dataclass
class CheckReport:
    """What the checker found; ``ok`` when no new crossing and no gap below its requirement."""

    problem: str
    radius: float | None
    new_crossings: list[dict[str, Any]]
    lost: list[dict[str, Any]]                    # designed crossings lost, per pair of loops
    short_gaps: list[dict[str, Any]]              # below their requirement: violations
    #                                                (the LISTED shortest; ``n_short`` all)
    below_2r: int                                 # below 2r (thick yarn pairs included)
    smallest_gap: float | None                    # between pieces that must keep 2r
    thick_below_2r: int = 0                       # naturally closer than 2r, not closer now
    interlock_below_2r: int = 0                   # in designed interlocks (crossing is theirs)
    samples: int = SAMPLES                        # segments per loop of the crossing count
    gap_samples: int | None = None                # samples per loop of the gap search
    notes: list[str] = field(default_factory=list)
    n_short: int = 0                              # gaps below their requirement, all of them

    @property
    def lost_crossings(self) -> int:
        return sum(p["lost"] for p in self.lost)

    @property
    def ok(self) -> bool:
        return not self.new_crossings and not self.n_short

    # the results contract (knit_nlp/outcome.py): the answer passes its check
    @property
    def success(self) -> bool:
        return self.ok

    @property
    def status(self) -> str:
        """``Clean`` (``ok``) or ``Violations_Found`` (new crossings or short gaps)."""
        return "Clean" if self.ok else "Violations_Found"

    @property
    def message(self) -> str:
        """One sentence: the check's verdict."""
        return self.verdict()

    def line(self) -> str:
        """The one-line summary."""
        text = (f"{self.problem}: {'clean' if self.ok else 'VIOLATIONS'}: {self.n_new} new "
                f"crossings between {len(self.new_crossings)} pairs of loops")
        if self.radius is not None:
            text += f"; {self.n_short} gaps below their requirement"
            text += (f", smallest gap {self.smallest_gap / (2 * self.radius):.6g} x 2r "
                     f"(r = {self.radius:g})" if self.smallest_gap is not None
                     else f", no pieces within 4r (r = {self.radius:g})")
            if self.thick_below_2r:
                text += (f"; {self.thick_below_2r} thick-yarn pairs below 2r (naturally "
                         "closer, not closer now)")
            if self.interlock_below_2r:
                text += f"; {self.interlock_below_2r} pairs in designed interlocks below 2r"
        else:
            text += "; no yarn radius, gaps not checked"
        return text + f"; {self.lost_crossings} designed crossings lost" + self._where_lost()

    def _where_lost(self) -> str:
        """Between how many pairs of loops the lost crossings are, and how many of those
        pairs lie inside the fabric (no loop on its edge)."""
        if not self.lost:
            return ""
        inside = sum(not p["edge"] for p in self.lost)
        where = ("all at the fabric's edges" if not inside else
                 f"{inside} of them inside the fabric")
        return f" (between {len(self.lost)} pairs of loops, {where})"

    @property
    def n_new(self) -> int:
        return sum(c["count"] for c in self.new_crossings)

    def verdict(self) -> str:
        """What the check says about the answer, in words (the summary's, the picture's and
        the result JSON's ``check.verdict``)."""
        n = self.n_new
        if self.radius is None:
            return (f"{n} new crossings between {len(self.new_crossings)} pairs of loops: the "
                    "paper's model has no yarn contact (add [yarn] radius)" if n else
                    "clean: no yarn passes through another")
        if self.ok:
            text = "clean: no new crossing, no gap below its requirement"
        else:
            text = (f"{n} new crossings, {self.n_short} gaps below their requirement: the "
                    "answer lets yarns overlap")
        if self.smallest_gap is not None:
            text += f" (smallest gap {self.smallest_gap / (2 * self.radius):.4g} x 2r)"
        if self.thick_below_2r:
            text += (f"; {self.thick_below_2r} thick-yarn pairs closer than 2r (naturally "
                     "closer, kept at their natural gap: the yarn is thick for this loop)")
        return text

    def block(self) -> dict[str, Any]:
        """The result JSON's ``check`` block: the counts, without the lists."""
        gap = self.smallest_gap
        return {"ok": self.ok, "verdict": self.verdict(), "radius": self.radius,
                "new_crossings": self.n_new,
                "new_crossing_pairs": len(self.new_crossings),
                "lost_designed_crossings": self.lost_crossings,
                "short_gaps_count": self.n_short,
                "smallest_gap_over_2r": (None if gap is None or self.radius is None
                                         else gap / (2 * self.radius)),
                "thick_pairs": self.thick_below_2r,
                "interlock_pairs_below_2r": self.interlock_below_2r,
                "samples_per_loop": self.samples, "gap_samples_per_loop": self.gap_samples,
                "command": "knit-nlp check RESULT.json lists them"}

    def to_json(self) -> dict[str, Any]:
        return {"problem": self.problem, "ok": self.ok, "radius": self.radius,
                "samples_per_loop": self.samples, "gap_samples_per_loop": self.gap_samples,
                "gap_tolerance": GAP_TOL,
                "new_crossings": self.new_crossings, "lost_designed_crossings": self.lost_crossings,
                "lost_crossings": self.lost,
                "short_gaps_count": self.n_short, "short_gaps": self.short_gaps,
                "gaps_below_2r": self.below_2r,
                "thick_yarn_pairs_below_2r": self.thick_below_2r,
                "interlock_pairs_below_2r": self.interlock_below_2r,
                "smallest_gap": self.smallest_gap, "notes": self.notes}

    def save(self, out_dir: Path | str, result_path: Path | str | None = None) -> list[Path]:
        """``<result stem>.check.json`` in ``out_dir`` (``knit-nlp check``'s file), named after
        the checked result file ``result_path`` (``<problem>.check.json`` without one)."""
        stem = (self.problem if result_path is None
                else Path(result_path).name.removesuffix(".json"))
        return [write_json(Path(out_dir) / f"{stem}.check.json", self.to_json())]


def loops_of(result: Any, problem: WeftProblem, where: str = "result"
             ) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients (m, n, 2t+2) and loop starts (m, n, 2) of a result JSON (a solve's, or a
    control's ``equilibrium``), checked against the problem (ProblemError naming the key
    otherwise)."""
    m, n, nc = problem.courses, problem.wales, n_coeffs(problem.t)
    if not isinstance(result, dict):
        raise ProblemError(where, "", "", f"a weft result is a JSON object, got "
                           f"{type(result).__name__}")
    if "loops" not in result and isinstance(result.get("equilibrium"), dict):
        result = result["equilibrium"]           # a control result: its equilibrium's loops
    loops = result.get("loops")
    if not isinstance(loops, dict):
        raise ProblemError(where, "loops", "", "missing: not a weft solve or control result")
    coeffs = _array(loops.get("coefficients"), (m, n, nc), where, "coefficients")
    course = _array(loops.get("course_starts"), (m, 2), where, "course_starts")
    ends = positions(coeffs.reshape(-1, nc), [problem.L], problem.L, problem.t).reshape(m, n, 2)
    starts = np.concatenate([course[:, None], ends[:, :-1]], axis=1).cumsum(axis=1)
    return coeffs, starts


def _array(value: Any, shape: tuple[int, ...], where: str, key: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ProblemError(where, "loops", key, f"must be an array of numbers of shape "
                           f"{list(shape)} (the problem's courses, wales, ...)") from None
    if arr.shape != shape:
        raise ProblemError(where, "loops", key, f"has shape {list(arr.shape)}, the problem "
                           f"needs {list(shape)}: is it the result of this problem?")
    if not np.all(np.isfinite(arr)) or np.any(np.abs(arr) > 1e12):
        raise ProblemError(where, "loops", key, "holds a number that is not finite (or is "
                           "absurdly large): the solve did not converge")
    return arr


def check(result: Any, problem: WeftProblem, samples: int = SAMPLES,
          where: str = "result") -> CheckReport:
    """Check a result (a parsed result JSON) of a problem."""
    return check_state(problem, *loops_of(result, problem, where), samples, where)


def check_state(problem: WeftProblem, coeffs: np.ndarray, starts: np.ndarray,
                samples: int = SAMPLES, where: str = "result", places: bool = True
                ) -> CheckReport:
    """Check a state of a problem: loop coefficients (m, n, 2t+2) and starts (m, n, 2);
    ``places``: list where each new crossing is (the result's own check counts only). Python's
    cyclic garbage collector is paused meanwhile: the report's lists and dicts (some 33,000
    pairs of loops with new crossings at 100 x 100) hold no cycles, and the collections their
    allocations set off walked every live object (after a solve, CasADi's too): 0.3-0.4 s of
    a 100 x 100 check's 0.07 s of building them."""
    with _collector_paused():
        return _check_state(problem, coeffs, starts, samples, where, places)


@contextmanager
def _collector_paused() -> Iterator[None]:
    """Python's cyclic garbage collector off inside (as it was, after)."""
    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def _check_state(problem: WeftProblem, coeffs: np.ndarray, starts: np.ndarray,
                 samples: int, where: str, places: bool) -> CheckReport:
    """:func:`check_state` (the collector paused)."""
    curves = Curves.of(coeffs, starts, problem.L)
    grid = Grid(problem.courses, problem.wales, problem.L, samples)
    radius = problem.yarn.radius if problem.yarn is not None else None
    fab = NaturalFabric.of(problem, radius if radius is not None else problem.L / 100)
    found = find_crossings(curves, grid, ordered=places)     # the order only shows in places
    verdict = judge(fab, found, problem.courses, problem.wales)
    n = problem.wales
    report = CheckReport(problem.name, radius, _new(verdict, found, n, places),
                         _lost(verdict.lost_pairs, found.counts(), fab, problem), [], 0, None,
                         samples=crossing_samples(samples))
    if radius is None:
        return report
    zones = designed_zones(fab, curves, grid, found, verdict.new)
    try:
        pairs, grid = checked_pairs(fab, curves, problem.courses, problem.wales, zones,
                                    samples, CHECK_ROWS)
    except TooLarge as err:
        per_loop = check_samples(problem.L, radius, samples)
        raise ProblemError(where, "yarn", "radius", too_large(err.rows, radius, per_loop)
                           ) from None
    report.gap_samples = grid.per_loop
    if not len(pairs):
        return report
    limit = 2 * radius * (1 - GAP_TOL)
    below = pairs.gap < limit
    short = short_of(pairs)
    report.n_short = int(short.sum())
    report.short_gaps = _shortest(pairs.select(short), curves, n)
    interlock = pairs.required <= 0.0
    free = pairs.required >= 2 * radius
    report.below_2r = int(below.sum())
    report.thick_below_2r = int(np.sum(below & ~short & ~free & ~interlock))
    report.interlock_below_2r = int(np.sum(below & interlock))
    report.smallest_gap = float(pairs.gap[free].min()) if free.any() else None
    return report


def _new(verdict: Verdict, found: Crossings, n: int, places: bool = True
         ) -> list[dict[str, Any]]:
    """Each pair of loops with new crossings: its loops, its crossings now and in the natural
    fabric, and (``places``) where they are. The crossings are grouped once by their loop
    keys: a scan of all crossings per pair took 12 s on the 100 x 100 pull's 32,667 pairs."""
    if not verdict.new:
        return []
    big = int(found.kB.max()) + 1
    key = found.kA.astype(np.int64) * big + found.kB
    order = np.argsort(key, kind="stable")
    keys, first, count = np.unique(key[order], return_index=True, return_counts=True)
    xy = np.round(found.xy[order], 6).tolist() if places else []
    pairs = sorted(verdict.new.items())
    ka, kb, extra = (np.array(v, dtype=np.int64)
                     for v in zip(*((a, b, e) for (a, b), e in pairs)))
    group = np.searchsorted(keys, ka * big + kb)
    # read as Python ints at once: per pair, numpy scalars took 1.5 s of a 100 x 100 check
    counts, starts = count[group].tolist(), first[group].tolist()
    return [{"loops": [la, lb], "count": c, "natural": c - e,
             "where": xy[f:f + c] if places else []}
            for la, lb, c, e, f in zip(_loops(ka, n), _loops(kb, n), counts, extra.tolist(),
                                       starts)]


def _shortest(short: Pairs, curves: Curves, n: int) -> list[dict[str, Any]]:
    """The ``LISTED`` shortest gaps (relative to their requirement), shortest first: loops,
    material points, gap, requirement and the midpoint of the two centreline points."""
    order = np.argsort(short.gap / np.maximum(short.required, 1e-300), kind="stable")[:LISTED]
    s = short.select(order)
    pts = 0.5 * (curves.points(s.kA, s.sA) + curves.points(s.kB, s.sB))
    return [{"loops": [_loop(a, n), _loop(b, n)], "s": [float(sa), float(sb)],
             "gap": float(g), "required": float(r), "point": p.tolist()}
            for a, sa, b, sb, g, r, p in zip(s.kA, s.sA, s.kB, s.sB, s.gap, s.required, pts)]


def _lost(lost: dict[tuple[int, int], int], counts: dict[tuple[int, int], int],
          fab: NaturalFabric, problem: WeftProblem) -> list[dict[str, Any]]:
    """Each pair of loops with designed crossings lost (crossings.judge: fewer than the
    natural count, slides into a neighbouring loop not counted): its loops, its crossings now,
    in the natural fabric and lost, and whether a loop of it is on the fabric's edge (first or
    last course or wale: there a course's yarn ends, or no course lies below or above)."""
    n, m = problem.wales, problem.courses

    def edge(k: int) -> bool:
        return k // n in (0, m - 1) or k % n in (0, n - 1)

    return [{"loops": [_loop(a, n), _loop(b, n)], "count": counts.get((a, b), 0),
             "natural": fab.crossings((b // n - a // n, b % n - a % n)), "lost": v,
             "edge": edge(a) or edge(b)}
            for (a, b), v in sorted(lost.items())]


def _loop(k: int, n: int) -> list[int]:
    return [int(k // n) + 1, int(k % n) + 1]


def _loops(k: np.ndarray, n: int) -> list[list[int]]:
    """:func:`_loop` of many loop indices at once."""
    return np.stack([k // n + 1, k % n + 1], axis=1).tolist()


def own_check(problem: WeftProblem, coeffs: np.ndarray, starts: np.ndarray
              ) -> tuple[CheckReport | None, dict[str, Any]]:
    """The check every weft result carries (``WeftResult.checked``): the report and its JSON
    block, or None and a block saying why it was not made (a gap search too large to finish,
    or loops that are not finite), never an exception."""
    if not (np.all(np.isfinite(coeffs)) and np.all(np.isfinite(starts))):
        return None, {"ok": None, "verdict": "not checked: the loops are not finite"}
    try:
        report = check_state(problem, np.asarray(coeffs), np.asarray(starts), places=False)
    except ProblemError as err:
        return None, {"ok": None, "verdict": f"not checked: {err.message}"}
    return report, report.block()


# -- the 3-D model (docs/weft3d.md, "Check") ---------------------------------------------

@dataclass
class SpatialCheckReport:
    """``knit-nlp check`` of a 3-D result: the independent check over all pairs of yarn
    pieces (``model.spatial.proximity``), with the CheckReport's ``ok``, ``line`` and ``save``."""

    problem: str
    report: ProximityReport
    unit: str

    @property
    def ok(self) -> bool:
        return self.report.ok

    def line(self) -> str:
        return f"{self.problem}: {self.report.verdict(self.unit)}"

    def to_json(self) -> dict[str, Any]:
        return {"problem": self.problem, **self.report.block(self.unit)}

    def save(self, out_dir: Path | str, result_path: Path | str | None = None) -> list[Path]:
        """``<result stem>.check.json`` in ``out_dir``, as :meth:`CheckReport.save`."""
        stem = (self.problem if result_path is None
                else Path(result_path).name.removesuffix(".json"))
        return [write_json(Path(out_dir) / f"{stem}.check.json", self.to_json())]


def spatial_own_check(problem: WeftProblem, centrelines: np.ndarray) -> dict[str, Any]:
    """The ``check`` block every 3-D result carries (``WeftResult.checked``)."""
    if not np.all(np.isfinite(centrelines)):
        return {"model": "3d", "ok": None, "verdict": "not checked: the loops are not finite"}
    return spatial_state(problem, centrelines).block(problem.units.length)


def spatial_loops(result: Any, problem: WeftProblem, where: str = "result",
                  samples: int = SAMPLES) -> np.ndarray:
    """A 3-D result JSON's loops rebuilt (coefficients, ``elevations``, course starts with
    ``course_starts_z``: eq. S2, loops chained) as sampled centrelines (m, n, S, 3)."""
    coeffs, _ = loops_of(result, problem, where)
    loops = (result.get("equilibrium", result) if "loops" not in result else result)["loops"]
    m, n, q = problem.courses, problem.wales, problem.yarn.elevation_modes
    if "elevations" not in loops or "course_starts_z" not in loops:
        raise ProblemError(where, "loops", "elevations", "missing: a 3-D result written before "
                           "the 3-D check (solve it again)")
    elev = _array(loops["elevations"], (m, n, n_coeffs(q)), where, "elevations")
    course = np.concatenate([_array(loops["course_starts"], (m, 2), where, "course_starts"),
                             _array(loops["course_starts_z"], (m,), where,
                                    "course_starts_z")[:, None]], axis=1)
    A, B = coeffs.reshape(m * n, -1), elev.reshape(m * n, -1)
    S = spatial_samples(problem, samples)
    s = np.linspace(0.0, problem.L, S)
    d = positions3d(A, B, s, problem.L, problem.t, q).reshape(m, n, S, 3)
    starts = np.concatenate([course[:, None], d[:, :-1, -1]], axis=1).cumsum(axis=1)
    return d + starts[:, :, None, :]


def check_spatial(result: Any, problem: WeftProblem, samples: int = SAMPLES,
                  where: str = "result") -> SpatialCheckReport:
    """``knit-nlp check`` of a 3-D result JSON (``samples``: at most this many per loop)."""
    report = spatial_state(problem, spatial_loops(result, problem, where, samples))
    return SpatialCheckReport(problem.name, report, problem.units.length)


def load_result_json(path: Path) -> Any:
    """A result JSON file (any JSON value; ``check`` judges its shape)."""
    try:
        return json.loads(read_regular_file(path, MAX_RESULT_BYTES),
                          parse_constant=_reject_constant)
    except ProblemError:
        raise
    except (OSError, ValueError, RecursionError) as err:
        raise ProblemError(path, "", "", f"cannot read it as JSON ({shown(err, 120)})") from None


def _reject_constant(name: str) -> float:
    """JSON's NaN and Infinity are read as NaN, so the shape check names them."""
    return math.nan
