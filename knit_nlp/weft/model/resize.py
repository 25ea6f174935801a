"""Shipped pulls at another size: ``knit-nlp solve diagonal_pull --size 30x30``.

A shipped problem whose pull is one of the shared load cases (:mod:`.cases`, the functions the
benchmarks in ``scripts/`` build their pulls with) is rebuilt at courses × wales from that case:
its fabric resized and its clamps replaced by the case's at the new size, every other key of
the file kept. The pull scales as the case defines it: :func:`.cases.diagonal_pull` moves H of
loop (1, n) by eq. 28's stretch and turn of its chord from the pinned corner, and
:func:`.cases.course_pull` stretches the fabric by the same strain of its width. The resized
document is written as a problem file of its own (``knit_nlp.tomlio.toml_text``), so that the result's
recorded source is the fabric that was solved (``check`` and ``overlay`` read it).
"""
from __future__ import annotations

import re
from typing import Any, Callable

from ...errors import ArgumentError
from . import cases

MAX_SIDE = 1000          # courses or wales; the solve's own memory estimate refuses far less

# shipped problem name -> (courses, wales) -> the case's document at that size
SCALED: dict[str, Callable[[int, int], dict[str, Any]]] = {
    "diagonal_pull": lambda m, n: cases.diagonal_pull(n, m),
    "wada_fig7": lambda m, n: cases.diagonal_pull(n, m),
    "course_stretch": lambda m, n: cases.course_pull(n, 0.25, m),
}


def parse_size(text: str) -> tuple[int, int]:
    """``CxW`` (courses x wales, e.g. ``30x30``) or ``N`` for N x N."""
    match = re.fullmatch(r"\s*(\d{1,7})\s*(?:[xX×]\s*(\d{1,7}))?\s*", text)
    if not match:
        raise ArgumentError(f"--size {text}", "expected COURSESxWALES, e.g. 30x30, or one "
                            "number for a square fabric")
    m = int(match.group(1))
    n = int(match.group(2) or m)
    if not (1 <= m <= MAX_SIDE and 1 <= n <= MAX_SIDE) or n < 2:
        raise ArgumentError(f"--size {text}", f"courses must be in 1..{MAX_SIDE} and wales in "
                            f"2..{MAX_SIDE} (a pull needs two wales)")
    return m, n


def resized(doc: dict[str, Any], source: str, courses: int, wales: int) -> dict[str, Any]:
    """The problem document ``doc`` (read from ``source``) at ``courses`` × ``wales``: the
    fabric and clamps of its load case (:data:`SCALED`, found by the problem's name), every
    other key of the file kept; refused in one line for a problem that is not a scaled case."""
    name = str(doc.get("name", ""))
    case = SCALED.get(name)
    keys = set(doc) - {"name", "description", "model", "fabric", "clamp", "loop", "material",
                       "units", "solver"}
    if case is None or keys or doc.get("model", "weft") != "weft":
        raise ArgumentError(f"--size (problem {source})", f"resizes only the shipped pulls "
                            f"that are load cases: {', '.join(SCALED)}; edit the file's "
                            "[fabric] and clamps for another problem")
    scaled = case(courses, wales)
    out = {**doc, "name": scaled["name"], "clamp": scaled["clamp"],
           "fabric": {**doc.get("fabric", {}), **scaled["fabric"]}}
    out["description"] = (f"{name} resized to {courses} x {wales}, its pull scaled with it "
                          f"(knit-nlp solve {name} --size {courses}x{wales})")
    return out
