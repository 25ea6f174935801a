"""Run the README's shell blocks exactly as written, in a fresh clone, as a newcomer would.

    python scripts/readme_literal.py [--with-tests] [--keep]

The committed HEAD is cloned into a temporary folder; every ``console`` block (the Quickstart:
venv, install, first solve) and then every ``sh`` block runs there line by line through
``bash -c`` (continuation lines joined), in order, with nothing activated (no virtual
environment's folder on ``PATH``). A line that exits non-zero is reported with its output and the
script exits 1. ``--with-tests`` also runs the block that runs the test suite (minutes);
``--keep`` leaves the clone for inspection. ``tests/test_docs.py`` runs the same ``sh`` blocks
in-process on every test run; this script is the newcomer's literal path, run before a release
(docs/design.md, "Documentation that runs").
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```\s*$", re.S | re.M)


def shell_lines(readme: str, with_tests: bool) -> list[str]:
    """The command lines of the README's console blocks, then of its sh blocks, in order."""
    found = [(m[1].strip().split()[0] if m[1].strip() else "", m[2])
             for m in FENCE.finditer(readme)]
    lines = []
    for kind in ("console", "sh"):
        for info, body in found:
            if info != kind:
                continue
            for line in body.replace("\\\n", " ").splitlines():
                line = line.split(" #")[0].strip() if not line.lstrip().startswith("#") else ""
                if line and (with_tests or "pytest" not in line):
                    lines.append(line)
    return lines


def bare_path() -> str:
    """This machine's PATH without any virtual environment's folders (nothing activated)."""
    return os.pathsep.join(d for d in os.environ.get("PATH", "/usr/bin:/bin").split(os.pathsep)
                           if not (Path(d).parent / "pyvenv.cfg").exists())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--with-tests", action="store_true")
    ap.add_argument("--keep", action="store_true")
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="readme_literal_"))
    clone = work / "knit_nlp"
    subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
    failed = 0
    try:
        for line in shell_lines((clone / "README.md").read_text(), args.with_tests):
            t0 = time.perf_counter()
            run = subprocess.run(["bash", "-c", line], cwd=clone, capture_output=True,
                                 text=True, env={"PATH": bare_path(), "HOME": str(work)})
            took = time.perf_counter() - t0
            print(f"[{'ok' if run.returncode == 0 else 'FAILED'} {took:6.1f} s] {line}",
                  flush=True)
            if run.returncode != 0:
                failed += 1
                print((run.stdout + run.stderr)[-2000:])
    finally:
        if args.keep:
            print(f"clone kept in {clone}")
        else:
            shutil.rmtree(work, ignore_errors=True)
    print("every line ran as written" if not failed else f"{failed} line(s) failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
