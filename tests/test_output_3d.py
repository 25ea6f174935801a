"""The yarn in three dimensions as a tube (issue 39, item 3): the tube's geometry against closed
forms, the files ParaView and Blender open read back by meshio as written, and the PNG's
panels drawn at the true thickness."""
from __future__ import annotations

import meshio
import numpy as np
import pytest

from imagecheck import read_rgb, saturated
from knit_nlp.weft.output.files3d import write_yarn_3d
from knit_nlp.weft.output.picture3d import plot_tubes
from knit_nlp.weft.output.tubes import tube_mesh, unit_tangents, rotation_minimising_frames


def circle_courses(R: float, courses: int, wales: int, samples: int, pitch: float) -> np.ndarray:
    """Courses along 0.9 of the circle of radius R about the z axis, at heights pitch·i, each
    split into ``wales`` loops whose ends are the next loops' starts."""
    t = np.linspace(0.0, 1.8 * np.pi, wales * (samples - 1) + 1)
    out = np.empty((courses, wales, samples, 3))
    for i in range(courses):
        for j in range(wales):
            tj = t[j * (samples - 1):(j + 1) * (samples - 1) + 1]
            out[i, j] = np.column_stack([R * np.cos(tj), R * np.sin(tj), np.full_like(tj, pitch * i)])
    return out


def test_tube_vertices_lie_at_distance_r_from_the_centreline():
    """Tubes about circles of radius R at heights z_i: a vertex's distance to its own course's
    circle is sqrt((ρ - R)² + (z - z_i)²) in closed form and equals r (away from the two end
    rings, where the tangent is one-sided); every triangle faces outwards; each course's tube
    has 2·sides triangles per segment."""
    R, r, sides = 3.0, 0.2, 10
    c = circle_courses(R, courses=2, wales=3, samples=21, pitch=1.0)
    tube = tube_mesh(c, r, sides)
    rho = np.hypot(tube.points[:, 0], tube.points[:, 1])
    dist = np.hypot(rho - R, tube.points[:, 2] - tube.course * 1.0)
    ends = np.zeros(len(dist), bool)
    for i in range(2):
        idx = np.flatnonzero(tube.course == i)
        ends[idx[:sides]] = ends[idx[-sides:]] = True
    assert np.max(np.abs(dist[~ends] - r)) < 1e-12 * R
    assert np.max(np.abs(dist[ends] - r)) < 1e-3 * r
    assert len(tube.triangles) == 2 * sides * 2 * (3 * 20)    # 2 courses of 3 x 20 segments
    a, b, d = (tube.points[tube.triangles[:, k]] for k in range(3))
    normal = np.cross(b - a, d - a)
    centroid = (a + b + d) / 3
    outward = centroid - tube.centres[tube.triangles[:, 0]]
    assert np.all(np.einsum("ij,ij->i", normal, outward) > 0)


def helix_frame_error(samples: int, R: float = 1.0, p: float = 0.4) -> float:
    """The largest error of the frames' turning along the helix (R cos t, R sin t, p t),
    t in [0, 4π], against the closed form (see the test below), ends excluded."""
    t = np.linspace(0.0, 4 * np.pi, samples)
    path = np.column_stack([R * np.cos(t), R * np.sin(t), p * t])
    tan = unit_tangents(path)
    u, _ = rotation_minimising_frames(path, tan)
    N = -np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])
    B = np.cross(tan, N)
    angle = np.unwrap(np.arctan2(np.einsum("ij,ij->i", u, B), np.einsum("ij,ij->i", u, N)))
    expected = angle[1] - p / (R ** 2 + p ** 2) * np.hypot(R, p) * (t - t[1])
    return float(np.max(np.abs(angle[1:-1] - expected[1:-1])))


def test_frames_along_a_helix_rotate_against_the_frenet_normal_at_the_torsion_rate():
    """A rotation-minimising frame turns against the Frenet frame at the torsion τ: along the
    helix (R cos t, R sin t, p t), τ = p / (R² + p²), arc length s = t √(R² + p²), so the angle
    from the principal normal N = -(cos t, sin t, 0) to u grows by -τ s (closed form). Double
    reflection is fourth order (measured 2.5e-7 at 201 samples, 1.6e-8 at 401); one
    reflection alone is third order (5.2e-6, 6.3e-7)."""
    coarse, fine = helix_frame_error(201), helix_frame_error(401)
    assert coarse < 1e-6 and coarse / fine > 12, (coarse, fine)


def stockinette_like(m: int, n: int, r: float, samples: int = 41) -> np.ndarray:
    """A synthetic fabric: loops (x = j w + w s - b sin 2πs, y = i h + a (1 - cos 2πs),
    z = r sin 4πs), s in [0, 1], each loop starting where the previous one ends."""
    s = np.linspace(0.0, 1.0, samples)
    w, h, a, b = 2.0, 1.6, 1.1, 0.5
    c = np.empty((m, n, samples, 3))
    for i in range(m):
        for j in range(n):
            c[i, j] = np.column_stack([j * w + w * s - b * np.sin(2 * np.pi * s),
                                       i * h + a * (1 - np.cos(2 * np.pi * s)),
                                       r * np.sin(4 * np.pi * s)])
    return c


def test_files_read_back_as_written(tmp_path):
    """meshio reads the .vtu back with one point per distinct centreline sample, a line cell
    between every two consecutive samples of a course, the radius at every point, the
    crossings as vertex cells; and the .ply with the tube mesh's points and triangles."""
    r = 0.15
    c = stockinette_like(3, 3, r)
    crossings = c[:, :, [10, 30]].reshape(-1, 3)
    vtu, ply = write_yarn_3d(tmp_path / "fabric", c, r, crossings)
    assert (vtu.name, ply.name) == ("fabric.yarn.vtu", "fabric.tube.ply")
    mesh = meshio.read(vtu)
    courses = [np.concatenate([c[i, 0]] + [c[i, j, 1:] for j in range(1, 3)]) for i in range(3)]
    expected = np.concatenate(courses + [crossings])
    np.testing.assert_allclose(mesh.points, expected, rtol=0, atol=1e-15)
    lines = mesh.cells_dict["line"]
    start = np.cumsum([0] + [len(p) for p in courses])
    want = np.concatenate([np.column_stack([np.arange(a, b - 1), np.arange(a + 1, b)])
                           for a, b in zip(start[:-1], start[1:])])
    np.testing.assert_array_equal(lines, want)
    np.testing.assert_array_equal(mesh.point_data["radius"], np.full(len(expected), r))
    np.testing.assert_array_equal(mesh.cells_dict["vertex"].ravel(),
                                  start[-1] + np.arange(len(crossings)))
    np.testing.assert_array_equal(mesh.point_data["course"][:start[-1]],
                                  np.repeat([1, 2, 3], [len(p) for p in courses]))
    tube = tube_mesh(c, r)
    read = meshio.read(ply)
    np.testing.assert_array_equal(read.points, tube.points.astype(np.float32))
    np.testing.assert_array_equal(read.cells_dict["triangle"], tube.triangles)
    np.testing.assert_array_equal(read.point_data["course"], tube.course + 1)
    from knit_nlp.weft.output.files3d import write_tube_ply
    small = meshio.read(write_tube_ply(tmp_path / "small.ply", c, r, vertices=2000))
    kept = c[:, :, list(range(0, 40, 3)) + [40]]   # 9 loops x 40 segments x 12 sides / 2000: every 3rd
    assert len(small.points) <= 2000
    np.testing.assert_array_equal(small.points, tube_mesh(kept, r).points.astype(np.float32))


@pytest.mark.parametrize("bad", [np.zeros((3, 3, 5, 2)), np.full((2, 2, 5, 3), np.nan)])
def test_bad_centrelines_are_refused(tmp_path, bad):
    with pytest.raises(ValueError, match="centrelines"):
        write_yarn_3d(tmp_path / "x", bad, 0.1)


def test_picture_shows_the_tube_at_its_thickness(tmp_path, saved_figures):
    """The PNG (8 x 8.5 in at 110 dpi) has three panels with coloured pixels, explains itself
    (units on the axes, the yarn and the crossings in the legend), and in the side view
    along +y, straight courses along x at z = 0 show coloured pixels over a height of 2r at the
    axes' scale (to 2.5 px of 59: an antialiased edge pixel each side may fall below the
    colour threshold, the 0.7 pt outline reaches half a pixel out; 0.8 r would be 12 px off)."""
    r = 0.25
    c = stockinette_like(3, 3, r)
    png = plot_tubes(tmp_path / "t.png", c, r, c[:, :, [10, 30]].reshape(-1, 3), "mm", "test")
    rgb = read_rgb(png)
    assert rgb.shape[:2] == (935, 880)
    panels = saved_figures.axes["t.png"][:3]
    colour = saturated(rgb)
    for ax in panels:
        x0, y0, x1, y1 = ax.box
        box = colour[int(935 - y1):int(935 - y0), int(x0):int(x1)]
        assert box.mean() > 0.02, ax.box
    saved_figures.explained("t.png")

    flat = np.zeros((3, 2, 11, 3))
    x = np.linspace(0.0, 4.0, 21)
    for i in range(3):
        for j in range(2):
            flat[i, j, :, 0], flat[i, j, :, 1] = x[10 * j:10 * j + 11], 1.5 * i
    png = plot_tubes(tmp_path / "flat.png", flat, r, None, "mm")
    side = saved_figures.axes["flat.png"][1]         # the side views come first
    rgb = read_rgb(png)
    x0, y0, x1, y1 = side.box
    rows = np.flatnonzero(saturated(rgb)[int(935 - y1) + 3:int(935 - y0) - 3,
                                         int(0.5 * (x0 + x1))])
    height_px = rows.max() - rows.min() + 1
    px_per_unit = side.transform[1, 1]
    assert abs(height_px - 2 * r * px_per_unit) < 2.5, (height_px, 2 * r * px_per_unit)
