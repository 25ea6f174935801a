"""Property-based hostile input (hypothesis) for ``control``, ``fit``, ``overlay`` and ``sweep``,
through ``main([...])`` in process: mutated control files, random observation CSVs, random
bytes and JSON for overlay's result, NPZ and photograph, random ``--vary``/``--path`` axes. The
contract, as for ``solve``: exit code 0, 1 or 2; on 2 exactly one printable stderr line starting
``knit-nlp:`` and nothing under ``--out``; never a traceback. No solver runs: each command's
solve is replaced by a stub that raises ``Accepted`` (the input got past every check)."""
from __future__ import annotations

import copy
import io
import json
import math
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from knit_nlp.cli import main
from test_command_contract import MATCHES, png, tiny
from test_hardening_properties import VALUES, mutated

EXAMPLES = int(os.environ.get("KNIT_FUZZ_EXAMPLES", "40"))    # more for a long hunt
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, derandomize=False,
                    suppress_health_check=[HealthCheck.too_slow,
                                           HealthCheck.function_scoped_fixture])


def rarely(strategy: st.SearchStrategy) -> st.SearchStrategy:
    """None three times in four: a hostile value for an option most examples leave alone, so
    that most get past it to the input under test."""
    return st.integers(0, 3).flatmap(lambda k: strategy if k == 0 else st.none())


class Accepted(Exception):
    """Raised by the stubbed solves: the input passed every check."""


def _accepted(*args: Any, **kwargs: Any) -> None:
    raise Accepted


@pytest.fixture(autouse=True)
def no_solves(monkeypatch):
    """The solves raise Accepted; a sweep still opens its (local) executor, which starts no
    process before a point is submitted, so its --workers is checked end to end."""
    from knit_nlp.studies import runner
    from knit_nlp.weft.inverse import run
    for name in ("control", "fit", "overlay"):
        monkeypatch.setattr(run, name, _accepted)
    monkeypatch.setattr(runner, "run_study", _accepted)


@contextmanager
def scratch() -> Iterator[Path]:
    """A fresh folder per example (hypothesis reuses the test's tmp_path)."""
    with tempfile.TemporaryDirectory() as folder:
        yield Path(folder)


def check_contract(argv: list[str], out: Path, capsys) -> None:
    """Run the command: accepted (the stub), or exit 0/1, or exit 2 with one line and no
    ``--out``."""
    capsys.readouterr()
    try:
        code = main([*argv, "--out", str(out)])
    except Accepted:
        return
    err = capsys.readouterr().err
    assert code in (0, 1, 2), code
    if code == 2:
        assert err.startswith("knit-nlp: ") and err.count("\n") == 1, repr(err)
        assert err.strip().isprintable(), repr(err)
        assert not out.exists(), list(out.rglob("*"))


# -- TOML text of a (mutated) document -----------------------------------------------------------
def toml_value(value: Any) -> str:
    """Inline TOML for plain data; values TOML cannot hold (integers beyond 64 bits, a NUL)
    are written anyway and make the file malformed, which is also hostile input."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return "nan" if math.isnan(value) else repr(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {toml_value(v)}"
                               for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return value.isoformat()                 # date, time


def toml_text(doc: dict[str, Any]) -> str:
    return "\n".join(f"{json.dumps(str(k))} = {toml_value(v)}" for k, v in doc.items()) + "\n"


CONTROL_BASE = {
    "name": "ctl", "model": "weft",
    "fabric": {"courses": 2, "wales": 3},
    "loop": {"harmonics": 2, "quadrature_nodes": 4},
    "clamp": [{"loop": [1, 1], "point": "start", "position": [0.0, 0.0]},
              {"loop": [2, 3], "point": "H", "displacement": [0.0, 0.0], "actuated": True,
               "bounds": [[0.0, 10.0], [0.0, 10.0]]}],
    "rigid_clamp": [{"points": [{"loop": [1, 3], "point": "start"}], "translation": [0.0, 0.0],
                     "actuated": True}],
    "goal": [{"loop": [2, 2], "point": "H", "displacement": [0.5, 0.0], "weight": 1.0,
              "fix": ["x", "y"]}],
    "opening": [{"points": [{"loop": [1, 1], "point": "B"}, {"loop": [1, 1], "point": "R"}],
                 "at_least": 1.0}],
    "control": {"travel_weight": 0.1},
}


def test_the_control_base_is_accepted(tmp_path, capsys):
    path = tmp_path / "ctl.toml"
    path.write_text(toml_text(CONTROL_BASE))
    with pytest.raises(Accepted):
        main(["control", str(path), "--out", str(tmp_path / "o")])


@SETTINGS
@given(doc=mutated(CONTROL_BASE))
def test_hostile_control_files_keep_the_contract(capsys, doc):
    with scratch() as folder:
        path = folder / "ctl.toml"
        path.write_text(toml_text(doc), encoding="utf-8", errors="surrogatepass")
        check_contract(["control", str(path)], folder / "o", capsys)


# -- fit: observation CSVs and --params -----------------------------------------------------------
CELLS = st.one_of(st.sampled_from(["obs", "other", "1", "2", "3", "0", "-1", "H", "start", "end",
                                   "B", "0.5", "nan", "inf", "1e999", "", " ", '"', '"a,b"',
                                   "#", "\x00", "9" * 40]),
                  st.floats(allow_nan=True, allow_infinity=True).map(repr),
                  st.integers(-10 ** 20, 10 ** 20).map(str),
                  st.text(max_size=8))
HEADER = "case,course,wale,point,x,y"


@st.composite
def observation_text(draw) -> bytes:
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=200))
    header = draw(st.sampled_from([HEADER, HEADER, HEADER, "case,course,wale,x,y", "",
                                   "# made by hand\n" + HEADER]))
    rows = draw(st.lists(st.lists(CELLS, min_size=5, max_size=7), max_size=6))
    lines = [header, *(",".join(r) for r in rows)]
    if draw(st.booleans()):
        lines.append("obs,2,2,H,4.0,4.0")
    return "\n".join(lines).encode("utf-8", "surrogatepass")


PARAMS = st.lists(st.sampled_from(["k_a", "k_b", "R_f", "k_c", ""]), max_size=4, unique=True)


@SETTINGS
@given(text=observation_text(), params=PARAMS,
       k_b=st.sampled_from([0.01, 0.01, 0.0, 1e-300, 1e9]), name=rarely(st.text(max_size=8)))
def test_hostile_observations_and_params_keep_the_contract(capsys, text, params, k_b, name):
    with scratch() as folder:
        problem = tiny(folder, k_b=k_b)
        data = folder / "d.csv"
        data.write_bytes(text)
        argv = ["fit", str(problem), "--observations", str(data)]
        argv += ["--params", *params] if params else []
        argv += ["--name", name] if name is not None else []
        check_contract(argv, folder / "o", capsys)


# -- overlay: result JSON, NPZ, photograph, matches ----------------------------------------------
@pytest.fixture(scope="module")
def solved(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("solved")
    problem = tiny(folder)
    assert main(["solve", str(problem), "--out", str(folder)]) == 0
    (folder / "img.png").write_bytes(png(30, 20))
    return folder


JSON = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=6),
                    lambda inner: st.lists(inner, max_size=3)
                    | st.dictionaries(st.sampled_from(["problem", "source", "file", "success",
                                                       "x"]), inner, max_size=3),
                    max_leaves=6)


@st.composite
def result_json(draw, real: bytes) -> bytes:
    kind = draw(st.integers(0, 5))
    if kind <= 2:
        return real
    if kind == 3:
        return draw(st.binary(max_size=100))
    if kind == 4:
        return json.dumps(draw(JSON)).encode()
    doc = json.loads(real)
    for key in draw(st.lists(st.sampled_from(sorted(doc) + ["source"]), max_size=3)):
        doc[key] = draw(JSON)
    return json.dumps(doc).encode()


def _filled(shape: tuple, fill: float, dtype) -> np.ndarray:
    """An array of one value; NaN and inf cast to int on purpose (hostile data), quietly."""
    with np.errstate(invalid="ignore", over="ignore"):
        return np.full(shape, fill).astype(dtype)


ARRAY = st.builds(_filled,
                  st.lists(st.integers(0, 4), max_size=4).map(tuple),
                  st.sampled_from([0.0, 1.0, -1.0, np.nan, np.inf, 1e308]),
                  st.sampled_from([float, int, complex, bool, "U1"]))


@st.composite
def result_npz(draw, arrays: dict[str, np.ndarray]) -> bytes:
    kind = draw(st.integers(0, 5))
    if kind == 1:
        return draw(st.binary(max_size=100))
    changed = copy.copy(arrays)
    kind = 0 if kind > 3 else kind
    if kind >= 2:
        for key in draw(st.lists(st.sampled_from(sorted(arrays)), min_size=1, max_size=2)):
            if draw(st.booleans()):
                changed.pop(key, None)
            else:
                changed[key] = draw(ARRAY) if kind == 2 else np.swapaxes(
                    arrays[key], 0, -1) if arrays[key].ndim else arrays[key]
    buffer = io.BytesIO()
    np.savez(buffer, **changed)
    return buffer.getvalue()


IMAGES = st.one_of(st.just(None), st.just(None), st.just(None), st.binary(max_size=100),
                   st.builds(png, st.integers(0, 64), st.integers(0, 64)),
                   st.builds(png, st.integers(26_000_000, 2 ** 31 - 1), st.integers(1, 64)),
                   st.builds(png, st.integers(6000, 70000), st.integers(6000, 70000)))
MATCH = st.one_of(st.sampled_from(MATCHES[1::2] + ["1,1,H=1,1", "3,3,H=1,1", "1,1,Z=1,1",
                                                   "1,1,0.5=nan,1", "1,1,H=inf,1", "1,1,H",
                                                   "a,b,c=d,e", "1,1,start=1,1,1"]),
                  st.text(max_size=12))


@SETTINGS
@given(data=st.data())
def test_hostile_overlay_inputs_keep_the_contract(capsys, solved, data):
    with np.load(solved / "obs.full.npz") as npz:
        arrays = dict(npz)
    with scratch() as folder:
        result = folder / "obs.full.json"
        result.write_bytes(data.draw(result_json((solved / "obs.full.json").read_bytes())))
        (folder / "obs.full.npz").write_bytes(data.draw(result_npz(arrays)))
        image = data.draw(IMAGES)
        picture = folder / "img.png"
        picture.write_bytes((solved / "img.png").read_bytes() if image is None else image)
        argv = ["overlay", str(result), str(picture)]
        for match in data.draw(st.lists(MATCH, max_size=3)):
            argv += ["--match", match]
        problem = data.draw(st.sampled_from([None, "same", "bigger", "missing"]))
        if problem == "same":
            argv += ["--problem", str(solved / "obs.toml")]
        elif problem is not None:
            argv += ["--problem", str(tiny(folder, "other", courses=3) if problem == "bigger"
                                      else folder / "none.toml")]
        check_contract(argv, folder / "o", capsys)


# -- sweep: --vary / --path axes and --workers ---------------------------------------------------
KEYS = st.sampled_from(["material.k_b", "material.k_a", "material.R_f", "clamp[2].displacement",
                        "clamp[2].displacement.x", "clamp[1].position", "clamp[3].position.x",
                        "load[1].force", "solver.tol", "fabric.courses", "material.k_x", "x",
                        "material..k_b", "clamp[0].position", "clamp[99999999999].angle"])
ENDS = st.one_of(st.sampled_from(["0", "1", "-1", "0.01", "1e999", "-1e999", "1e308", "-1e308",
                                  "nan", "inf", "1,2", "1,2,3", "0.5,0", "", "1e9", "1e10",
                                  "0x10", "1_0"]),
                 st.floats(allow_nan=True, allow_infinity=True).map(repr),
                 st.text(max_size=5))
COUNTS = st.sampled_from(["1", "2", "3", "2", "3", "0", "100001", "1" + "0" * 30, "-1", "x", ""])


@st.composite
def axis(draw) -> str:
    if draw(st.integers(0, 5)) == 0:
        return draw(st.text(max_size=20))
    ends = [draw(st.sampled_from(["0.01", "0.5", "1", "0.2,0.1"]) | ENDS) for _ in range(2)]
    return f"{draw(KEYS)}={ends[0]}:{ends[1]}:{draw(COUNTS)}"


@pytest.mark.filterwarnings("error::RuntimeWarning")          # 1e999 made numpy warn
@SETTINGS
@given(vary=st.lists(axis(), max_size=3), path=rarely(st.lists(axis(), max_size=2)),
       workers=rarely(st.integers(-2, 10 ** 10).map(str) | st.text(max_size=4)),
       name=rarely(st.text(max_size=8)))
def test_hostile_sweep_axes_keep_the_contract(capsys, solved, vary, path, workers, name):
    argv = ["sweep", str(solved / "obs.toml")]
    for flag, axes in (("--vary", vary), ("--path", path)):
        for a in axes or ():
            argv.append(f"{flag}={a}")
    argv += [] if workers is None else [f"--workers={workers}"]
    argv += [] if name is None else [f"--name={name}"]
    with scratch() as folder:
        check_contract(argv, folder / "o", capsys)
