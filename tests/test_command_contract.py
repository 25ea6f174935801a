"""control, fit, overlay and sweep meet solve's bad-input contract (issue 21 item 7): one line on
stderr naming file/table/key (or flag) and what to do, exit 2, nothing written under --out,
checked before anything is solved; no hang on a FIFO, no unbounded memory on a bomb image."""
from __future__ import annotations

import os
import shutil
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from knit_nlp.cli import main

TINY = """
name = "{name}"
[fabric]
courses = {courses}
wales = 3
[material]
k_b = {k_b}
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [{courses}, 3]
point = "H"
displacement = [0.3, 0.0]
{extra}
"""
ACTUATED_GOAL = 'actuated = true\n[[goal]]\nloop = [2, 2]\npoint = "H"\ndisplacement = [0.5, 0.0]\n'
OBSERVATIONS = "case,course,wale,point,x,y\nobs,2,2,H,4.0,4.0\nobs,1,2,H,1.0,1.5\n"
MATCHES = ["--match", "1,1,start=1,1", "--match", "2,3,H=10,10"]


def tiny(folder: Path, name: str = "obs", courses: int = 2, k_b: float = 0.01,
         extra: str = "") -> Path:
    path = folder / f"{name}.toml"
    path.write_text(TINY.format(name=name, courses=courses, k_b=k_b, extra=extra))
    return path


def png(width: int, height: int) -> bytes:
    """A 1-bit greyscale PNG of zeros: a few kB on disk for any declared size."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    rows = zlib.compressobj(9)
    row = b"\0" * (1 + (width + 7) // 8)
    data = b"".join(rows.compress(row) for _ in range(min(height, 64))) + rows.flush()
    header = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", data) + chunk(b"IEND", b"")


def refused(capsys, *needles: str) -> str:
    err = capsys.readouterr().err
    assert err.startswith("knit-nlp: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in err, err
    return err


def listing(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*")) if folder.exists() else []


@pytest.fixture(scope="module")
def solved(tmp_path_factory) -> Path:
    """A solved 2 x 3 result (``obs.full.json`` and ``.npz``), its problem and a small image."""
    folder = tmp_path_factory.mktemp("solved")
    problem = tiny(folder)
    assert main(["solve", str(problem), "--out", str(folder)]) == 0
    import matplotlib.pyplot as plt
    plt.imsave(folder / "img.png", np.zeros((20, 30, 3)))
    return folder


def _overlay(result: Path, image: Path, out: Path, *extra: str) -> int:
    return main(["overlay", str(result), str(image), *MATCHES, *extra, "--out", str(out)])


# -- --out where nothing can be written: refused before solving ----------------------------------
def _unwritable(tmp_path: Path) -> list[Path]:
    """Folders nothing can be written under, for this user: under /proc (even for root), and
    a read-only folder (not for root, who may write anyway). ``os.access`` says root may
    write into /proc and /sys; only creating something there tells."""
    places = [Path(f"{top}/knit_nlp_out") for top in ("/proc", "/sys") if Path(top).is_dir()]
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        places.append(ro / "out")
    if not places:
        pytest.skip("no folder here that cannot be written")
    return places


def test_control_fit_overlay_refuse_an_unwritable_out_before_solving(tmp_path, capsys, solved,
                                                                       monkeypatch):
    from knit_nlp.weft.inverse import run
    monkeypatch.setattr(run, "control", lambda *a, **k: pytest.fail("solved before the check"))
    monkeypatch.setattr(run, "fit", lambda *a, **k: pytest.fail("solved before the check"))
    ctl = tiny(tmp_path, "ctl", extra=ACTUATED_GOAL)
    obs = tmp_path / "o.csv"
    obs.write_text(OBSERVATIONS)
    for out in _unwritable(tmp_path):
        assert main(["control", str(ctl), "--out", str(out)]) == 2
        refused(capsys, "output folder")
        assert main(["fit", str(solved / "obs.toml"), "--observations", str(obs),
                     "--params", "k_a", "--out", str(out)]) == 2
        refused(capsys, "output folder")
        assert _overlay(solved / "obs.full.json", solved / "img.png", out) == 2
        refused(capsys, "output folder")


# -- an output name that is a folder ------------------------------------------------------------
def test_control_refuses_an_output_that_is_a_folder(tmp_path, capsys):
    ctl = tiny(tmp_path, "ctl", extra=ACTUATED_GOAL)
    (tmp_path / "o" / "ctl.control.json").mkdir(parents=True)
    assert main(["control", str(ctl), "--out", str(tmp_path / "o")]) == 2
    refused(capsys, "ctl.control.json", "not a file")
    assert listing(tmp_path / "o") == ["ctl.control.json"]


def test_fit_refuses_an_output_that_is_a_folder(tmp_path, capsys, solved):
    obs = tmp_path / "o.csv"
    obs.write_text(OBSERVATIONS)
    (tmp_path / "o" / "obs.fit.png").mkdir(parents=True)
    assert main(["fit", str(solved / "obs.toml"), "--observations", str(obs), "--params", "k_a",
                 "--out", str(tmp_path / "o")]) == 2
    refused(capsys, "obs.fit.png", "not a file")
    assert listing(tmp_path / "o") == ["obs.fit.png"]


def test_overlay_refuses_an_output_that_is_a_folder(tmp_path, capsys, solved):
    (tmp_path / "o" / "obs.full.img.overlay.png").mkdir(parents=True)
    assert _overlay(solved / "obs.full.json", solved / "img.png", tmp_path / "o") == 2
    refused(capsys, "obs.full.img.overlay.png", "not a file")
    assert listing(tmp_path / "o") == ["obs.full.img.overlay.png"]


@pytest.mark.parametrize("blocker, is_dir", [("sweep.csv", True), ("sweep.png", True),
                                              ("summary.json", True), ("points", False)])
def test_sweep_refuses_an_output_in_the_way_and_leaves_no_cache(tmp_path, capsys, solved,
                                                                blocker, is_dir):
    target = tmp_path / "s" / blocker
    target.parent.mkdir()
    target.mkdir() if is_dir else target.write_text("")
    assert main(["sweep", str(solved / "obs.toml"), "--vary", "material.k_b=0.01:0.02:2",
                 "--name", "s", "--workers", "1", "--out", str(tmp_path)]) == 2
    refused(capsys, blocker)
    assert listing(tmp_path) == ["s", f"s/{blocker}"]


# -- fit's observations and values ---------------------------------------------------------------
def test_fit_refuses_a_csv_cell_over_the_csv_field_limit_in_one_line(tmp_path, capsys, solved):
    obs = tmp_path / "o.csv"
    obs.write_text(OBSERVATIONS + "obs,2,2,H," + "1" * (200 * 1024) + ",1.0\n")
    assert main(["fit", str(solved / "obs.toml"), "--observations", str(obs),
                 "--out", str(tmp_path / "o")]) == 2
    refused(capsys, str(obs), "[line 4]")
    assert not (tmp_path / "o").exists()


def test_fit_refuses_a_zero_parameter_it_is_asked_to_fit(tmp_path, capsys):
    problem = tiny(tmp_path, k_b=0.0)
    obs = tmp_path / "o.csv"
    obs.write_text(OBSERVATIONS)
    assert main(["fit", str(problem), "--observations", str(obs), "--params", "k_b",
                 "--out", str(tmp_path / "o")]) == 2
    refused(capsys, str(problem), "[material] k_b", "positive")
    assert not (tmp_path / "o").exists()


# -- overlay's result files ----------------------------------------------------------------------
@pytest.mark.parametrize("text", ["[1, 2]", "null", "3", '"x"', "true"])
def test_overlay_refuses_a_result_json_that_is_not_an_object(tmp_path, capsys, solved, text):
    result = tmp_path / "obs.full.json"
    result.write_text(text)
    shutil.copy(solved / "obs.full.npz", tmp_path)
    assert _overlay(result, solved / "img.png", tmp_path / "o", "--problem",
                    str(solved / "obs.toml")) == 2
    refused(capsys, str(result), "not a weft solve result")
    assert not (tmp_path / "o").exists()


def _arrays(solved: Path) -> dict[str, np.ndarray]:
    with np.load(solved / "obs.full.npz") as npz:
        return dict(npz)


def _nan(a: np.ndarray) -> np.ndarray:
    a = a.astype(float).copy()
    a.flat[-1] = np.nan
    return a


@pytest.mark.parametrize("change, needle", [
    (lambda a: {"coefficients": a["coefficients"].T}, "coefficients"),
    (lambda a: {"coefficients": _nan(a["coefficients"])}, "coefficients"),
    (lambda a: {"starts": _nan(a["starts"])}, "starts"),
    (lambda a: {"deformed": _nan(a["deformed"])}, "deformed"),
    (lambda a: {"s": np.zeros(0)}, "s"),
    (lambda a: {"s": -a["s"]}, "s"),
    (lambda a: {"coefficients": a["coefficients"][..., :5]}, "coefficients"),
    (lambda a: {"coefficients": np.float64(1.0)}, "coefficients"),
    (lambda a: {"starts": a["starts"][:1]}, "starts"),
    (lambda a: {"coefficients": a["coefficients"].astype(complex)}, "coefficients"),
])
def test_overlay_refuses_a_damaged_npz_in_one_line(tmp_path, capsys, solved, change, needle):
    shutil.copy(solved / "obs.full.json", tmp_path)
    arrays = _arrays(solved)
    np.savez(tmp_path / "obs.full.npz", **{**arrays, **change(arrays)})
    assert _overlay(tmp_path / "obs.full.json", solved / "img.png", tmp_path / "o", "--problem",
                    str(solved / "obs.toml")) == 2
    refused(capsys, "obs.full", needle)
    assert not (tmp_path / "o").exists()


def test_overlay_refuses_a_problem_larger_than_the_result(tmp_path, capsys, solved):
    bigger = tiny(tmp_path, "obs", courses=3)
    assert main(["overlay", str(solved / "obs.full.json"), str(solved / "img.png"),
                 "--match", "1,1,start=1,1", "--match", "3,3,H=10,10", "--problem", str(bigger),
                 "--out", str(tmp_path / "o")]) == 2
    refused(capsys, "3 x 3", "2 x 3")
    assert not (tmp_path / "o").exists()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_overlay_does_not_hang_on_a_fifo_npz(tmp_path, capsys, solved):
    shutil.copy(solved / "obs.full.json", tmp_path)
    os.mkfifo(tmp_path / "obs.full.npz")
    assert _overlay(tmp_path / "obs.full.json", solved / "img.png", tmp_path / "o") == 2
    refused(capsys, "obs.full.npz", "regular file")


def test_overlay_refuses_an_npz_declaring_more_than_it_may_hold(tmp_path, capsys, solved,
                                                               monkeypatch):
    from knit_nlp.weft.inverse import overlay
    monkeypatch.setattr(overlay, "MAX_ARRAY_BYTES", 10 ** 6)
    shutil.copy(solved / "obs.full.json", tmp_path)
    arrays = _arrays(solved)
    np.savez_compressed(tmp_path / "obs.full.npz", **{**arrays, "deformed": np.zeros(10 ** 7)})
    assert (tmp_path / "obs.full.npz").stat().st_size < 10 ** 6
    assert _overlay(tmp_path / "obs.full.json", solved / "img.png", tmp_path / "o") == 2
    refused(capsys, "obs.full.npz", "larger than")


# -- overlay's photograph: no decompression bomb -------------------------------------------------
@pytest.mark.parametrize("width, height", [(60000, 60000), (7000, 7000)])
def test_overlay_refuses_an_image_over_the_pixel_limit_before_decoding(tmp_path, capsys, solved,
                                                                       width, height):
    image = tmp_path / "bomb.png"
    image.write_bytes(png(width, height))
    assert image.stat().st_size < 100_000
    assert _overlay(solved / "obs.full.json", image, tmp_path / "o") == 2
    refused(capsys, str(image), f"{width} x {height}", "pixels")
    assert not (tmp_path / "o").exists()


# -- sweep's arguments ---------------------------------------------------------------------------
@pytest.mark.parametrize("workers", ["-1", "0", "1000000000", str(4 * (os.cpu_count() or 1) + 1)])
def test_sweep_refuses_a_worker_count_out_of_range_before_forking(tmp_path, capsys, solved,
                                                                  monkeypatch, workers):
    from knit_nlp.studies import executors
    monkeypatch.setattr(executors, "ProcessPoolExecutor",
                        lambda *a, **k: pytest.fail("a pool was started"))
    assert main(["sweep", str(solved / "obs.toml"), "--vary", "material.k_b=0.01:0.02:2",
                 "--workers", workers, "--out", str(tmp_path / "o")]) == 2
    refused(capsys, "--workers")
    assert not (tmp_path / "o").exists()


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("axis", ["material.k_b=1e999:1:2", "material.k_b=0:-1e999:2",
                                  "material.k_b=-1e308:1e308:3"])
def test_sweep_says_an_infinite_end_is_not_finite_without_warnings(tmp_path, capsys, solved, axis):
    assert main(["sweep", str(solved / "obs.toml"), "--vary", axis,
                 "--out", str(tmp_path / "o")]) == 2
    err = refused(capsys, f"--vary {axis}", "finite")
    assert "nan" not in err
    assert not (tmp_path / "o").exists()
