"""What a solved weft fabric should not look like, named after the solve (issue 41, item 2).

The paper's model lets its crossing springs (eqs. 6-8) stretch without bound and knows nothing
of which side of a course its neighbours lie on, so an answer IPOPT calls converged can be a
fabric no yarn makes. Three findings, each from the loops' coefficients and start points:

- **a spring stretched beyond a loop length**: |(E − B) − B₀E₀| or |(H − R) − R₀H₀| > L for
  the spring pairs of loops (i + 1, j) and (i, j) (the vectors of eq. 8);
- **a course folded onto another**: the chord midpoint of loop (i + 1, j) lies on the wrong side
  of loop (i, j)'s chord (its offset along the chord's left normal, c in the natural fabric,
  is negative);
- **a loop turned inside out**: the signed area enclosed by a loop's centreline and its chord
  (the shoelace formula) has the opposite sign to the natural loop's (and at least
  ``INSIDE_OUT`` of its size: a loop pulled flat is not inside out).

:func:`summary_line` is the one line ``knit-nlp solve`` prints (output/summary.py).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..model.quadrature import positions

if TYPE_CHECKING:
    from ..model.problem import WeftProblem
    from .results import WeftResult

SAMPLES = 64           # points per loop for the signed area (the trapezoid rule's error ~1/S²)
INSIDE_OUT = 0.1       # |area| as a fraction of the natural loop's, with the opposite sign
SHOWN = 3              # places named per finding


@dataclass
class Findings:
    """The implausible places of one solved fabric (1-based loops)."""

    springs: list[tuple[float, tuple[int, int], str]] = field(default_factory=list)
    folds: list[tuple[int, int]] = field(default_factory=list)       # (upper course, wale)
    inside_out: list[tuple[int, int]] = field(default_factory=list)

    def __bool__(self) -> bool:
        return bool(self.springs or self.folds or self.inside_out)


def findings(pr: "WeftProblem", coefficients: np.ndarray, starts: np.ndarray) -> Findings:
    """The findings of the fabric with these loop coefficients (m, n, 2t+2) and starts (m, n, 2)."""
    return Findings(_stretched(pr, coefficients, starts), _folded(pr, coefficients, starts),
                    _inside_out(pr, coefficients))


def _points(pr: "WeftProblem", coefficients: np.ndarray, starts: np.ndarray,
            s: list[float]) -> np.ndarray:
    """Positions (m, n, len(s), 2) of the material points s of every loop."""
    m, n, k = coefficients.shape
    rel = positions(coefficients.reshape(-1, k), s, pr.L, pr.t).reshape(m, n, len(s), 2)
    return rel + starts[:, :, None, :]


def _stretched(pr: "WeftProblem", coefficients: np.ndarray, starts: np.ndarray
               ) -> list[tuple[float, tuple[int, int], str]]:
    """(stretch / L, upper loop, "B-E" or "R-H") of every spring pair stretched beyond L."""
    c = pr.crossings
    if c is None or pr.courses < 2:
        return []
    p = _points(pr, coefficients, starts, [c.s[x] for x in "BERH"])
    out = []
    for up, low, rest in ((0, 1, c.rest_left), (2, 3, c.rest_right)):
        stretch = np.linalg.norm(p[:-1, :, low] - p[1:, :, up] - rest, axis=-1) / pr.L
        for i, j in zip(*np.nonzero(stretch > 1.0)):
            out.append((float(stretch[i, j]), (int(i) + 2, int(j) + 1), "BERH"[up] + "-" +
                        "BERH"[low]))
    return sorted(out, reverse=True)


def _folded(pr: "WeftProblem", coefficients: np.ndarray, starts: np.ndarray
            ) -> list[tuple[int, int]]:
    """(upper course, wale) where course i + 1's chord midpoint lies below course i's chord."""
    if pr.courses < 2:
        return []
    ends = _points(pr, coefficients, starts, [pr.L])[:, :, 0]
    chord, mid = ends - starts, (ends + starts) / 2
    length = np.linalg.norm(chord, axis=-1)
    normal = np.stack([-chord[..., 1], chord[..., 0]], axis=-1) / np.maximum(length, 1e-300)[..., None]
    offset = np.sum((mid[1:] - mid[:-1]) * normal[:-1], axis=-1)
    folded = (offset < 0) & (length[:-1] > 1e-3 * pr.L)
    return [(int(i) + 2, int(j) + 1) for i, j in zip(*np.nonzero(folded))]


def _inside_out(pr: "WeftProblem", coefficients: np.ndarray) -> list[tuple[int, int]]:
    """Loops whose centreline-and-chord area has turned sign against the natural loop's."""
    s = list(np.linspace(0.0, pr.L, SAMPLES))
    m, n, k = coefficients.shape
    area = _signed_area(positions(coefficients.reshape(-1, k), s, pr.L, pr.t)).reshape(m, n)
    natural = float(_signed_area(positions(pr.natural.coeffs[None], s, pr.L, pr.t))[0])
    flipped = (area * natural < 0) & (np.abs(area) > INSIDE_OUT * abs(natural))
    return [(int(i) + 1, int(j) + 1) for i, j in zip(*np.nonzero(flipped))]


def _signed_area(xy: np.ndarray) -> np.ndarray:
    """Shoelace area of each closed polygon (N, S, 2) (closed by its chord), > 0 anticlockwise."""
    x, y = xy[..., 0], xy[..., 1]
    return 0.5 * np.sum(x * np.roll(y, -1, axis=-1) - np.roll(x, -1, axis=-1) * y, axis=-1)


def describe(found: Findings) -> str:
    """The findings in words, ';'-separated; '' for none."""
    parts = []
    if found.springs:
        top = ", ".join(f"{pair} of loops {list(up)}-{[up[0] - 1, up[1]]} {x:.3g} L"
                        for x, up, pair in found.springs[:SHOWN])
        parts.append(f"{len(found.springs)} crossing spring{_s(found.springs)} stretched beyond "
                     f"a loop length L ({top}{', ...' * (len(found.springs) > SHOWN)})")
    if found.folds:
        top = ", ".join(f"course {i} onto {i - 1} at wale {j}" for i, j in found.folds[:SHOWN])
        parts.append(f"{len(found.folds)} place{_s(found.folds)} where a course is folded onto "
                     f"the one below ({top}{', ...' * (len(found.folds) > SHOWN)})")
    if found.inside_out:
        top = ", ".join(str(list(x)) for x in found.inside_out[:SHOWN])
        parts.append(f"{len(found.inside_out)} loop{_s(found.inside_out)} turned inside out "
                     f"({top}{', ...' * (len(found.inside_out) > SHOWN)})")
    return "; ".join(parts)


def _s(items: list) -> str:
    return "s" if len(items) != 1 else ""


def summary_line(r: "WeftResult") -> list[str]:
    """The summary's line on an implausible answer ([] for none, or for no finite answer)."""
    coefficients, starts = r.coefficients, r.starts
    if not (np.isfinite(coefficients).all() and np.isfinite(starts).all()):
        return []
    text = describe(findings(r.problem, coefficients, starts))
    return [f"  IMPLAUSIBLE: {text}"] if text else []
