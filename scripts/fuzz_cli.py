"""Hostile-user generator for ``knit-nlp`` (issue 13): bad problem files and command lines for
both models, plus small valid problems, checked against the contract.

Contract checked per case (each in its own forked process, like a fresh ``knit-nlp`` run):
- a bad case exits 2 with exactly one printable line on stderr, nothing on stdout, and writes
  nothing at all (not even the --out folder);
- a valid case exits 0 or 1, with nothing on stderr (no warnings, no traceback), and writes only
  ``<name>.*`` files inside --out;
- no case writes outside its workspace (decoy absolute names are checked), and none runs longer
  than ``--timeout`` seconds.

    python scripts/fuzz_cli.py [--seed 0] [--cases 200] [--more] [--timeout 60] [--keep]

The default run (150 cases) takes about a minute on the 2-core development machine (shared); ``--more``
runs 5x as many.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import struct
import sys
import tempfile
import time
import traceback
import zlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

# imported once here, so that every forked case starts warm (the CLI imports these lazily)
import matplotlib.image  # noqa: E402,F401
import knit_nlp.jacquard.render  # noqa: E402,F401
import knit_nlp.jacquard.summary  # noqa: E402,F401
import knit_nlp.weft.api  # noqa: E402,F401
import knit_nlp.weft.output.plot  # noqa: E402,F401
import knit_nlp.weft.output.summary  # noqa: E402,F401
from knit_nlp.cli import main  # noqa: E402

DECOY = Path(tempfile.gettempdir()) / "knit_fuzz_decoy"


@dataclass
class Case:
    """One generated run: files to create, the command line, whether it is valid input."""

    kind: str
    valid: bool
    argv: list[str]
    files: dict[str, bytes | str] = field(default_factory=dict)
    special: list[tuple[str, str]] = field(default_factory=list)   # (kind, relative path)


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return {float("inf"): "inf", float("-inf"): "-inf"}.get(v, "nan" if v != v else repr(v))
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return json.dumps(v)               # JSON string escapes are valid TOML basic strings
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    raise TypeError(v)


def to_toml(doc: dict) -> str:
    """A small TOML writer for generated documents (tables, arrays of tables, scalars)."""
    lines = [f"{json.dumps(k)} = {toml_value(v)}" for k, v in doc.items()
             if not isinstance(v, (dict,)) and not (isinstance(v, list) and v and isinstance(v[0], dict))]

    def table(prefix: str, t: dict, array: bool = False) -> None:
        lines.append(f"[[{prefix}]]" if array else f"[{prefix}]")
        subs = []
        for k, v in t.items():
            if isinstance(v, dict):
                subs.append((k, v))
            else:
                lines.append(f"{json.dumps(k)} = {toml_value(v)}")
        for k, v in subs:
            table(f"{prefix}.{json.dumps(k)}", v)

    for k, v in doc.items():
        if isinstance(v, dict):
            table(json.dumps(k), v)
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for item in v:
                table(json.dumps(k), item, array=True)
    return "\n".join(lines) + "\n"


def weft_doc(rng: random.Random) -> dict:
    m, n = rng.randint(1, 3), rng.randint(1, 3)
    point = (rng.choice(["H", "E", "start"]) if m >= 2 else
             "end" if n == 1 else rng.choice(["start", "end"]))
    dx, dy = rng.uniform(-1, 1), rng.uniform(-0.5, 0.5)
    return {"name": f"w{rng.randint(0, 999)}", "fabric": {"courses": m, "wales": n},
            "clamp": [{"loop": [1, 1], "point": "start", "position": [0.0, 0.0]},
                      {"loop": [m, n], "point": point, "displacement": [dx, dy]}],
            "solver": {"max_iter": 300}}


DESIGNS = ["##++\n##++\n++##\n++##", "+..+\n+..+\n.++.\n.++.", "####\n####\n####\n####",
           "....\n....\n....\n...."]


def jacquard_doc(rng: random.Random) -> dict:
    return {"name": f"j{rng.randint(0, 999)}", "model": "jacquard",
            "fabric": {"wales": 4, "courses": 4, "dz": 10.0, "dh": 8.0},
            "fall_plate": {"design": rng.choice(DESIGNS)},
            "inlay": {"design": rng.choice(DESIGNS)},
            "solver": {"method": rng.choice(["static", "explicit"]), "max_steps": 3000}}


INT_KEYS = {"weft": [("fabric", "courses"), ("fabric", "wales"), ("loop", "harmonics"),
                     ("loop", "quadrature_nodes"), ("solver", "max_iter"),
                     ("solver", "continuation")],
            "jacquard": [("fabric", "wales"), ("fabric", "courses"), ("solver", "max_iter"),
                         ("solver", "max_steps"), ("fall_plate.span", "thick")]}
FLOAT_KEYS = {"weft": [("loop", "length"), ("material", "k_a"), ("material", "k_b"),
                       ("material", "R_f"), ("solver", "tol"), ("solver", "max_time"),
                       ("loop", "course_spacing")],
              "jacquard": [("fabric", "dz"), ("fabric", "dh"), ("fabric", "damping"),
                           ("fabric", "mass"), ("fabric", "dt"), ("ground", "pretension"),
                           ("ground", "stiffness"), ("solver", "tol"), ("solver", "max_time"),
                           ("fabric", "lambda_max")]}
HUGE_INTS = [99999999999999999999, 10 ** 30, 2 ** 63, 10 ** 12, -(10 ** 20), 10 ** 400]
BAD_FLOATS = [1e308, -1e308, float("inf"), float("-inf"), float("nan"), 10 ** 30, 10 ** 400,
              -1.0]             # (0 is allowed for stiffnesses and damping: see "range" below)
BAD_NAMES = [str(DECOY / "abs"), "../evil", "a/b", "..", "e\x1b[2Jvil", "n\x00ul", "x" * 300,
             "\x07bell", " x", "c:\\evil"]


def put(doc: dict, table: str, key: str, value) -> None:
    t = doc
    for part in table.split("."):
        t = t.setdefault(part, {})
    t[key] = value


def png(width: int, height: int, rows: int = 1) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    raw = zlib.compress(b"\0" * (width + 1) * min(rows, height), 9)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0))
            + chunk(b"IDAT", raw) + chunk(b"IEND", b""))


def bad_problem(rng: random.Random) -> Case:
    model = rng.choice(["weft", "jacquard"])
    doc = weft_doc(rng) if model == "weft" else jacquard_doc(rng)
    doc["solver"].pop("method", None) if model == "weft" else None
    kind = rng.choice(["name", "huge int", "bad float", "size", "wrong type", "unknown key",
                       "design path", "file", "range"])
    files: dict[str, bytes | str] = {}
    special: list[tuple[str, str]] = []
    if kind == "name":
        doc["name"] = rng.choice(BAD_NAMES)
    elif kind == "huge int":
        put(doc, *rng.choice(INT_KEYS[model]), rng.choice(HUGE_INTS))
    elif kind == "bad float":
        put(doc, *rng.choice(FLOAT_KEYS[model]), rng.choice(BAD_FLOATS))
        if model == "weft" and doc.get("loop", {}).get("course_spacing") == 0.0:
            pass
    elif kind == "size":
        if model == "weft":
            size = rng.choice([(1000, 1000), (400, 400), (100000, 100), (200, 200, 20)])
            doc["fabric"] = {"courses": size[0], "wales": size[1]}
            if len(size) == 3:
                doc["loop"] = {"harmonics": size[2]}
            doc["clamp"] = doc["clamp"][:1]
        else:
            side = rng.choice([1200, 3000, 100000])
            doc["fabric"].update(wales=side, courses=side)
    elif kind == "wrong type":
        table, key = rng.choice(INT_KEYS[model] + FLOAT_KEYS[model])
        put(doc, table, key, rng.choice(["1", [1, 2], True, "nan"]))
    elif kind == "unknown key":
        table = rng.choice(["", "fabric", "solver"])
        key = rng.choice(["colour", "\x1b[2J", "k\x00ey", "x" * 200, "wales "])
        if table:
            doc[table][key] = 1
        else:
            doc[key] = 1
    elif kind == "design path":
        model = "jacquard"
        doc = jacquard_doc(rng)
        sub = rng.choice(["/dev/zero", "/etc/shadow", "../outside.txt", "zero.txt", "fifo.txt",
                          "huge.txt", "bomb.png", "binary.txt", "missing.txt", "."])
        key = "design_image" if sub.endswith(".png") else "design_file"
        doc["fall_plate"] = {key: sub}
        if sub == "zero.txt":
            special.append(("symlink:/dev/zero", "prob/zero.txt"))
        elif sub == "fifo.txt":
            special.append(("fifo", "prob/fifo.txt"))
        elif sub == "huge.txt":
            special.append(("sparse:9437184", "prob/huge.txt"))
        elif sub == "bomb.png":
            files["prob/bomb.png"] = png(20000, 20000)
        elif sub == "binary.txt":
            files["prob/binary.txt"] = bytes(rng.randrange(256) for _ in range(64))
        files["outside.txt"] = "####\n" * 4
    elif kind == "file":
        what = rng.choice(["syntax", "binary", "empty", "fifo", "devzero", "big", "digits"])
        argv_problem = {"fifo": "prob/p.toml", "devzero": "/dev/zero"}.get(what, "prob/p.toml")
        if what == "fifo":
            special.append(("fifo", "prob/p.toml"))
        elif what == "big":
            special.append(("sparse:2097152", "prob/p.toml"))
        elif what != "devzero":
            files["prob/p.toml"] = {"syntax": "[fabric\ncourses = = 2\n", "empty": "",
                                    "binary": bytes(rng.randrange(256) for _ in range(200)),
                                    "digits": "[fabric]\ncourses = " + "9" * 5000 + "\n"}[what]
        return Case(f"bad file: {what}", False, ["solve", argv_problem, "--out", "out"], files,
                    special)
    else:   # range: zero / negative where positive is required
        table, key = rng.choice([("fabric", "courses"), ("fabric", "wales"), ("solver", "max_time"),
                                 ("solver", "tol"), ("solver", "max_iter")]
                                + ([("loop", "length"), ("solver", "continuation")]
                                   if model == "weft" else [("fabric", "dz"), ("fabric", "dt")]))
        put(doc, table, key, rng.choice([0, -3, -1.5, 0.0]))
    files["prob/p.toml"] = to_toml(doc)
    return Case(f"bad {model}: {kind}", False, ["solve", "prob/p.toml", "--out", "out"], files,
                special)


def bad_arguments(rng: random.Random) -> Case:
    model = rng.choice(["weft", "jacquard"])
    doc = weft_doc(rng) if model == "weft" else jacquard_doc(rng)
    files: dict[str, bytes | str] = {"prob/p.toml": to_toml(doc), "afile": "keep"}
    kind = rng.choice(["continuation", "out", "flags", "problem"])
    argv = ["solve", "prob/p.toml", "--out", "out"]
    if kind == "continuation":
        argv += ["--continuation", rng.choice(["0", "-3", "x", "1e3", "1001", "", "2.5"])]
        if model == "jacquard" and rng.random() < 0.5:
            argv[-1] = "2"        # a valid count, but weft-only
    elif kind == "out":
        argv[3] = rng.choice(["afile", "afile/sub", "/proc/version/x", "/sys/knit_fuzz",
                              "x" * 300, ""])
    elif kind == "flags":
        argv += rng.choice([["--reduced", "--full"], ["--bogus"], ["--solver", "explicitt"],
                            ["--svg"] if model == "weft" else ["--reduced"],
                            ["--solver", "static"] if model == "weft" else ["--warm-from-reduced"]])
    else:
        argv = rng.choice([["solve"], ["solve", "nonexistent_problem"], ["frobnicate"],
                           ["solve", "x" * 5000], ["solve", "\x1b[2J"], [],
                           ["compare", "prob/p.toml", "--out", "out"] if model == "jacquard"
                           else ["list", "extra"]])
    return Case(f"bad arguments ({model}): {kind}", False, argv, files)


def valid(rng: random.Random) -> Case:
    model = rng.choice(["weft", "weft", "jacquard"])
    doc = weft_doc(rng) if model == "weft" else jacquard_doc(rng)
    argv = ["solve", "prob/p.toml", "--out", "out"]
    if model == "weft" and rng.random() < 0.3:
        argv += ["--continuation", str(rng.randint(1, 3))]
    if model == "jacquard" and rng.random() < 0.3:
        argv.append("--svg")
    if rng.random() < 0.15:
        doc["solver"]["max_time"] = 0.001          # runs out of time: exit 1
    if model == "jacquard" and rng.random() < 0.15:
        doc["fabric"].update(dt=50.0, damping=0.0)
        doc["solver"]["method"] = "explicit"         # diverges: exit 1
    return Case(f"valid {model}", True, argv, {"prob/p.toml": to_toml(doc)})


def generate(rng: random.Random) -> Case:
    r = rng.random()
    return bad_problem(rng) if r < 0.55 else bad_arguments(rng) if r < 0.8 else valid(rng)


def materialise(case: Case, work: Path) -> None:
    (work / "prob").mkdir(parents=True)
    for rel, content in case.files.items():
        path = work / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(content if isinstance(content, bytes) else content.encode())
    for what, rel in case.special:
        path = work / rel
        if what == "fifo":
            os.mkfifo(path)
        elif what.startswith("symlink:"):
            path.symlink_to(what.split(":", 1)[1])
        elif what.startswith("sparse:"):
            with open(path, "wb") as fh:
                fh.truncate(int(what.split(":", 1)[1]))


def listing(work: Path) -> set[str]:
    return {str(p.relative_to(work)) for p in work.rglob("*")}


def run_case(case: Case, work: Path, timeout: float) -> tuple[int | None, str, str, float]:
    """Fork, run the CLI in ``work`` with stdout/stderr to files; (exit code or None if it timed
    out, stdout, stderr, seconds)."""
    out_path, err_path = work.parent / f"{work.name}.stdout", work.parent / f"{work.name}.stderr"
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:                                   # child: behave like `knit-nlp ARGV`
        code = 70
        try:
            os.chdir(work)
            for fd, p in ((1, out_path), (2, err_path)):
                f = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
                os.dup2(f, fd)
            sys.stdout = os.fdopen(1, "w", buffering=1)
            sys.stderr = os.fdopen(2, "w", buffering=1)
            code = main(case.argv)
        except SystemExit as stop:
            code = stop.code if isinstance(stop.code, int) else 1
        except BaseException:
            traceback.print_exc()
            code = 70
        finally:
            try:
                sys.stdout.flush()
                sys.stderr.flush()
            finally:
                os._exit(code)
    deadline = t0 + timeout
    code = None
    while time.perf_counter() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            code = os.waitstatus_to_exitcode(status)
            break
        time.sleep(0.01)
    else:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
    took = time.perf_counter() - t0
    read = lambda p: p.read_text(errors="replace") if p.exists() else ""   # noqa: E731
    return code, read(out_path), read(err_path), took


def check(case: Case, work: Path, before: set[str], result) -> list[str]:
    code, out, err, took = result
    problems = []
    if code is None:
        return [f"hang (> {took:.0f} s)"]
    new = listing(work) - before
    if "Traceback" in err:
        problems.append("traceback: " + err.strip().splitlines()[-1][:120])
    if case.valid:
        if code not in (0, 1):
            problems.append(f"exit {code} for a valid problem: {err.strip()[:160]!r}")
        if err.strip() and "Traceback" not in err:
            problems.append(f"stderr not empty: {err.strip()[:160]!r}")
        stray = [p for p in new if not (p == "out" or p.startswith("out/"))]
        if stray:
            problems.append(f"wrote outside --out: {stray[:3]}")
    else:
        if code != 2:
            problems.append(f"exit {code}, expected 2 (stderr {err.strip()[:120]!r})")
        lines = err.strip().splitlines()
        if len(lines) != 1:
            problems.append(f"{len(lines)} lines on stderr")
        elif not lines[0].isprintable() or not lines[0].startswith("knit-nlp:"):
            problems.append(f"unprintable or unprefixed message {lines[0][:120]!r}")
        if out.strip():
            problems.append(f"stdout not empty: {out.strip()[:80]!r}")
        if new:
            problems.append(f"wrote {sorted(new)[:3]} for bad input")
    if any(DECOY.parent.glob(DECOY.name + "*")):
        problems.append("wrote a decoy absolute path")
    return problems


def main_fuzz() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--cases", type=int, default=150)
    ap.add_argument("--more", action="store_true", help="5x as many cases")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds per case")
    ap.add_argument("--keep", action="store_true", help="keep the workspaces")
    args = ap.parse_args()
    rng = random.Random(args.seed)
    n = args.cases * (5 if args.more else 1)
    root = Path(tempfile.mkdtemp(prefix=f"knit_fuzz_{args.seed}_"))
    for stale in DECOY.parent.glob(DECOY.name + "*"):
        shutil.rmtree(stale) if stale.is_dir() else stale.unlink()
    counts, violations, codes, times = Counter(), [], Counter(), []
    t0 = time.perf_counter()
    for k in range(n):
        case = generate(rng)
        work = root / f"case{k:04d}"
        materialise(case, work)
        before = listing(work)
        result = run_case(case, work, args.timeout)
        found = check(case, work, before, result)
        counts[case.kind.split(":")[0]] += 1
        times.append((result[3], case.kind))
        codes[(case.valid, result[0])] += 1
        if found:
            violations.append((k, case.kind, case.argv, found))
    took = time.perf_counter() - t0
    print(f"seed {args.seed}: {n} cases in {took:.0f} s; violations: {len(violations)}")
    for group, count in sorted(counts.items()):
        print(f"  {group:<28} {count:4d}")
    print("  exit codes: " + ", ".join(f"{'valid' if v else 'bad'} -> {c}: {k}"
                                       for (v, c), k in sorted(codes.items(), key=str)))
    print("  slowest: " + ", ".join(f"{kind} {t:.1f} s" for t, kind in sorted(times)[-3:]))
    for k, kind, argv, found in violations[:40]:
        print(f"  VIOLATION case {k} [{kind}] argv={[a[:40] for a in argv]}: {'; '.join(found)}")
    if not args.keep:
        shutil.rmtree(root, ignore_errors=True)
    else:
        print(f"  workspaces kept in {root}")
    raise SystemExit(1 if violations else 0)


if __name__ == "__main__":
    main_fuzz()
