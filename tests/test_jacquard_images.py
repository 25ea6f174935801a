"""Three-colour PNG designs (``design_image``) for the jacquard problem form."""
from __future__ import annotations

import json
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from PIL import Image

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402

from knit_nlp.cli import main  # noqa: E402
from knit_nlp.jacquard import parse_problem, solve_static  # noqa: E402
from knit_nlp.tomlio import load_toml  # noqa: E402

# Asymmetric (no left-right, top-bottom or transpose symmetry), all three symbols, 6 x 6.
FALL_PLATE = "##+...\n#+....\n+.....\n...++#\n..+###\n.+####\n"
INLAY = "..+###\n.+####\n+#####\n###+..\n##+...\n#+....\n"
GREY = {"#": 0.0, "+": 128 / 255, ".": 1.0}      # 8-bit exact: black, mid grey, white

HEAD = """\
name = "{name}"
model = "jacquard"
[fabric]
wales = {wales}
courses = {courses}
dz = 10.0
dh = 8.0
"""


def _grey(text: str) -> np.ndarray:
    """A text design as a greyscale float image (rows top to bottom)."""
    return np.array([[GREY[c] for c in line] for line in text.split()])


def _save_rgb(path: Path, grey: np.ndarray) -> Path:
    """Save a greyscale float image as an RGB(A) 8-bit PNG with imsave; check it round-trips."""
    rgb = np.repeat(grey[:, :, None], 3, axis=2)
    mpimg.imsave(path, rgb)
    back = mpimg.imread(path)
    assert back.shape[:2] == grey.shape and np.array_equal(back[:, :, :3], rgb.astype(np.float32))
    return path


def _toml(name: str, fall_plate: str, inlay: str, shape: tuple[int, int] = (6, 6)) -> str:
    """A problem with the given ``[fall_plate]`` and ``[inlay]`` design lines."""
    return (HEAD.format(name=name, wales=shape[1], courses=shape[0])
            + f"[fall_plate]\n{fall_plate}\n[inlay]\n{inlay}\n")


def _text_key(text: str) -> str:
    return f'design = """\n{text}"""'


def _problem(tmp_path: Path, name: str, text: str):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return parse_problem(load_toml(path), path)


def test_image_design_equals_text_design(tmp_path):
    """Cell for cell (orientation included) and the same static equilibrium."""
    _save_rgb(tmp_path / "fp.png", _grey(FALL_PLATE))
    _save_rgb(tmp_path / "in.png", _grey(INLAY))
    text = _problem(tmp_path, "text", _toml("text", _text_key(FALL_PLATE), _text_key(INLAY)))
    image = _problem(tmp_path, "image", _toml("image", 'design_image = "fp.png"',
                                              'design_image = "in.png"'))
    for t, i in zip(text.systems, image.systems):
        assert i.codes.dtype == np.int8 and i.codes.shape == (6, 6)
        assert np.array_equal(t.codes, i.codes)
    fp = image.systems[0].codes
    assert fp[0, 0] == 0 and fp[5, 0] == 2               # bottom-left net, top-left thick
    assert not np.array_equal(fp, fp[::-1]) and not np.array_equal(fp, fp[:, ::-1])
    a, b = solve_static(text), solve_static(image)
    assert a.success and b.success
    assert np.array_equal(a.positions, b.positions)


def _save_pil(path: Path, grey: np.ndarray, mode: str) -> None:
    """Greyscale 8-bit (L), 16-bit (I;16) or RGB-without-alpha PNGs, written with Pillow."""
    if mode == "L":
        Image.fromarray(np.round(grey * 255).astype(np.uint8), "L").save(path)
    elif mode == "I;16":
        Image.fromarray(np.round(grey * 65535).astype(np.uint16)).save(path)
    else:
        rgb = np.repeat(np.round(grey * 255).astype(np.uint8)[:, :, None], 3, axis=2)
        Image.fromarray(rgb, "RGB").save(path)


@pytest.mark.parametrize("mode", ["L", "I;16", "RGB"])
def test_greyscale_16bit_and_rgb_pngs(tmp_path, mode):
    _save_pil(tmp_path / "fp.png", _grey(FALL_PLATE), mode)
    assert Image.open(tmp_path / "fp.png").mode == mode
    image = _problem(tmp_path, "image", _toml("image", 'design_image = "fp.png"',
                                              _text_key(INLAY)))
    text = _problem(tmp_path, "text", _toml("text", _text_key(FALL_PLATE), _text_key(INLAY)))
    assert np.array_equal(image.systems[0].codes, text.systems[0].codes)


def test_colours_classified_by_luminance(tmp_path):
    """Y = 0.299 R + 0.587 G + 0.114 B: < 1/3 thick, < 2/3 thin, else net (hue is ignored)."""
    red = (0.4, 0.0, 0.0)        # Y 0.120 -> thick
    green = (0.0, 1.0, 0.0)      # Y 0.587 -> thin
    yellow = (1.0, 1.0, 0.0)     # Y 0.886 -> net
    rgb = np.array([[red, green, yellow, red], [yellow, red, green, green]])
    mpimg.imsave(tmp_path / "fp.png", rgb)
    doc = _toml("lum", 'design_image = "fp.png"', _text_key("####\n####\n"), shape=(2, 4))
    codes = _problem(tmp_path, "lum", doc).systems[0].codes
    assert codes.tolist() == [[0, 2, 1, 1], [2, 1, 0, 2]]  # row 0 = bottom = image's last row


def _write_bad(tmp_path: Path, case: str) -> Path:
    """A problem whose ``[fall_plate] design_image`` is bad in the way ``case`` says."""
    grey = _grey(FALL_PLATE)
    key = 'design_image = "fp.png"'
    if case == "four colours":
        grey[0, 0] = 64 / 255
        _save_rgb(tmp_path / "fp.png", grey)
    elif case == "transparent":
        rgba = np.concatenate([np.repeat(grey[:, :, None], 3, axis=2), np.ones((6, 6, 1))], axis=2)
        rgba[2, 3, 3] = 0.0
        mpimg.imsave(tmp_path / "fp.png", rgba)
    elif case == "wrong size":
        _save_rgb(tmp_path / "fp.png", grey[:, :5])
    elif case == "not an image":
        (tmp_path / "fp.png").write_text("##+...\n")
    elif case == "jpeg":
        Image.fromarray(np.round(grey * 255).astype(np.uint8), "L").save(tmp_path / "fp.jpg")
        key = 'design_image = "fp.jpg"'
    elif case == "missing":
        pass
    elif case == "both":
        _save_rgb(tmp_path / "fp.png", grey)
        key = _text_key(FALL_PLATE) + "\n" + key
    path = tmp_path / "tiny.toml"
    path.write_text(_toml("tiny", key, _text_key(INLAY)))
    return path


@pytest.mark.parametrize("case, words", [
    ("four colours", "4 distinct colours"),
    ("transparent", "(x=3, y=2 from the top left) has alpha 0"),
    ("wrong size", "design image is 5 x 6 pixels; [fabric] declares 6 wales x 6 courses"),
    ("not an image", "is not a PNG image"),
    ("jpeg", "is not a PNG image"),
    ("missing", "cannot read design image"),
    ("both", "give exactly one of 'design'"),
])
def test_bad_image_exits_2_with_one_line(tmp_path, capsys, case, words):
    path = _write_bad(tmp_path, case)
    out = tmp_path / "out"
    assert main(["solve", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert "tiny.toml" in err and "[fall_plate] design_image:" in err and words in err, err
    assert not out.exists()


def test_shipped_image_problem(tmp_path):
    """problems/jacquard_image.toml: 12 x 12, three colours per system, every cell underlapped."""
    root = Path(__file__).resolve().parent.parent / "problems"
    problem = parse_problem(load_toml(root / "jacquard_image.toml"), root / "jacquard_image.toml")
    fp, inlay = (s.codes for s in problem.systems)
    assert fp.shape == inlay.shape == (12, 12)
    assert set(np.unique(fp)) == set(np.unique(inlay)) == {0, 1, 2}
    assert np.all((fp > 0) | (inlay > 0))
    assert main(["solve", "jacquard_image", "--out", str(tmp_path)]) == 0
    assert json.loads((tmp_path / "jacquard_image.jacquard.json").read_text())["success"] is True
