"""Messages that say what to fix (issue 21 items 6 and 7): bad input is one line on stderr
naming the file (or flag), table and key, with what to do, and exit code 2."""
from pathlib import Path

import pytest

from knit_nlp.cli import main

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"

GOOD = """
[fabric]
courses = 2
wales = 3
[[clamp]]
loop = [1, 1]
point = "start"
position = [0.0, 0.0]
[[clamp]]
loop = [2, 3]
point = "H"
displacement = [1.0, 0.5]
"""


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
      "--reduced (jacquard flags: --solver, --svg)"]),
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
