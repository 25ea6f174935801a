"""The jacquard model's part of the command line: its ``knit-nlp solve`` flags and how they
become solve and save options (read through ``knit_nlp.api.MODELS``)."""
from __future__ import annotations

from argparse import Namespace
from pathlib import Path
from typing import Any

from ..errors import ArgumentError
from .api import SOLVERS
from .problem import JacquardProblem

# (names, argparse keywords, group)
FLAGS = (
    (("--solver",), {"choices": list(SOLVERS), "default": None,
                     "help": "override [solver] method"}, None),
    (("--svg",), {"action": "store_true", "help": "also write an SVG picture"}, None),
    (("--window",), {"type": int, "default": None, "metavar": "LOOPS",
                     "help": "draw at most LOOPS wales and courses from the bottom-left corner "
                             "(default: the whole fabric, up to 120 each way)"}, None),
)


def document(doc: dict[str, Any], path: Path) -> dict[str, Any]:
    """The document ``knit-nlp solve`` solves: the file's own."""
    return doc


def solve_options(args: Namespace, problem: JacquardProblem, path: Path) -> dict[str, Any]:
    return {"solver": args.solver}


def save_options(args: Namespace) -> dict[str, Any]:
    """``save`` keywords from the flags; ``--window`` below 1 is refused in one line."""
    if args.window is not None and args.window < 1:
        raise ArgumentError("--window", f"must be a whole number of loops >= 1; got "
                            f"{args.window}")
    return {**({"svg": True} if args.svg else {}),
            **({"window": args.window} if args.window is not None else {})}
