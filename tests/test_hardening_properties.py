"""Property-based hostile input (hypothesis): problem documents built from the real keys of both
models, with wrong types, out-of-range, huge and non-finite values, unknown and missing keys,
are either a valid problem or exactly one ProblemError with a one-line printable message; the
command line's argument handling exits 0 or 2 with one line, never a traceback. Parse only:
no solver runs here (the CLI's solve entry points are replaced by a stub)."""
import copy
import datetime
from dataclasses import replace
import math
from pathlib import Path
from unittest import mock

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from knit_nlp.cli import main
from knit_nlp.errors import ProblemError
from knit_nlp.jacquard.problem import parse_problem as parse_jacquard
from knit_nlp.weft.model.problem import parse_problem as parse_weft

SETTINGS = settings(max_examples=150, deadline=3000, derandomize=False,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

WEFT_BASE = {
    "name": "w", "description": "d", "model": "weft",
    "fabric": {"courses": 2, "wales": 3},
    "loop": {"preset": "jersey", "length": 10.0, "harmonics": 3, "quadrature_nodes": 8},
    "material": {"k_a": 1.0, "k_b": 0.01, "R_f": 1.0},
    "clamp": [{"loop": [1, 1], "point": "start", "position": [0.0, 0.0], "fix": ["x", "y"]},
              {"loop": [2, 3], "point": "H", "displacement": [1.0, 0.5], "angle": 0.1}],
    "rigid_clamp": [{"points": [{"loop": [1, 2], "point": "start"}], "translation": [0.1, 0.0],
                     "rotation": 0.01, "centre": [1.0, 1.0]}],
    "load": [{"loop": [2, 2], "point": "E", "force": [0.1, 0.0], "moment": 0.01}],
    "reduction": {"representative_courses": [1, 2], "representative_wales": [1, 3]},
    "solver": {"tol": 1e-8, "max_iter": 100, "continuation": 2, "max_time": 10.0},
}

JACQUARD_BASE = {
    "name": "j", "description": "d", "model": "jacquard",
    "fabric": {"wales": 4, "courses": 4, "dz": 10.0, "dh": 8.0, "mass": 1.0, "damping": 0.5,
               "dt": 0.05, "lambda_max": 1.1, "zigzag": "right", "boundary": "fixed",
               "fixed_edges": ["bottom", "top"], "loop_width_stiffness": 0.0},
    "ground": {"stiffness": 1.0, "pretension": 0.9},
    "fall_plate": {"design": "##++\n##++\n++##\n++##", "span": {"thick": 3, "thin": 2, "net": 1},
                   "stiffness": {"longitudinal": 0.5, "thick": 1.0, "thin": 0.7},
                   "pretension": {"longitudinal": 0.9, "thick": 0.9, "thin": 0.9}},
    "inlay": {"design_file": "inlay.txt"},
    "solver": {"method": "static", "tol": 1e-10, "max_iter": 50, "hessian": "exact",
               "move_tol": 1e-10, "max_steps": 1000, "regularization": 1e-8, "max_time": 5.0},
}

EXTRA_KEYS = ["design_image", "natural_coefficients", "course_spacing", "points", "colour",
              "\x1b[2J", "", "nul\x00key", "fix", "angle"]

NASTY_FLOATS = st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 1e-308, 0.0,
                                -0.0, 1e9, 1e10, -1.0, 0.5, 2.0, 1.1, 1e-300])
NASTY_INTS = st.sampled_from([0, -1, 1, 2, 3, 4, 31, 64, 65, 1000, 10 ** 6, 10 ** 9, 10 ** 10,
                              2 ** 63, 10 ** 20, 10 ** 400, -(10 ** 400)])
TEXT = st.text(st.characters(codec="utf-8"), max_size=12) | st.sampled_from(
    ["", "start", "H", "x", "y", "thick", "../x", "/dev/zero", "a\x00b", "\x1b[2J", ".",
     "jersey", "straight", "explicit", "explicitt", "limited-memory", "fixed", "left", "top"])
BEYOND_FLOAT = st.sampled_from([10 ** 309, -(10 ** 309), 10 ** 400, 2 ** 1100, 10 ** 4000])
SCALARS = (NASTY_INTS | st.integers() | NASTY_FLOATS | st.floats(allow_nan=True) | st.booleans()
           | TEXT | st.just(datetime.date(2020, 1, 1)) | st.just(datetime.time(1, 2)))
VALUES = st.one_of(NASTY_INTS, BEYOND_FLOAT, NASTY_FLOATS, TEXT,
                   st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=4)
                                | st.dictionaries(st.sampled_from(EXTRA_KEYS + ["loop", "point"]),
                                                  inner, max_size=3), max_leaves=8))


def _tables(doc, prefix=()):
    """Every (path, table) of a document, arrays of tables included."""
    yield prefix, doc
    for key, value in doc.items():
        if isinstance(value, dict):
            yield from _tables(value, prefix + (key,))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for k, v in enumerate(value):
                yield from _tables(v, prefix + (key, k))


@st.composite
def mutated(draw, base):
    """The base document with a few keys set to nasty values, removed, or added."""
    doc = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 4))):
        tables = list(_tables(doc))
        _, table = tables[draw(st.integers(0, len(tables) - 1))]
        action = draw(st.sampled_from(["set", "set", "set", "delete", "add"]))
        if action == "add" or not table:
            table[draw(st.sampled_from(EXTRA_KEYS))] = draw(VALUES)
        elif action == "delete":
            del table[draw(st.sampled_from(sorted(table)))]
        else:
            key = draw(st.sampled_from(sorted(table)))
            old = table[key]
            if isinstance(old, list) and old and not isinstance(old[0], dict) and draw(st.booleans()):
                old[draw(st.integers(0, len(old) - 1))] = draw(VALUES)   # one entry of an array
            else:
                table[key] = draw(VALUES)
    return doc


def _check_outcome(parse):
    try:
        parse()
    except ProblemError as err:
        text = str(err)
        assert "\n" not in text and text.isprintable(), repr(text)


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("jq")
    (d / "inlay.txt").write_text("+..+\n+..+\n.++.\n.++.\n")
    return d


def test_the_base_documents_are_valid(folder):
    assert parse_weft(copy.deepcopy(WEFT_BASE), "w.toml").courses == 2
    assert parse_jacquard(copy.deepcopy(JACQUARD_BASE), folder / "j.toml").wales == 4


@SETTINGS
@given(doc=mutated(WEFT_BASE))
def test_weft_documents_are_a_problem_or_one_problem_error(doc):
    _check_outcome(lambda: parse_weft(doc, "w.toml"))


@SETTINGS
@given(doc=mutated(JACQUARD_BASE))
def test_jacquard_documents_are_a_problem_or_one_problem_error(folder, doc):
    _check_outcome(lambda: parse_jacquard(doc, folder / "j.toml"))


TOKENS = st.sampled_from(["solve", "compare", "list", "--out", "--continuation", "--reduced",
                          "--full", "--warm-from-reduced", "--solver", "--svg", "static",
                          "explicit", "0", "-3", "5", "1e3", "wada_fig7", "jacquard_stripe",
                          "nonexistent", "--out=/proc/version/x", "--continuation=-1",
                          "--out=/sys/x", "x" * 300, "a\x1b[2Jb", "--", "-"])
ANY_TEXT = st.text(st.characters(codec="utf-8", exclude_characters="\x00"), max_size=8)
OPTION_VALUES = {
    "--out": st.sampled_from(["", "/proc/version/x", "/sys/knit_nlp_x", "x" * 300, "a\x1b[2Jb",
                              "out", "p.toml"]),
    "--continuation": st.sampled_from(["0", "-3", "1", "1001", "1e3", "x", ""]),
    "--solver": st.sampled_from(["static", "explicit", "explicitt", ""]),
}


@st.composite
def structured_argv(draw):
    """A command, a problem and a few options with hostile values."""
    argv = [draw(st.sampled_from(["solve", "compare", "list"])),
            draw(st.sampled_from(["wada_fig7", "jacquard_stripe", "nonexistent"]) | ANY_TEXT)]
    for _ in range(draw(st.integers(0, 3))):
        opt = draw(st.sampled_from(["--out", "--out", "--continuation", "--solver", "--reduced",
                                    "--full", "--warm-from-reduced", "--svg"]))
        if opt in OPTION_VALUES:
            value = draw(OPTION_VALUES[opt] | ANY_TEXT)
            argv += [f"{opt}={value}"] if draw(st.booleans()) else [opt, value]
        else:
            argv.append(opt)
    return argv


ARGV = structured_argv() | st.lists(TOKENS | ANY_TEXT, max_size=7)


@settings(max_examples=200, deadline=3000,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(argv=ARGV)
def test_cli_arguments_exit_0_or_2_with_one_line(tmp_path, capsys, argv):
    """Solving is stubbed out (returns 0): what is tested is everything before it."""
    with mock.patch.dict("knit_nlp.api.MODELS", _STUBS), \
            mock.patch("knit_nlp.cli.prepare_out", side_effect=_no_writes(tmp_path)):
        code = main(argv)
    out, err = capsys.readouterr()
    assert code in (0, 2)
    if code == 2:
        assert len(err.strip().splitlines()) == 1 and err.strip().isprintable(), repr(err)


class _Solved:
    """What a stubbed solve or compare returns: success, and nothing saved."""

    success = True

    def save(self, out, **options):
        return []


def _stub(model):
    from knit_nlp.api import MODELS
    real = MODELS[model]
    return replace(real, solve=lambda problem, **options: _Solved(),
                   compare=None if real.compare is None else lambda problem, **options: _Solved(),
                   summary=lambda result, paths: "solved",
                   compare_summary=lambda cmp, paths: "compared")


_STUBS = {model: _stub(model) for model in ("weft", "jacquard")}


def _no_writes(tmp_path: Path):
    """prepare_out's checks without creating folders outside tmp_path."""
    from knit_nlp.cli import prepare_out

    def checked(out, name, kinds):
        if not out or out.startswith(("/proc", "/sys")) or "\0" in out:
            return prepare_out(out, name, kinds)
        return prepare_out(str(tmp_path / "o" / out.lstrip("/")), name, kinds)
    return checked
