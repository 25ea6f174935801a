"""The README's Python examples run as written (from a scratch folder, so ``save`` writes there)."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


def _python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_the_readme_has_python_examples():
    assert len(_python_blocks()) >= 4


def test_readme_python_blocks_run_in_order(tmp_path, monkeypatch, capsys):
    """One namespace for all blocks, as a reader pasting them in order would have."""
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for block in _python_blocks():
        exec(compile(block, str(README), "exec"), namespace)     # noqa: S102 (our own README)
    r = namespace["r"]
    assert r.success and r.clamps[1].number == 2
    assert (tmp_path / "results" / "wada_fig7.full.json").exists()
    assert namespace["jac"].success
    printed = capsys.readouterr().out
    assert "Solve_Succeeded" in printed


def test_front_door_one_liner():
    """The issue's 'done when' line."""
    import knit_nlp
    r = knit_nlp.solve("wada_fig7")
    assert r.success and r.energy.total == pytest.approx(1.67381054, rel=1e-6)
