"""Pictures that hid what they draw (issue 41, "Docs and pictures"): the animation's legend and
grips, the sweep's coinciding grips, the control picture's start over the natural shape, the
course key's ticks, the jacquard panels' key and their stretch, the yarn's thickness."""
from __future__ import annotations

import numpy as np
import pytest

from imagecheck import check_explained
from knit_nlp.problems import resolve
from knit_nlp.weft.model.centrelines import natural_centrelines
from knit_nlp.weft.model.problem import load_problem
from knit_nlp.weft.output.plot import animate, course_ticks, held_points
from problem_texts import small_pull


@pytest.mark.parametrize("courses", range(1, 160))
def test_course_key_ticks_are_evenly_spaced_course_numbers(courses):
    """Every course up to ten; beyond, at most ten ticks, all courses, one round step
    (1, 2 or 5 x 10^k) apart: not the uneven 1, 4, 7, 11, ... of rounded equal divisions."""
    ticks = course_ticks(courses)
    assert 1 <= ticks.min() and ticks.max() <= courses and len(ticks) <= 10
    if courses <= 10:
        assert list(ticks) == list(range(1, courses + 1))
        return
    steps = set(np.diff(ticks))
    assert len(steps) == 1, ticks
    step = steps.pop()
    assert step / 10 ** np.floor(np.log10(step)) in (1, 2, 5)
    assert courses - ticks.max() < step and ticks.min() == step


def test_animation_frames_hold_their_legend_and_draw_the_grips_where_they_hold(
        tmp_path, saved_figures, monkeypatch):
    """Every GIF frame's texts (legend included) lie inside the frame and name the grips, its
    course key is ticked at whole courses (it had 0.5, 1.0, 1.5, ...); the grips drawn in a
    frame are at the held material points of that frame's loops: for the natural loops, the
    problem's natural positions of its clamps."""
    from knit_nlp.weft.output import plot
    ticks = []
    grab = plot.PillowWriter.grab_frame

    def recording(self, **kwargs):
        bar = [ax for ax in self.fig.axes if ax.get_label() == "<colorbar>"][0]
        low, high = bar.get_ylim()
        ticks.append([t for t in bar.get_yticks() if low <= t <= high])
        return grab(self, **kwargs)
    monkeypatch.setattr(plot.PillowWriter, "grab_frame", recording)
    pr = load_problem(resolve("hold_top_pull_corner"))
    natural = natural_centrelines(pr, 121)
    moved = natural + np.array([0.5, -0.25])
    frames = [("natural", natural), ("a long title " * 8, moved)]
    animate(tmp_path / "a.gif", natural, frames, pr.units, problem=pr)
    assert len(saved_figures.frames) == 2
    for frame in saved_figures.frames:
        check_explained(frame)
        assert any("clamp[1] (8 points)" in t for t in frame.legend), frame.legend
        assert "point clamp" in frame.legend
    bars, singles = held_points(pr, natural)
    grouped = [c for c in pr.clamps if c.expanded]
    exact = np.array([pr.natural_position(c.loop, c.s) for c in grouped])
    np.testing.assert_allclose(bars[0][1], exact, atol=2e-3 * pr.L)
    exact = np.array([pr.natural_position(c.loop, c.s) for c in pr.clamps if not c.expanded])
    np.testing.assert_allclose(singles, exact, atol=2e-3 * pr.L)
    np.testing.assert_allclose(held_points(pr, moved)[1], exact + [0.5, -0.25], atol=2e-3 * pr.L)
    animate(tmp_path / "b.gif", natural[:4], [("4 courses", natural[:4])], pr.units)
    assert ticks == [list(range(1, pr.courses + 1))] * 2 + [[1, 2, 3, 4]], ticks


UNITS = {"material.k_b": "N/mm", "material.k_a": "N/mm"}


def _sweep_summary(forces: dict[str, list[float]], others: list[float] | None = None) -> dict:
    """A sweep summary over k_b = 0.01, 0.02, 0.03 (and, with ``others``, a second key)."""
    points = []
    for second in others or [None]:
        for q, kb in enumerate((0.01, 0.02, 0.03)):
            label = {"material.k_b": kb} | ({} if second is None else {"material.k_a": second})
            points.append({"path": f"p{q}", "index": q, "label": label, "success": True,
                           "status": "ok", "energy": {"total": 1.0 + q},
                           "grips": {g: [f[q] * (second or 1.0), 0.0] for g, f in forces.items()}})
    return {"points": points}


def test_sweep_overview_tells_coinciding_grips_apart(tmp_path, saved_figures):
    """Two clamps pulling with equal force magnitudes (a two-clamp pull) are drawn in two
    colours (each colour's pixels in the force panel), the second named as lying on the first;
    with a second key each combination keeps one colour, a grip its line style."""
    from imagecheck import near, pixels_in_axes, read_rgb
    from knit_nlp.studies.overview import plot_overview
    png = plot_overview(tmp_path / "s.png", _sweep_summary({"clamp[1]": [1, 2, 4],
                                                             "clamp[2]": [1, 2, 4]}),
                        ["material.k_b"], "test", key_units=UNITS)
    rgb = read_rgb(png)
    force = saved_figures.axes["s.png"][1]
    for colour in ("#1f77b4", "#ff7f0e"):                  # C0, C1
        assert len(pixels_in_axes(force, near(rgb, colour, 0.08))) > 100, colour
    legend = saved_figures.explained("s.png").legend
    assert "clamp[2] (equal to clamp[1]: its line lies on clamp[1]'s)" in legend, legend
    assert "clamp[1]" in legend
    png = plot_overview(tmp_path / "t.png", _sweep_summary({"clamp[1]": [1, 2, 4],
                                                             "clamp[2]": [1, 3, 5]}, [1.0, 2.0]),
                        ["material.k_b", "material.k_a"], "test", key_units=UNITS)
    legend = saved_figures.explained("t.png").legend
    assert "clamp[2], material.k_a = 1.0" in legend, legend


def test_control_picture_names_the_natural_shape_as_the_start_when_they_coincide(tmp_path,
                                                                                  saved_figures):
    """place_stitch starts from the natural fabric: one drawing named for both (the dashed
    start lay exactly on the natural loops and hid them); a start a thousandth of the extent
    away is its own shape."""
    from knit_nlp.cli import main
    from knit_nlp.weft.inverse.plot import same_shape
    assert main(["control", "place_stitch", "--out", str(tmp_path)]) == 0
    legend = saved_figures.explained("place_stitch.control.png").legend
    assert "natural, also the start (before control)" in legend, legend
    assert "natural" not in legend and "start (before control)" not in legend
    natural = natural_centrelines(load_problem(resolve("hold_top_pull_corner")))
    extent = np.ptp(natural.reshape(-1, 2), axis=0).max()
    assert same_shape(natural, natural + 1e-8 * extent)
    assert not same_shape(natural, natural + 1e-3 * extent)


def test_jacquard_panels_have_a_key_and_draw_a_small_stretch_magnified():
    """The fabric panels' key names the pillar loops, the red underlaps, the shaded cells and
    the blue inlay; a displacement of 0.01 mm (far below a pixel) is drawn as arrows magnified
    to about 1.5 wale spacings (x100 here, a round factor), from each particle's natural place
    to natural + 100 u, and the key says by how much."""
    from matplotlib.patches import PathPatch
    from knit_nlp.jacquard import load_problem as load_jacquard, solve_static
    from knit_nlp.jacquard.render import ARROW_COLOUR, figure
    from knit_nlp.jacquard.springs import natural_positions
    result = solve_static(load_jacquard(resolve("jacquard_letter_k")))
    fig, axes = figure(result)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    for words in ("pillar loop (ground yarn)", "fall-plate underlap, thick (front bar)",
                  "cell with a thick front (shaded; net: none)", "inlay underlap, thin"):
        assert any(words in label for label in labels), (words, labels)
    p = result.problem
    natural = natural_positions(p)
    u = np.zeros_like(natural)
    u[:, 1] = 0.01 * natural[:, 1] / natural[:, 1].max()          # 0.01 mm at the top
    fig, axes = figure(type(result)(**{**vars(result), "positions": natural + u}))
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert f"drawn x100 (largest {0.01:.3g} mm)" in labels[-1], labels
    arrows = [a for a in axes["simulated"].patches if isinstance(a, PathPatch)
              and a.get_facecolor()[:3] == pytest.approx((0x11 / 255,) * 3)]
    assert len(arrows) == 1 and ARROW_COLOUR == "#111111"
    verts = arrows[0].get_path().vertices.reshape(-1, 6, 2)
    moved = u[:, 1] > 0                                            # zero arrows are left out
    np.testing.assert_allclose(verts[:, 0], natural[moved], atol=1e-12)
    np.testing.assert_allclose(verts[:, 2], natural[moved] + 100 * u[moved], atol=1e-12)


def test_the_yarn_is_drawn_as_wide_as_it_is(tmp_path, saved_figures):
    """With ``--yarn`` the picture shows the yarn's width 2r, not the centreline's line width:
    0.7 r to either side of a deformed centreline (outside its 1.8 pt line, inside the band)
    the picture is at least half as dark as on the centreline (median over the samples; the
    band was a faint 0.3 alpha under the line: the yarn looked as thin as the line)."""
    import json
    from imagecheck import read_rgb, to_pixels
    from knit_nlp.cli import main
    r = 0.3
    problem = tmp_path / "small.toml"
    problem.write_text(SMALL_PULL + f"[yarn]\nradius = {r}\n")
    out = tmp_path / "out"
    assert main(["solve", str(problem), "--out", str(out), "--yarn"]) == 0
    assert json.loads((out / "small.full.json").read_text())["success"]
    lines = np.load(out / "small.full.npz")["deformed"]
    rgb = read_rgb(out / "small.full.png")
    dark = 1.0 - rgb @ np.array([0.299, 0.587, 0.114])
    ax = saved_figures.axes["small.full.png"][0]
    ratios = []
    for course in lines:
        c = np.concatenate(list(course))[5:-5]                  # away from the clamped ends
        t = np.gradient(c, axis=0)
        n = np.column_stack([-t[:, 1], t[:, 0]]) / np.hypot(*t.T)[:, None]

        def at(pts):
            px = np.round(to_pixels(ax, pts, rgb.shape[0]) - 0.5).astype(int)
            return dark[px[:, 1], px[:, 0]]
        centre = at(c)
        side = np.minimum(at(c + 0.7 * r * n), at(c - 0.7 * r * n))
        ratios.append(side / np.maximum(centre, 1e-3))
    assert 0.7 * r * ax.transform[0, 0] > 4.0                     # the band is wider than the line
    assert np.median(np.concatenate(ratios)) > 0.5, np.median(np.concatenate(ratios))


SMALL_PULL = small_pull("small")


def test_the_solution_pictures_course_key_uses_the_even_ticks():
    """The solution picture's colourbar of 30 courses is ticked 5, 10, ..., 30 (it was 1, 4,
    7, 11, 14, ...)."""
    from matplotlib.collections import LineCollection
    from knit_nlp.figures import new_figure
    from knit_nlp.units import Units
    from knit_nlp.weft.output.plot import colour_key
    fig = new_figure()
    ax = fig.subplots()
    mapped = LineCollection([np.zeros((2, 2))] * 30, array=np.arange(1, 31))
    mapped.set_clim(0.5, 30.5)
    ax.add_collection(mapped)
    colour_key(fig, ax, mapped, "course", 30, Units())
    bar = [a for a in fig.axes if a.get_label() == "<colorbar>"][0]
    assert list(bar.get_yticks()) == [5, 10, 15, 20, 25, 30]
