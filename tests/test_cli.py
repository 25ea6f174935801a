"""The command line: outputs per the contract, exit codes, and every bad-input rule."""
import json
import subprocess
import sys

import numpy as np
import pytest

from knit_nlp.cli import main

from imagecheck import check_weft_picture
from problem_texts import small_pull

GOOD = small_pull()


def test_solve_writes_contract_json_npz_png(write_problem, tmp_path, capsys, saved_figures):
    path = write_problem(GOOD, "good.toml")
    out = tmp_path / "out"
    assert main(["solve", str(path), "--out", str(out)]) == 0
    r = json.loads((out / "good.full.json").read_text())
    for key in ("problem", "model", "success", "status", "energy", "n_parameters", "n_variables",
                "n_constraints", "iterations", "max_constraint_violation", "timings", "clamps", "loops"):
        assert key in r
    assert r["problem"] == "good" and r["model"] == "full" and r["success"] is True
    e = r["energy"]
    assert e["total"] == pytest.approx(e["spring"] + e["bending"])
    assert e["spring"] > 1e-4 and e["bending"] > 1e-4      # two courses: crossing springs work
    assert r["n_parameters"] == 2 * 3 * 8 + 2 * 2
    assert np.array(r["loops"]["coefficients"]).shape == (2, 3, 8)
    assert np.array(r["loops"]["course_starts"]).shape == (2, 2)
    assert set(r["clamps"][0]) >= {"loop", "point", "position", "reaction"}
    arrays = np.load(out / "good.full.npz")
    np.testing.assert_array_equal(arrays["s"], np.linspace(0.0, 10.0, arrays["deformed"].shape[2]))
    assert arrays["deformed"].shape[:2] == (2, 3) and arrays["natural"].shape == arrays["deformed"].shape
    check_weft_picture(out / "good.full.png", r, 10.0, arrays["natural"], saved_figures)
    assert "Solve_Succeeded" in capsys.readouterr().out


def test_not_converged_is_exit_1_and_success_false(write_problem, tmp_path):
    path = write_problem(GOOD + "[solver]\nmax_iter = 1\ncontinuation = 1\n", "short.toml")
    assert main(["solve", str(path), "--out", str(tmp_path)]) == 1
    r = json.loads((tmp_path / "short.full.json").read_text())
    assert r["success"] is False and r["status"] != "Solve_Succeeded"


def test_list_names_the_problems(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for name in ("wada_fig7", "diagonal_pull", "course_stretch", "wale_stretch", "single_loop_moment"):
        assert name in out


def test_console_script_runs_a_named_problem(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "knit_nlp.cli", "solve", "wada_fig7", "--out",
                           str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "wada_fig7.full.json").exists()


CLAMP2 = '[[clamp]]\nloop = [2, 3]\npoint = "H"\ndisplacement = [1.0, 0.5]\n'
BAD = {
    "unknown top key": ("colour = 1\n" + GOOD, "(top level) colour"),
    "unknown fabric key": (GOOD.replace("wales = 3", "wales = 3\nrows = 2"), "[fabric] rows"),
    "unknown clamp key": (GOOD + CLAMP2.replace("H", "E").replace("displacement", "displacment"),
                          "[clamp[3]] displacment"),
    "wrong type": (GOOD.replace("courses = 2", 'courses = "2"'), "[fabric] courses"),
    "float for int": (GOOD.replace("courses = 2", "courses = 2.0"), "[fabric] courses"),
    "missing fabric": ("[loop]\nlength = 3.0\n", "(top level) fabric"),
    "loop out of range": (GOOD.replace("loop = [2, 3]", "loop = [3, 3]"), "[clamp[2]] loop"),
    "unknown label": (GOOD.replace('"H"', '"Z"'), "[clamp[2]] point"),
    "s out of range": (GOOD.replace('"H"', "12.5"), "[clamp[2]] point"),
    "both position and displacement": (
        GOOD.replace("displacement = [1.0, 0.5]", "displacement = [1.0, 0.5]\nposition = [1.0, 2.0]"),
        "[clamp[2]] position"),
    "neither position nor displacement": (GOOD.replace("displacement = [1.0, 0.5]", ""),
                                          "[clamp[2]] position"),
    "zero length": ("[loop]\nlength = 0.0\n" + GOOD, "[loop] length"),
    "negative length": ("[loop]\nlength = -2.0\n" + GOOD, "[loop] length"),
    "zero harmonics": ("[loop]\nharmonics = 0\n" + GOOD, "[loop] harmonics"),
    "negative stiffness": ("[material]\nk_b = -0.1\n" + GOOD, "[material] k_b"),
    "wrong coefficient count": ("[loop]\nnatural_coefficients = [2.0, 0, 0]\n" + GOOD,
                                "[loop] natural_coefficients"),
    "no crossings": ("[loop]\ncourse_spacing = 50.0\n" + GOOD, "[loop] course_spacing"),
    "over-constrained point": (GOOD + CLAMP2.replace("1.0, 0.5", "2.0, 0.5"), "[clamp[3]] fix"),
    "end is next start": (GOOD + '[[clamp]]\nloop = [1, 1]\npoint = "end"\nposition = [2.0, 0.0]\n'
                          '[[clamp]]\nloop = [1, 2]\npoint = "start"\nposition = [2.2, 0.0]\n'
                          'fix = ["x"]\n', "[clamp[4]] fix"),
    "angle twice": (GOOD + '[[clamp]]\nloop = [1, 2]\npoint = 3.0\nfix = []\nangle = 0.1\n'
                    '[[clamp]]\nloop = [1, 2]\npoint = 3.0\nfix = []\nangle = 0.2\n',
                    "[clamp[4]] angle"),
    "bad fix entry": (GOOD.replace("displacement = [1.0, 0.5]", 'displacement = [1.0, 0.5]\nfix = ["z"]'),
                      "[clamp[2]] fix"),
    "load without force or moment": (GOOD + '[[load]]\nloop = [1, 2]\npoint = "end"\n', "[load[1]] force"),
    "bad reduction": (GOOD + "[reduction]\nrepresentative_courses = [2]\n",
                      "[reduction] representative_courses"),
    "adaptive with representatives": (
        GOOD + "[reduction]\nadaptive = true\nrepresentative_wales = [1, 3]\n",
        "[reduction] representative_wales"),
    "tolerance without adaptive": (GOOD + "[reduction]\ntolerance = 0.5\n", "[reduction] tolerance"),
    "adaptive not a boolean": (GOOD + '[reduction]\nadaptive = "yes"\n', "[reduction] adaptive"),
    "zero tolerance": (GOOD + "[reduction]\nadaptive = true\ntolerance = 0.0\n",
                       "[reduction] tolerance"),
    "zero parameter budget": (GOOD + "[reduction]\nadaptive = true\nmax_parameters = 0\n",
                              "[reduction] max_parameters"),
    "not toml": ("[fabric\ncourses = 2", "not valid TOML"),
    "bad model": ('model = "warp"\n' + GOOD, "(top level) model"),
    "short position": (GOOD.replace("displacement = [1.0, 0.5]", "position = [1.0]"),
                       "[clamp[2]] position"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_problem_is_one_line_exit_2(case, write_problem, tmp_path, capsys):
    text, expected = BAD[case]
    path = write_problem(text, "bad.toml")
    assert main(["solve", str(path), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    assert str(path) in err and expected in err, err
    assert not list(tmp_path.glob("*.json"))


def test_missing_file_and_bad_arguments(tmp_path, capsys):
    assert main(["solve", str(tmp_path / "nope.toml")]) == 2
    assert "nope.toml" in capsys.readouterr().err
    assert main(["solve", "wada_fig7", "--reduced", "--full"]) == 2
    assert "not allowed with argument --reduced" in capsys.readouterr().err
    directory = tmp_path / "dir.toml"
    directory.mkdir()
    assert main(["solve", str(directory)]) == 2


def test_every_command_has_help(capsys):
    """``--help`` of the program and of every command prints its usage and exits 0 (``solve
    --help`` once ended in argparse's "empty group" traceback: a mutually exclusive group was
    made for every flag, leaving empty ones)."""
    from knit_nlp.cli import _parser
    commands = next(a for a in _parser()._actions if a.dest == "command").choices
    assert {"solve", "list", "control", "fit", "overlay", "check"} <= set(commands)
    for argv in (["--help"], *([c, "--help"] for c in commands)):
        assert main(argv) == 0, argv
        out = capsys.readouterr().out
        assert out.startswith("usage: knit-nlp") and "Traceback" not in out, argv
    assert main(["solve", "--help"]) == 0
    assert "--reduced" in capsys.readouterr().out


def test_list_shows_the_folders_and_each_name_it_shows_resolves(capsys):
    """``list`` shows the problems in sub-folders (fit_example/, real_fabric/: once omitted)
    under names that ``solve``/``fit``/``calibrate`` accept, with the command for specs, and
    each folder's other files."""
    from knit_nlp.problems import problems_dir, resolve
    assert main(["list"]) == 0
    rows = [line.split() for line in capsys.readouterr().out.splitlines()]
    names = {row[0]: row[1] for row in rows}
    assert names["fit_example/fit_course_pull"] == "weft"
    assert names["real_fabric/acrylic_fit_x"] == "calibrate"
    assert names["fit_example/"] == "folder" and "observations.csv," in \
        next(r for r in rows if r[0] == "fit_example/")
    shipped = {str(p.relative_to(problems_dir()).with_suffix(""))
               for p in problems_dir().glob("**/*.toml")}
    assert shipped == {n for n in names if not n.endswith("/")}
    for name in shipped:
        assert resolve(name) == problems_dir() / f"{name}.toml"
