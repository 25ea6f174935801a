"""What a run writes and prints (issue 11): pictures checked by their pixels, reactions and loads
on one arrow scale, the loading path (work = stored energy), GIF frames, centreline CSV/SVG,
the overwrite guard, --verbose and --version."""
import csv
import json
import xml.etree.ElementTree as ET

import matplotlib.image as mpimg
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.quiver import Quiver

import knit_nlp
from knit_nlp.cli import main
from knit_nlp.weft.api import solve
from knit_nlp.weft.output.plot import ARROW_FRACTION, DPI, drawn_arrows, round_reference, solution_figure
from knit_nlp.weft.model.problem import load_problem

FABRIC = "[fabric]\ncourses = 3\nwales = 4\n"
PULL = FABRIC + """
[[clamp]]
edge = "left"
displacement = [0.0, 0.0]
[[clamp]]
loop = [3, 4]
point = "end"
direction = 20.0
distance = 3.0
"""
LOADED = FABRIC + """
[[clamp]]
edge = "left"
displacement = [0.0, 0.0]
[[load]]
edge = "right"
direction = 0.0
magnitude = 0.02
"""


def _pixels(fig, ax, pts: np.ndarray) -> np.ndarray:
    """(row, col) of data points in the PNG the figure saves at DPI."""
    fig.canvas.draw()
    disp = ax.transData.transform(pts)
    height = fig.canvas.get_width_height()[1]
    return np.column_stack([height - disp[:, 1], disp[:, 0]]).round().astype(int)


def _near(img: np.ndarray, rc: np.ndarray, colour: np.ndarray, tol: float, r: int = 1) -> bool:
    patch = img[rc[0] - r:rc[0] + r + 1, rc[1] - r:rc[1] + r + 1, :3].reshape(-1, 3)
    return bool(np.min(np.linalg.norm(patch - colour, axis=1)) < tol)


@pytest.mark.parametrize("colour", ["course", "displacement"])
def test_picture_shows_each_deformed_loop_in_its_colour_where_the_result_puts_it(
        write_problem, tmp_path, colour):
    r = solve(load_problem(write_problem(PULL)))
    natural, deformed = r.natural_centrelines(), r.centrelines()
    fig, ax = solution_figure(r, natural, deformed, colour)
    path = tmp_path / "p.png"
    fig.savefig(path, dpi=DPI)
    img = mpimg.imread(path)
    rc = _pixels(fig, ax, deformed.reshape(-1, 2))
    plt.close(fig)
    m, n, k, _ = deformed.shape
    if colour == "course":
        value = np.repeat(np.arange(1, m + 1), n * k)
        expected = plt.get_cmap("viridis")((value - 0.5) / m)[:, :3]
    else:
        mag = np.linalg.norm(deformed - natural, axis=-1).ravel()
        expected = plt.get_cmap("viridis")((mag - mag.min()) / np.ptp(mag))[:, :3]
    hits = [_near(img, p, c, 0.12) for p, c in zip(rc, expected)]
    assert np.mean(hits) > 0.9, np.mean(hits)
    # natural loops in grey where no deformed loop passes within 8 pixels
    nat_rc = _pixels(fig, ax, natural.reshape(-1, 2))
    far = [p for p in nat_rc if np.min(np.abs(rc - p).max(axis=1)) > 8]
    assert len(far) > 50
    assert np.mean([_near(img, p, np.array([0.8, 0.8, 0.8]), 0.08) for p in far]) > 0.9


def test_axes_and_keys_name_their_units(write_problem):
    r = solve(load_problem(write_problem('[units]\nlength = "mm"\nforce = "N"\n' + PULL)))
    fig, ax = solution_figure(r, r.natural_centrelines(), r.centrelines())
    labels = [a.get_ylabel() for a in fig.axes]
    assert ax.get_xlabel() == "x [mm]" and ax.get_ylabel() == "y [mm]" and "course (deformed loops)" in labels
    assert "N·mm" in ax.get_title()
    assert len(fig.legends) == 1
    legend = fig.legends[0]
    fig.canvas.draw()
    # the legend sits outside the fabric's axes
    lb, ab = legend.get_window_extent(), ax.get_window_extent()
    assert lb.y1 <= ab.y0 + 1
    plt.close(fig)


def test_reactions_and_loads_share_one_arrow_scale(write_problem):
    r = solve(load_problem(write_problem(LOADED)))
    assert r.success
    natural, deformed = r.natural_centrelines(), r.centrelines()
    fig, ax = solution_figure(r, natural, deformed)
    quivers = [c for c in ax.collections if isinstance(c, Quiver)]
    plt.close(fig)
    assert len(quivers) == 2                                   # reactions, loads
    arrows = drawn_arrows(r)
    lengths = np.concatenate([np.hypot(q.U, q.V) for q in quivers])
    forces = np.array([np.hypot(*f) for kind in ("reaction", "load")
                       for _, f, k in arrows if k == kind])
    ratio = lengths / forces
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-9)
    size = np.ptp(np.concatenate([natural.reshape(-1, 2), deformed.reshape(-1, 2)]), axis=0).max()
    assert lengths.max() == pytest.approx(ARROW_FRACTION * size)
    # the loads and the reactions balance: both kinds are drawn at about the same total length
    total = {k: sum(np.array(f) for _, f, kk in arrows if kk == k) for k in ("reaction", "load")}
    np.testing.assert_allclose(total["reaction"], -total["load"], atol=1e-6)


def test_negligible_reactions_are_not_drawn(write_problem):
    r = solve(load_problem(write_problem(FABRIC + '[[clamp]]\nedge = "bottom"\npoint = "head"\n'
                                         "displacement = [0.0, 0.0]\n")))
    assert max(np.abs(c.reaction).max() for c in r.clamps) < r.problem.solver.tol
    assert drawn_arrows(r) == []
    fig, ax = solution_figure(r, r.natural_centrelines(), r.centrelines())
    assert not [c for c in ax.collections if isinstance(c, Quiver)]
    plt.close(fig)
    assert [round_reference(v) for v in (0.7, 0.31, 0.0042, 17.0)] == [0.5, 0.2, 0.005, 20.0]


def _work_error(tmp_path, steps: int) -> tuple[float, list[dict]]:
    out = tmp_path / f"s{steps}"
    assert main(["solve", "hold_top_pull_corner", "--continuation", str(steps), "--out",
                 str(out)]) == 0
    rows = list(csv.DictReader((out / "hold_top_pull_corner.full.path.csv").open()))
    pull = [r for r in rows if r["grip"] == "clamp[2]"]
    d = np.array([float(r["distance"]) for r in pull])
    f = np.array([float(r["force_along_pull"]) for r in pull])
    energy = json.loads((out / "hold_top_pull_corner.full.json").read_text())["energy"]["total"]
    return abs(np.trapezoid(f, d) / energy - 1), rows


def test_loading_path_force_does_the_stored_work_and_converges(tmp_path):
    """The pulling clamp's work along the path (trapezoid rule) equals the final stored energy;
    the holding clamps do none; the error falls as the steps are refined (second order)."""
    e4, rows4 = _work_error(tmp_path, 4)
    e8, rows8 = _work_error(tmp_path, 8)
    assert e8 < 0.01 and e8 < e4 / 3, (e4, e8)
    held = [r for r in rows8 if r["grip"] == "clamp[1]"]
    assert all(r["distance"] == "" and float(r["displacement_x"]) == 0.0 for r in held)
    assert len(rows8) == 2 * 9 and rows8[0]["step"] == "0"


def test_animation_has_one_frame_per_step(tmp_path):
    from PIL import Image
    assert main(["solve", "hold_top_pull_corner", "--continuation", "3", "--animate", "--out",
                 str(tmp_path)]) == 0
    with Image.open(tmp_path / "hold_top_pull_corner.full.gif") as gif:
        assert gif.n_frames == 4
        first = np.asarray(gif.convert("RGB"), dtype=float)
        gif.seek(3)
        last = np.asarray(gif.convert("RGB"), dtype=float)
    assert np.abs(first - last).mean() > 1.0          # the fabric moved between frames


def test_animate_without_a_path_is_refused(capsys):
    assert main(["solve", "wada_fig7", "--animate"]) == 2
    assert "--continuation" in capsys.readouterr().err


def test_centreline_csv_and_svg_hold_the_deformed_loops(write_problem, tmp_path):
    path = write_problem(PULL, "e.toml")
    assert main(["solve", str(path), "--export", "csv", "svg", "--out", str(tmp_path)]) == 0
    deformed = np.load(tmp_path / "e.full.npz")["deformed"]
    m, n, k, _ = deformed.shape
    rows = list(csv.DictReader((tmp_path / "e.full.csv").open()))
    assert list(rows[0]) == ["course", "wale", "s", "x", "y"] and len(rows) == m * n * k
    for row in rows[:: 97]:
        i, j = int(row["course"]), int(row["wale"])
        q = int(round(float(row["s"]) / 10.0 * (k - 1)))
        np.testing.assert_allclose([float(row["x"]), float(row["y"])], deformed[i - 1, j - 1, q])
    svg = ET.parse(tmp_path / "e.full.svg").getroot()
    polys = svg.findall(".//{http://www.w3.org/2000/svg}polyline")
    assert [p.get("id") for p in polys] == [f"course-{i}" for i in range(1, m + 1)]
    pts = [np.array([[float(v) for v in xy.split(",")] for xy in p.get("points").split()])
           for p in polys]
    # undo the viewBox offset and the y flip: differences between points are the model's
    course = np.concatenate(list(deformed[1]))
    np.testing.assert_allclose(pts[1] - pts[1][0], (course - course[0]) * [1, -1], atol=2e-4)


def test_result_of_another_problem_is_not_overwritten(tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    a.mkdir(), b.mkdir()
    (a / "same.toml").write_text(PULL)
    (b / "same.toml").write_text(PULL.replace("distance = 3.0", "distance = 2.0"))
    out = str(tmp_path / "out")
    assert main(["solve", str(a / "same.toml"), "--out", out]) == 0
    first = json.loads((tmp_path / "out" / "same.full.json").read_text())
    assert first["source"]["file"] == str((a / "same.toml").resolve())
    capsys.readouterr()
    assert main(["solve", str(b / "same.toml"), "--out", out]) == 2
    err = capsys.readouterr().err
    assert "another problem" in err and "--force" in err and "\n" not in err.strip()
    assert json.loads((tmp_path / "out" / "same.full.json").read_text()) == first
    # the same file again, edited, overwrites; a different file with the same content too
    (a / "same.toml").write_text(PULL.replace("distance = 3.0", "distance = 2.5"))
    assert main(["solve", str(a / "same.toml"), "--out", out]) == 0
    assert main(["solve", str(b / "same.toml"), "--out", out, "--force"]) == 0
    assert json.loads((tmp_path / "out" / "same.full.json").read_text())["source"]["file"] == \
        str((b / "same.toml").resolve())


def test_verbose_shows_every_iterate_on_one_line_and_quiet_shows_none(tmp_path, capsys):
    assert main(["solve", "wada_fig7", "--out", str(tmp_path)]) == 0
    quiet = capsys.readouterr()
    assert quiet.err == ""
    assert main(["solve", "wada_fig7", "--out", str(tmp_path), "--verbose"]) == 0
    err = capsys.readouterr().err
    nit = json.loads((tmp_path / "wada_fig7.full.json").read_text())["iterations"]
    assert err.count("\r") == err.count("IPOPT iterate") == nit + 1     # iterates 0..nit
    assert err.endswith("\n") and err.count("\n") == 1


def test_version(capsys):
    assert main(["--version"]) == 0            # main returns argparse's exit code
    assert capsys.readouterr().out.strip() == f"knit-nlp {knit_nlp.__version__}"


def test_targets_are_drawn_where_they_hold(write_problem):
    """A clamp holding x only is drawn as a bar at its target x (through where the point
    ended); one holding both as a cross at its target; holding clamps draw no target."""
    r = solve(load_problem(write_problem(FABRIC + """
[[clamp]]
edge = "left"
displacement = [0.0, 0.0]
fix = ["x"]
[[clamp]]
loop = [1, 1]
point = "head"
displacement = [0.0, 0.0]
[[clamp]]
edge = "right"
displacement = [2.0, 0.0]
fix = ["x"]
[[clamp]]
loop = [2, 2]
point = "head"
displacement = [0.5, 0.5]
""")))
    assert r.success
    fig, ax = solution_figure(r, r.natural_centrelines(), r.centrelines())
    marks = {line.get_marker(): np.column_stack(line.get_data()) for line in ax.get_lines()
             if line.get_marker() in ("x", "|", "_")}
    plt.close(fig)
    assert set(marks) == {"x", "|"}
    right = [c for c in r.clamps if c.group == "clamp[3]"]
    np.testing.assert_allclose(marks["|"], [[c.target[0], c.position[1]] for c in right])
    np.testing.assert_allclose(marks["x"], [r.clamps[-1].target])
