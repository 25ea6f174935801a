"""Result files: atomic under kill -9, deterministic, resumable past damage; packaging lookups."""
import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import tomllib
from fnmatch import fnmatch
from pathlib import Path

import numpy as np
import pytest

from knit_nlp.cli import main

ROOT = Path(__file__).resolve().parent.parent

WRITER = textwrap.dedent("""
    import sys
    from pathlib import Path
    import numpy as np
    from knit_nlp.jsonio import write_json, write_npz
    out = Path(sys.argv[1])
    k = 0
    while True:
        k += 1
        data = {"k": k, "payload": np.full(200_000, float(k))}
        write_json(out / "r.json", data)
        write_npz(out / "r.npz", payload=data["payload"])
        print(k, flush=True)
""")


def _kill_during_a_write(proc: subprocess.Popen, target: Path, timeout: float = 10.0) -> None:
    """SIGKILL ``proc`` the moment ``target`` changes (size or inode): with a plain write that is
    inside the write, the worst moment; with an atomic one it is right after the rename."""
    first = target.stat()
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            now = target.stat()
        except FileNotFoundError:
            break
        if (now.st_ino, now.st_size, now.st_mtime_ns) != (first.st_ino, first.st_size,
                                                          first.st_mtime_ns):
            break
    proc.send_signal(signal.SIGKILL)


def test_kill_9_never_leaves_a_truncated_result(tmp_path):
    """Kill a process that rewrites a 3 MB JSON and an NPZ in a loop (write_json, write_npz),
    6 times: the moment the JSON changes, the moment the NPZ changes, or at random. Each time
    both files hold one complete version (with plain writes they are left empty or cut)."""
    rng = np.random.default_rng(13)
    for trial in range(6):
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(tmp_path)], cwd=ROOT,
                                stdout=subprocess.PIPE, text=True)
        assert proc.stdout.readline().strip()          # at least one complete write
        if trial % 3 == 2:
            time.sleep(rng.uniform(0.0, 0.3))
            proc.send_signal(signal.SIGKILL)
        else:
            _kill_during_a_write(proc, tmp_path / ("r.json", "r.npz")[trial % 3])
        proc.wait()
        proc.stdout.close()
        data = json.loads((tmp_path / "r.json").read_text())
        assert len(data["payload"]) == 200_000 and set(data["payload"]) == {float(data["k"])}
        with np.load(tmp_path / "r.npz") as arrays:
            payload = arrays["payload"]
        assert payload.shape == (200_000,) and np.all(payload == payload[0])
    leftovers = [p.name for p in tmp_path.iterdir() if p.name not in ("r.json", "r.npz")]
    assert all(name.startswith((".r.json.", ".r.npz.")) for name in leftovers), leftovers


def test_a_failed_write_keeps_the_previous_file(tmp_path):
    from knit_nlp.atomic import atomic_file
    target = tmp_path / "a.json"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_file(target, "w") as fh:
            fh.write("half-new")
            raise RuntimeError("killed")
    assert target.read_text() == "old" and list(tmp_path.iterdir()) == [target]


def _without_timings(result: dict) -> dict:
    return {k: v for k, v in result.items() if k != "timings"}


@pytest.mark.parametrize("problem,files", [
    ("wada_fig7", ("wada_fig7.full.json", "wada_fig7.full.npz")),
    ("jacquard_diamond", ("jacquard_diamond.jacquard.json",)),
])
def test_two_runs_give_identical_json_and_bit_identical_arrays(tmp_path, capsys, problem, files):
    for run in ("a", "b"):
        assert main(["solve", problem, "--out", str(tmp_path / run)]) == 0
    js = files[0]
    a = json.loads((tmp_path / "a" / js).read_text())
    b = json.loads((tmp_path / "b" / js).read_text())
    assert _without_timings(a) == _without_timings(b)
    for npz in files[1:]:
        with np.load(tmp_path / "a" / npz) as xa, np.load(tmp_path / "b" / npz) as xb:
            assert sorted(xa.files) == sorted(xb.files)
            for key in xa.files:
                assert xa[key].tobytes() == xb[key].tobytes(), key


def _doc():
    return {"fabric": {"courses": 2, "wales": 3},
            "clamp": [{"loop": [1, 1], "point": "start", "position": [0.0, 0.0]},
                      {"loop": [1, 3], "point": "H", "displacement": [0.0, 0.0]}]}


@pytest.mark.parametrize("damage", ["empty json", "truncated json", "empty npy", "garbage npy",
                                    "json not a result"])
def test_a_study_resumes_past_a_damaged_cache_entry(tmp_path, capsys, damage):
    from knit_nlp.studies.runner import LoadPath, point_files, run_study
    path = LoadPath("pull", _doc(), [{"displacements": {"2": [d, 0.0]}} for d in (0.5, 1.0, 1.5)])
    whole = run_study("s", [path], tmp_path / "a", workers=1)
    partial = run_study("s", [path], tmp_path / "b", workers=1, limit=2)
    assert not partial["complete"]
    js, npy = point_files(tmp_path / "b" / "s" / "points", path, 1)
    if damage == "empty json":
        js.write_text("")
    elif damage == "truncated json":
        js.write_text(js.read_text()[:100])
    elif damage == "empty npy":
        npy.write_bytes(b"")
    elif damage == "garbage npy":
        npy.write_bytes(b"\x93NUMPY garbage")
    else:
        js.write_text("[1, 2, 3]")
    resumed = run_study("s", [path], tmp_path / "b", workers=1)
    assert resumed["complete"]
    a = json.loads((tmp_path / "a" / "s" / "summary.json").read_text())
    b = json.loads((tmp_path / "b" / "s" / "summary.json").read_text())
    assert a == b and whole == resumed
    assert json.loads(js.read_text())["success"] is True       # the damaged point was re-solved


def test_library_imports_leave_matplotlibs_backend_alone(tmp_path):
    """Solving and saving both models' pictures, and importing every library module, keeps the
    caller's backend."""
    code = textwrap.dedent(f"""
        import matplotlib
        matplotlib.use("svg")
        import knit_nlp
        for name in ("wada_fig7", "jacquard_stripe"):
            knit_nlp.solve(name).save({str(tmp_path)!r})
        import importlib, pkgutil
        for mod in pkgutil.walk_packages(knit_nlp.__path__, "knit_nlp."):
            importlib.import_module(mod.name)
        print(matplotlib.get_backend())
    """)
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         env={**os.environ, "MPLBACKEND": ""}, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "svg"
    for png in ("wada_fig7.full.png", "jacquard_stripe.jacquard.png"):
        assert (tmp_path / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_packaged_problems_are_found_through_importlib_resources(tmp_path, monkeypatch):
    from knit_nlp.problems import DATA_FOLDER, packaged_problems
    pkg = tmp_path / "fakepkg"
    (pkg / DATA_FOLDER).mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / DATA_FOLDER / "x.toml").write_text("[fabric]\ncourses = 1\nwales = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert packaged_problems("fakepkg") == pkg / DATA_FOLDER
    assert packaged_problems("json") is None                      # a package without data


def test_every_named_problem_file_is_declared_package_data():
    """pyproject maps problems/ to knit_nlp/problem_data and its patterns cover every file."""
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert conf["package-dir"]["knit_nlp.problem_data"] == "problems"
    assert "knit_nlp.problem_data" in conf["packages"]
    patterns = conf["package-data"]["knit_nlp.problem_data"]
    files = [str(p.relative_to(ROOT / "problems")) for p in (ROOT / "problems").rglob("*")
             if p.is_file()]
    assert files and all(any(fnmatch(f, pat) for pat in patterns) for f in files), files


def test_one_version_string():
    import knit_nlp
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in conf["project"] and "version" in conf["project"]["dynamic"]
    assert conf["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "knit_nlp.__version__"}
    assert knit_nlp.__version__.count(".") == 2


def test_every_subpackage_is_declared():
    """pyproject lists packages by hand (problems/ is mapped in): a new subpackage must be added
    there, or `pip install .` would leave it out."""
    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    found = {".".join(p.parent.relative_to(ROOT).parts)
             for p in (ROOT / "knit_nlp").rglob("__init__.py")}
    assert found <= set(conf["packages"]), found - set(conf["packages"])
