"""Messages that say what to fix (issue 21 items 6 and 7): bad input is one line on stderr
naming the file (or flag), table and key, with what to do, and exit code 2."""
import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from knit_nlp.api import load_problem as load_any
from knit_nlp.cli import main
from knit_nlp.weft.inverse.fit import Fitter
from knit_nlp.weft.inverse.observations import Observation
from knit_nlp.weft.model.problem import load_problem
from problem_texts import small_pull

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"

GOOD = small_pull()


def refused(capsys, argv: list[str], *words: str) -> str:
    """Run the CLI on bad input: exit 2, one line on stderr containing ``words``."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("knit-nlp: "), err
    for word in words:
        assert word in err, err
    return err


def test_a_misspelt_required_table_is_named(write_problem, tmp_path, capsys):
    path = write_problem(GOOD.replace("[fabric]", "[fabirc]"), "a.toml")
    refused(capsys, ["solve", str(path), "--out", str(tmp_path / "out")],
            "a.toml: (top level) fabric: missing required table",
            "found unknown table 'fabirc': misspelt?")


def test_a_misspelt_optional_table_is_named_with_the_allowed_ones(write_problem, tmp_path,
                                                                    capsys):
    path = write_problem(GOOD + "[materal]\nk_a = 2.0\n", "a.toml")
    refused(capsys, ["solve", str(path), "--out", str(tmp_path / "out")],
            "(top level) materal: unknown table", "misspelt 'material'?",
            "allowed: clamp, description, fabric")


def test_a_misspelt_jacquard_system_table_is_named(tmp_path, capsys):
    text = (PROBLEMS / "jacquard_stripe.toml").read_text()
    assert "[fall_plate]" in text
    path = tmp_path / "j.toml"
    path.write_text(text.replace("[fall_plate]", "[fall_plaet]"))
    refused(capsys, ["solve", str(path), "--out", str(tmp_path / "out")],
            "fall_plate: missing required table (found unknown table 'fall_plaet': misspelt?)")


@pytest.mark.parametrize("value", ['["weft"]', "1", "{ name = \"weft\" }", "true"])
def test_a_model_that_is_not_a_string_is_one_line(write_problem, tmp_path, capsys, value):
    path = write_problem(f"model = {value}\n" + GOOD, "a.toml")
    refused(capsys, ["solve", str(path), "--out", str(tmp_path / "out")],
            "a.toml: (top level) model: must be one of 'weft', 'jacquard'")


@pytest.mark.parametrize("argv, words", [
    (["solve", "jacquard_stripe", "--reduced"],
     ["knit-nlp: --reduced: applies to weft problems only", "is a jacquard problem: drop "
      "--reduced (jacquard flags: --solver, --svg, --window)"]),
    (["solve", "wada_fig7", "--solver", "static", "--svg"],
     ["knit-nlp: --solver --svg: apply to jacquard problems only", "drop --solver --svg"]),
    (["solve", "wada_fig7", "--reduced", "--warm-from-reduced"],
     ["knit-nlp: --warm-from-reduced: starts the full model", "add --full"]),
    (["solve", "wada_fig7", "--animate"],
     ["knit-nlp: --animate: draws a loading path", "add --continuation N"]),
    (["fit", "wada_fig7", "--observations", "x.csv", "--params", "k_a", "k_c"],
     ["knit-nlp: --params k_c: unknown parameter 'k_c'; use k_a, k_b, R_f"]),
    (["fit", "wada_fig7", "--observations", "x.csv", "--params", "k_a", "k_a"],
     ["knit-nlp: --params k_a: given twice; give each of k_a, k_b, R_f at most once"]),
])
def test_flag_messages_say_what_to_do_without_top_level(tmp_path, capsys, argv, words):
    err = refused(capsys, [*argv, "--out", str(tmp_path / "out")], *words)
    assert "(top level)" not in err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


DISPLACED = """name = "disp"
[fabric]
courses = 3
wales = 3
[material]
k_a = 1.5
k_b = 0.02
R_f = 0.7
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [3, 3]
point = "end"
displacement = [1.0, 0.5]
"""


def _observed(path: Path, csv: Path, values: list[float]) -> None:
    """Noise-free observations of every H point of ``path`` solved at ``values``."""
    problem = load_problem(path)
    obs = [Observation(problem.name, (i, j), "H", problem.crossings.s["H"], np.zeros(2))
           for i in (1, 2, 3) for j in (1, 2, 3)]
    fitter = Fitter([problem], obs)
    fitter.solve_cases(np.array(values))
    rows = [f"{problem.name},{o.loop[0]},{o.loop[1]},H,{x:.12f},{y:.12f}\n"
            for o, (x, y) in zip(obs, fitter.positions(fitter.cases[0]))]
    csv.write_text("case,course,wale,point,x,y\n" + "".join(rows))


def test_a_displacement_only_fit_says_only_ratios_can_be_identified(write_problem, tmp_path,
                                                                     capsys):
    """No force anywhere: scaling k_a, k_b, R_f together changes no equilibrium, so the
    warning says what to do (add a force, or fit fewer values)."""
    path = write_problem(DISPLACED, "disp.toml")
    _observed(path, tmp_path / "obs.csv", [1.0, 0.01, 1.0])
    assert main(["fit", str(path), "--observations", str(tmp_path / "obs.csv"),
                 "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    hint = ("only ratios can be identified with displacement-only clamps: add a force or fit "
            "ratios with --params")
    assert out.count(hint) == 3, out
    assert json.loads((tmp_path / "out" / "disp.fit.json").read_text())["warnings"][0].count(hint)


def test_a_fit_of_ratios_with_displacement_only_clamps_is_determined(write_problem, tmp_path,
                                                                      capsys):
    path = write_problem(DISPLACED, "disp.toml")
    _observed(path, tmp_path / "obs.csv", [1.0, 0.01, 0.7])
    assert main(["fit", str(path), "--observations", str(tmp_path / "obs.csv"),
                 "--params", "k_a", "k_b", "--out", str(tmp_path / "out")]) == 0
    r = json.loads((tmp_path / "out" / "disp.fit.json").read_text())
    assert "only ratios" not in capsys.readouterr().out and not r["warnings"]
    assert r["parameters"]["k_b"]["value"] == pytest.approx(0.01, rel=1e-5)


FAR = """
[fabric]
courses = 4
wales = 4
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [4, 4]
point = "H"
displacement = [0.0, 0.0]
actuated = true
bounds = [[0.0, 16.0], [0.0, 30.0]]
[[goal]]
loop = [3, 2]
point = "B"
position = [100.0, 7.0]
"""


def test_a_control_on_its_bounds_says_so_in_readable_lines(write_problem, tmp_path, capsys):
    """A goal beyond reach: the gripper stops on x <= 16. The summary and the JSON message
    name the unknown on its bound; no line prints a Python dict."""
    path = write_problem(FAR, "far.toml")
    assert main(["control", str(path), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert "{" not in out and "'" not in out, out
    assert "  actuated clamp[2]: target (16, " in out
    assert "on a bound: clamp[2] target x = 16 (upper bound): widen its bounds" in out
    assert "target y" not in out
    r = json.loads((tmp_path / "out" / "far.control.json").read_text())
    assert "stopped on a bound: clamp[2] target x = 16 (upper bound)" in r["message"]


JACQUARD = """name = "tiny"
model = "jacquard"
[fabric]
wales = 6
courses = 6
dz = 10.0
dh = 8.0
[fall_plate]
design_image = "fp.png"
[inlay]
design = \"\"\"
..+###
.+####
+#####
###+..
##+...
#+....
\"\"\"
"""
FALL_PLATE = ["##+...", "#+....", "+.....", "...++#", "..+###", ".+####"]
GREY = {"#": 0, "+": 128, ".": 255}


def _design_png(path: Path, mode: str, transparency: object) -> None:
    """The fall-plate design as an 8-bit grey (L) or RGB PNG with a ``tRNS`` chunk."""
    grey = np.array([[GREY[c] for c in row] for row in FALL_PLATE], dtype=np.uint8)
    pixels = grey if mode == "L" else np.repeat(grey[:, :, None], 3, axis=2)
    Image.fromarray(pixels, mode).save(path, transparency=transparency)


@pytest.mark.parametrize("mode, transparency", [("L", 255), ("RGB", (0, 0, 0)), ("L", 128)])
def test_a_png_whose_trns_chunk_hides_a_cell_is_refused(tmp_path, capsys, mode, transparency):
    _design_png(tmp_path / "fp.png", mode, transparency)
    (tmp_path / "tiny.toml").write_text(JACQUARD)
    first = next((x, y) for y, row in enumerate(FALL_PLATE) for x, c in enumerate(row)
                 if GREY[c] == (transparency if mode == "L" else 0))
    refused(capsys, ["solve", str(tmp_path / "tiny.toml"), "--out", str(tmp_path / "out")],
            "tiny.toml: [fall_plate] design_image:", "fp.png",
            f"pixel (x={first[0]}, y={first[1]} from the top left) has alpha 0 < 1",
            "flatten the image")
    assert not (tmp_path / "out").exists()


def test_a_png_whose_trns_colour_is_unused_is_accepted(tmp_path):
    _design_png(tmp_path / "fp.png", "L", 77)
    (tmp_path / "tiny.toml").write_text(JACQUARD)
    text = JACQUARD.replace('design_image = "fp.png"',
                            'design = """\n' + "\n".join(FALL_PLATE) + '\n"""')
    (tmp_path / "text.toml").write_text(text)
    image, plain = load_any(tmp_path / "tiny.toml"), load_any(tmp_path / "text.toml")
    assert np.array_equal(image.systems[0].codes, plain.systems[0].codes)


ONE_CLAMP = "[fabric]\ncourses = 2\nwales = 3\n[clamp]\nloop = [1, 1]\nposition = [0.0, 0.0]\n"


@pytest.mark.parametrize("text, words", [
    (GOOD.replace("[fabric]", "[[fabric]]"),
     "(top level) fabric: expected a table, got an array of tables ([[fabric]]): write [fabric]"),
    (ONE_CLAMP,
     "(top level) clamp: expected an array of tables ([[clamp]]): write [[clamp]], not [clamp]"),
])
def test_single_and_double_brackets_swapped_say_which_to_write(write_problem, tmp_path, capsys,
                                                               text, words):
    refused(capsys, ["solve", str(write_problem(text, "a.toml")), "--out",
                     str(tmp_path / "out")], words)


def test_an_out_folder_message_names_the_flag_not_a_file_key(tmp_path, capsys):
    """'(top level)' names file keys only: an unusable --out is 'PATH: what to do'."""
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["solve", "wada_fig7", "--out", str(blocker)]) == 2
    err = capsys.readouterr().err.strip()
    assert "(top level)" not in err and "give a folder" in err and len(err.splitlines()) == 1
