"""The command line starts without the heavy modules: matplotlib and scipy are imported where a
picture is drawn or a contact/sparse computation runs (issue 22: the CLI's import time)."""
from __future__ import annotations

import subprocess
import sys

HEAVY = ("matplotlib", "scipy", "pyamg")


def test_importing_the_cli_loads_neither_matplotlib_nor_scipy():
    code = ("import sys, knit_nlp.cli; "
            f"print(sorted({{m.split('.')[0] for m in sys.modules}} & set({HEAVY!r})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "[]", f"imported at start-up: {out}"


def test_a_solve_still_draws_and_a_contact_solve_still_counts(tmp_path):
    """The lazy imports are reached: a weft solve writes its picture, and the checker (which
    imports scipy's k-d tree lazily) runs."""
    from knit_nlp.cli import main
    assert main(["solve", "single_loop_moment", "--out", str(tmp_path)]) == 0
    png = tmp_path / "single_loop_moment.full.png"
    assert png.stat().st_size > 1000
    assert main(["check", str(tmp_path / "single_loop_moment.full.json")]) == 0
