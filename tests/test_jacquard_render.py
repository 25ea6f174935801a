"""The jacquard pictures show the motif: the rendered fabric, sampled cell by cell, correlates
with the design grid far above what the same picture gives against shuffled designs; the
design-grid panels show the designs; the SVG stays small."""
from __future__ import annotations

import json
import re
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest

from knit_nlp.cli import main
from knit_nlp.jacquard import load_problem, parse_problem as parse_jacquard, solve_static
from knit_nlp.tomlio import load_toml
from knit_nlp.jacquard.render import _Tiling, figure

from imagecheck import check_jacquard_picture

PROBLEMS = Path(__file__).resolve().parent.parent / "problems"
README = PROBLEMS.parent / "README.md"
LUMA = np.array([0.299, 0.587, 0.114])


def cell_darkness(fig, ax, p, x: np.ndarray) -> np.ndarray:
    """Mean darkness (1 - luminance) of the rendered pixels over each cell of one repeat
    (averaged over tiles): cell (i, j) is the box P(i,j) +- w/2 across, P(i,j) .. P(i,j) + h
    up, in the panel drawn with positions ``x``; shape (courses, wales)."""
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3] / 255.0
    dark = 1.0 - rgb @ LUMA
    height = dark.shape[0]
    t = _Tiling(p, x)
    total = np.zeros((p.courses, p.wales))
    count = np.zeros((p.courses, p.wales))
    for j in range(t.nc):
        for i in range(t.nw):
            r = t.root(np.array(i), np.array(j))
            (x0, y0), (x1, y1) = ax.transData.transform([r + (-0.4 * p.w, 0.1 * p.h),
                                                         r + (0.4 * p.w, 0.9 * p.h)])
            rows = slice(int(round(height - y1)), int(round(height - y0)))
            cols = slice(int(round(x0)), int(round(x1)))
            total[j % p.courses, i % p.wales] += dark[rows, cols].mean()
            count[j % p.courses, i % p.wales] += 1
    return total / count


def motif_correlation(darkness: np.ndarray, codes: np.ndarray, shuffles: int = 300,
                      seed: int = 0) -> tuple[float, float]:
    """Pearson r of darkness against the design codes, and the largest |r| against the same
    codes shuffled over the cells."""
    r = float(np.corrcoef(darkness.ravel(), codes.ravel())[0, 1])
    rng = np.random.default_rng(seed)
    null = [abs(np.corrcoef(darkness.ravel(), rng.permutation(codes.ravel()))[0, 1])
            for _ in range(shuffles)]
    return r, float(max(null))


@pytest.fixture(scope="module")
def letter_k():
    result = solve_static(load_problem(PROBLEMS / "jacquard_letter_k.toml"))
    assert result.success
    fig, axes = figure(result)
    yield result, fig, axes
    plt.close(fig)


@pytest.mark.parametrize("panel", ["natural", "simulated"])
def test_the_letter_k_can_be_seen(letter_k, panel):
    result, fig, axes = letter_k
    p = result.problem
    x = result.network.natural if panel == "natural" else result.positions
    darkness = cell_darkness(fig, axes[panel], p, x)
    front = p.systems[0].codes
    r, null = motif_correlation(darkness, front)
    print(f"letter K, {panel}: r = {r:.3f}, largest shuffled |r| = {null:.3f}")
    assert r > 0.7 and r > null + 0.3, (r, null)


@pytest.fixture(scope="module")
def arrow():
    result = solve_static(load_problem(PROBLEMS / "jacquard_image.toml"))
    assert result.success
    fig, axes = figure(result)
    yield result, fig, axes
    plt.close(fig)


def test_the_shipped_arrow_can_be_seen(arrow):
    result, fig, axes = arrow
    p = result.problem
    darkness = cell_darkness(fig, axes["simulated"], p, result.positions)
    r, null = motif_correlation(darkness, p.systems[0].codes)
    print(f"arrow, simulated: r = {r:.3f}, largest shuffled |r| = {null:.3f}")
    assert r > 0.7 and r > null + 0.3, (r, null)


def test_design_panels_show_the_designs(arrow):
    """The preview panels are the design grids: pixel darkness at each cell centre is the
    code's grey (thick black, thin grey, net white), for both bars, top row = top course
    (the arrow points up: no symmetry hides a flip)."""
    result, fig, axes = arrow
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3] / 255.0
    height = rgb.shape[0]
    for sys in result.problem.systems:
        ax = axes[sys.name]
        n, m = sys.codes.shape
        jj, ii = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
        px = ax.transData.transform(np.column_stack([ii.ravel() + 1, jj.ravel() + 1]))
        luma = rgb[(height - px[:, 1]).astype(int), px[:, 0].astype(int)] @ LUMA
        expected = np.array([1.0, 0.65, 0.1])[sys.codes.ravel()]
        assert np.allclose(luma, expected, atol=0.1)


def test_readme_letter_k_command(tmp_path, monkeypatch, capsys, saved_figures):
    """The README's jacquard task: the letter K rendered and stretched, run exactly as the
    README writes it (from a scratch folder), printing what the README says it prints."""
    readme = README.read_text()
    command = re.search(r"knit-nlp (solve jacquard_letter_k[^\n`]*)", readme).group(1)
    printed = re.search(r"It prints\s+`(pull top by [^`]*)`", readme).group(1)
    monkeypatch.chdir(tmp_path)
    assert main(command.split()) == 0
    assert printed in capsys.readouterr().out
    data = json.loads((tmp_path / "results" / "jacquard_letter_k.jacquard.json").read_text())
    assert data["success"] and data["pulls"][0]["edge"] == "top"
    final = np.array(data["particles"]["final"])
    assert np.ptp(final[:, 1]) == pytest.approx(15 * 1.0 + 0.3)       # stretched 0.3 mm
    check_jacquard_picture(tmp_path / "results" / "jacquard_letter_k.jacquard.png", data,
                           saved_figures)
    assert (tmp_path / "results" / "jacquard_letter_k.jacquard.svg").stat().st_size < 600_000


def test_the_12_by_12_svg_is_small(tmp_path):
    """The 12 x 12 repeat, tiled 2 x 2, was a 5 MB SVG (one path per yarn, sampled splines)."""
    result = solve_static(load_problem(PROBLEMS / "jacquard_diamond.toml"))
    paths = result.save(tmp_path, svg=True)
    svg = [q for q in paths if q.suffix == ".svg"][0]
    text = svg.read_text()
    assert svg.stat().st_size < 800_000
    assert text.count("<path") < 120       # one compound path per bar, structure and layer
    assert text.count("<image") == 2       # only the two design grids (lossless, 1 px per cell)


@pytest.fixture(scope="module")
def big_k():
    """The letter K scaled to a 40 x 40 patch (every design cell 2.5 x 2.5 cells): the old
    picture drew a 24 x 24 corner window of it, and the K's lower leg was never drawn."""
    doc = load_toml(PROBLEMS / "jacquard_letter_k.toml")
    rows = [r for r in doc["fall_plate"]["design"].split("\n") if r]
    big = ["".join(rows[int(j / 2.5)][int(i / 2.5)] for i in range(40)) for j in range(40)]
    doc["fabric"].update(wales=40, courses=40)
    doc["fall_plate"]["design"] = "\n".join(big)
    doc["inlay"]["design"] = "\n".join(["+" * 40] * 40)
    result = solve_static(parse_jacquard(doc, PROBLEMS / "jacquard_letter_k.toml"))
    assert result.success
    return result


def test_a_40_by_40_design_is_drawn_whole_by_default(big_k):
    fig, axes = figure(big_k)
    p = big_k.problem
    assert "window" not in axes["natural"].get_title()
    darkness = cell_darkness(fig, axes["simulated"], p, big_k.positions)
    r, null = motif_correlation(darkness, p.systems[0].codes, shuffles=100)
    assert darkness.shape == (40, 40) and r > 0.7 and r > null + 0.3, (r, null)
    plt.close(fig)


def test_a_window_is_drawn_only_on_request_and_says_so(big_k):
    fig, axes = figure(big_k, window=20)
    title = axes["natural"].get_title()
    assert "20 x 20 window at the bottom-left corner" in title and "40 x 40" in title
    assert axes["natural"].get_xlim()[1] < 0.6 * 40 * big_k.problem.w
    plt.close(fig)
