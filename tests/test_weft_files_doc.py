"""docs/weft_files.md says it lists every key of a weft problem file: every table the problem
reader reads, and every key each table allows, is in its problem block. The allowed keys come
from the reader itself (its one-line refusal of an unknown key lists them), so a key added to
the reader without a line in the doc fails here."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from knit_nlp.errors import ProblemError
from knit_nlp.weft.model.problem import parse_problem

DOC = Path(__file__).resolve().parent.parent / "docs" / "weft_files.md"
FENCE = re.compile(r"^```toml problem\n(.*?)^```\s*$", re.S | re.M)
BASE = {"fabric": {"courses": 2, "wales": 2}}
REQUIRED = {"yarn": {"radius": 0.1}}                     # tables with a required key
TABLES = ("fabric", "loop", "material", "units", "reduction", "solver", "yarn")
ARRAYS = {"clamp": {"loop": [1, 1], "point": "start", "position": [0.0, 0.0]},
          "load": {"loop": [1, 1], "point": "end", "force": [0.0, 0.0]},
          "rigid_clamp": {"edge": "left", "point": "start"}}


def block() -> str:
    (body,) = FENCE.findall(DOC.read_text())
    return body


def allowed(table: str) -> list[str]:
    """The keys the reader allows in ``table``, from its refusal of an unknown one."""
    doc = {**BASE, table: {**BASE.get(table, {}), **REQUIRED.get(table, {}), "no_such_key": 1}}
    if table in ARRAYS:
        doc[table] = [{**ARRAYS[table], "no_such_key": 1}]
    with pytest.raises(ProblemError) as err:
        parse_problem(doc, "probe.toml")
    found = re.search(r"allowed: ([^)]*)\)", str(err.value))
    assert found and "no_such_key" in str(err.value), str(err.value)
    return [k.strip() for k in found[1].split(",")]


@pytest.mark.parametrize("table", [*TABLES, *ARRAYS])
def test_every_key_of_every_table_is_in_the_doc(table):
    text = block()
    head = f"[[{table}]]" if table in ARRAYS else f"[{table}]"
    assert re.search(rf"^{re.escape(head)}", text, re.M), f"no {head} in docs/weft_files.md"
    missing = [k for k in allowed(table) if not re.search(rf"(^|[#|,] ?){k} =", text, re.M)]
    assert not missing, f"{head} keys not in docs/weft_files.md: {missing}"


def test_the_top_level_keys_are_in_the_doc():
    with pytest.raises(ProblemError) as err:
        parse_problem({**BASE, "no_such_key": 1}, "probe.toml")
    keys = re.search(r"allowed: ([^)]*)\)", str(err.value))[1].split(", ")
    text = block()
    for key in keys:
        assert re.search(rf"^(\[\[?)?{key}( =|\]\]?)", text, re.M), key
