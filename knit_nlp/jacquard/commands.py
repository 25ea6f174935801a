"""The jacquard model's part of the command line: its ``knit-nlp solve`` flags and how they
become solve and save options (read through ``knit_nlp.api.MODELS``)."""
from __future__ import annotations

from argparse import Namespace
from pathlib import Path
from typing import Any

from .api import SOLVERS
from .problem import JacquardProblem

# (names, argparse keywords, group)
FLAGS = (
    (("--solver",), {"choices": list(SOLVERS), "default": None,
                     "help": "override [solver] method"}, None),
    (("--svg",), {"action": "store_true", "help": "also write an SVG picture"}, None),
)


def document(doc: dict[str, Any], path: Path) -> dict[str, Any]:
    """The document ``knit-nlp solve`` solves: the file's own."""
    return doc


def solve_options(args: Namespace, problem: JacquardProblem, path: Path) -> dict[str, Any]:
    return {"solver": args.solver}


def save_options(args: Namespace) -> dict[str, Any]:
    return {"svg": True} if args.svg else {}
