"""The README's "Everyday tasks" done exactly as written: its `knit-nlp` lines run through the
CLI, and the files and numbers it promises are there."""
import csv
import json
import re
import shlex
from pathlib import Path

import numpy as np

from knit_nlp.cli import main

README = Path(__file__).resolve().parent.parent / "README.md"


def _section_commands() -> list[list[str]]:
    text = README.read_text()
    section = text.split("## Everyday tasks", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```sh\n(.*?)```", section, re.S)
    return [shlex.split(line)[1:] for block in blocks for line in block.splitlines()
            if line.startswith("knit-nlp ")]


def test_readme_everyday_tasks_run_as_written(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    commands = _section_commands()
    assert len(commands) == 2
    for argv in commands:
        assert main(argv) == 0, argv
    out = capsys.readouterr().out
    assert "[N·mm]" in out and "total reaction" in out
    res = tmp_path / "results"
    for suffix in (".json", ".png", ".path.csv", ".path.png", ".gif"):
        assert (res / f"hold_top_pull_corner.full{suffix}").exists(), suffix
    doc = json.loads((res / "hold_top_pull_corner.full.json").read_text())
    assert doc["units"]["length"] == "mm" and doc["success"]
    # task 1: the top course is held where it was, the corner moved 5 mm at -45 degrees
    held = [c for c in doc["clamps"] if c.get("group") == "clamp[1]"]
    assert len(held) == 8 and all(c["loop"][0] == 8 and c["point"] == "head" for c in held)
    pulled = doc["clamps"][-1]
    rows = list(csv.DictReader((res / "hold_top_pull_corner.full.path.csv").open()))
    last = [r for r in rows if r["grip"] == "clamp 9"][-1]
    assert abs(float(last["distance"]) - 5.0) < 1e-9
    np.testing.assert_allclose([float(last["displacement_x"]), float(last["displacement_y"])],
                               5.0 * np.array([1, -1]) / np.sqrt(2), atol=1e-9)
    # task 2: the curve ends at the solve's reaction and its area is the stored energy
    np.testing.assert_allclose([float(last["force_x"]), float(last["force_y"])],
                               pulled["reaction"], rtol=1e-6, atol=1e-9)
    pull = [r for r in rows if r["grip"] == "clamp 9"]
    work = np.trapezoid([float(r["force_along_pull"]) for r in pull],
                        [float(r["distance"]) for r in pull])
    assert abs(work / doc["energy"]["total"] - 1) < 0.01
