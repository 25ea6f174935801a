"""docs/inverse_files.md documents every input of ``control``, ``fit`` and ``overlay``, and its
examples are read by the readers they document.

The keys come from the code, not from a list here: the control keys stripped before the forward
reader (``CLAMP_KEYS``, ``RIGID_KEYS``, ``TOP_KEYS``), the keys each ``Table.allow(...)`` call of
``spec.py`` accepts (``[[goal]]``, ``[[opening]]`` and its points), the keys ``parse_control``
reads from ``[control]``, the observations reader's ``COLUMNS`` and the commands' flags. So a key
added to a reader without a row in the doc fails here.
"""
from __future__ import annotations

import ast
import inspect
import re
from pathlib import Path

import pytest

from knit_nlp.weft.commands import COMMANDS
from knit_nlp.weft.inverse import spec
from knit_nlp.weft.inverse.observations import COLUMNS, load_observations
from knit_nlp.weft.model.params import MATERIAL
from knit_nlp.weft.model.problem import load_problem

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "inverse_files.md"
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```\s*$", re.S | re.M)
FIT_CASES = ("fit_course_pull", "fit_wale_pull", "fit_shear")


def sections(text: str) -> dict[str, str]:
    """Heading line -> the text under it, up to the next heading of any level."""
    parts = re.split(r"^(#+ .*)$", text, flags=re.M)
    return {parts[k].strip(): parts[k + 1] for k in range(1, len(parts) - 1, 2)}


def section(text: str, needle: str) -> str:
    """The one section whose heading contains ``needle``."""
    found = [body for head, body in sections(text).items() if needle in head]
    assert len(found) == 1, f"docs/inverse_files.md: {len(found)} headings contain {needle!r}"
    return found[0]


def rows(body: str) -> set[str]:
    """The first cells of a section's Markdown table rows, unquoted: the documented names."""
    return set(re.findall(r"^\| `([^`]+)` \|", body, flags=re.M))


def allowed_keys() -> dict[str, tuple[str, ...]]:
    """Per reader function of spec.py, the keys its ``allow(...)`` calls accept."""
    out: dict[str, tuple[str, ...]] = {}
    tree = ast.parse(inspect.getsource(spec))
    for fn in (n for n in tree.body if isinstance(n, ast.FunctionDef)):
        for call in (n for n in ast.walk(fn) if isinstance(n, ast.Call)):
            if isinstance(call.func, ast.Attribute) and call.func.attr == "allow":
                out[fn.name] = out.get(fn.name, ()) + tuple(a.value for a in call.args)
    return out


def control_table_keys() -> set[str]:
    """The keys ``parse_control`` reads from the ``[control]`` table (``ctl.<reader>("key")``)."""
    fn = next(n for n in ast.parse(inspect.getsource(spec)).body
              if isinstance(n, ast.FunctionDef) and n.name == "parse_control")
    return {c.args[0].value for c in ast.walk(fn)
            if isinstance(c, ast.Call) and isinstance(c.func, ast.Attribute)
            and isinstance(c.func.value, ast.Name) and c.func.value.id == "ctl"
            and c.args and isinstance(c.args[0], ast.Constant)}


def blocks(info: str) -> list[str]:
    """The bodies of the doc's fenced blocks marked exactly ``info``."""
    return [m[2] for m in FENCE.finditer(DOC.read_text()) if m[1].strip() == info]


def test_the_introspection_finds_the_readers_keys():
    """A guard on the guard: the AST walks above still see the readers (else the test below
    would pass vacuously)."""
    allowed = allowed_keys()
    assert {"loop", "point", "position", "weight"} <= set(allowed["_read_goal"])
    assert {"points", "at_least", "loop", "point"} <= set(allowed["_read_opening"])
    assert "travel_weight" in control_table_keys()


def test_every_control_key_has_a_row_in_its_tables_section():
    text = DOC.read_text()
    allowed = allowed_keys()
    expected = {"[[clamp]]": set(spec.CLAMP_KEYS), "[[rigid_clamp]]": set(spec.RIGID_KEYS),
                "[[goal]]": set(allowed["_read_goal"]),
                "[[opening]]": set(allowed["_read_opening"]) - {"loop", "point"},
                "[control]": control_table_keys()}
    for heading, keys in expected.items():
        missing = keys - rows(section(text, heading))
        assert not missing, f"docs/inverse_files.md, {heading}: no row for {sorted(missing)}"
    # the opening's points take a goal's loop and point: named in the points row
    points_row = re.search(r"^\| `points` \|.*$", section(text, "[[opening]]"), flags=re.M)[0]
    assert all(f"{k}" in points_row for k in set(allowed["_read_opening"]) - {"points", "at_least"})
    # every top-level control table has its own section
    heads = " ".join(sections(text))
    for key in spec.TOP_KEYS:
        assert f"[{key}]" in heads, f"docs/inverse_files.md: no section for the {key} table"


def test_every_observation_column_and_every_flag_is_documented():
    text = DOC.read_text()
    assert f"`{','.join(COLUMNS)}`" in text             # the exact header line
    missing = set(COLUMNS) - rows(section(text, "Observations CSV"))
    assert not missing, f"docs/inverse_files.md: no row for the columns {sorted(missing)}"
    for command, heading in (("fit", "## Fit"), ("overlay", "## Overlay")):
        arguments = next(a for name, _, a, _ in COMMANDS if name == command)
        body = section(text, heading)
        for names, options in arguments:
            flags = [n for n in names if n.startswith("--")]
            documented = flags or [options.get("metavar", names[0])]
            assert any(d in " ".join(rows(body)) for d in documented), (
                f"docs/inverse_files.md, {heading}: no row for {names[0]}")
    params_row = re.search(r"^\| `--params` \|.*$", text, flags=re.M)[0]
    assert all(f"`{m}`" in params_row for m in MATERIAL), "--params: a material value undocumented"


def test_the_doc_has_full_control_examples_and_observation_examples():
    assert len(blocks("toml control")) >= 2 and blocks("csv observations")


@pytest.mark.parametrize("k", range(len(blocks("toml control"))))
def test_each_control_example_loads_through_the_control_reader(k, tmp_path):
    path = tmp_path / "example.toml"
    path.write_text(blocks("toml control")[k])
    cp = spec.load_control(path)
    assert cp.actuated and (cp.goals or cp.openings)


@pytest.mark.parametrize("k", range(len(blocks("csv observations"))))
def test_each_observations_example_is_read_by_the_observations_reader(k, tmp_path):
    cases = {n: load_problem(ROOT / "problems" / "fit_example" / f"{n}.toml") for n in FIT_CASES}
    path = tmp_path / "observations.csv"
    body = blocks("csv observations")[k]
    path.write_text(body)
    obs = load_observations(path, cases)
    data_lines = [ln for ln in body.splitlines() if ln.strip() and not ln.startswith("#")]
    assert len(obs) == len(data_lines) - 1            # every row read, the header excepted
