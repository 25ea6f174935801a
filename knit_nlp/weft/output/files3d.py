"""The yarn in three dimensions as files other programs open (issue 39, item 3), written with
meshio (a maintained mesh I/O library; the package writes no mesh format by hand):

- ``<stem>.yarn.vtu``, a VTK unstructured grid for ParaView: one polyline per course (VTK
  line cells between consecutive samples) with the point arrays ``radius`` (the yarn's radius
  r at every point), ``course`` and ``wale`` (1-based) and the cell array ``course``; designed
  crossings, if given, as vertex cells (their points carry course 0, wale 0). In ParaView:
  Extract Surface, then Tube with "Vary Radius: By Absolute Scalar" on ``radius`` (radius
  factor 1) draws the yarn at its true thickness.
- ``<stem>.tube.ply``, the tubes' triangle mesh (:func:`tubes.tube_mesh`) with vertex colours
  (red, green, blue: the course key's viridis) and a ``course`` property, for Blender (File >
  Import > Stanford PLY) and ParaView; coordinates as float32, at most about MESH_VERTICES
  vertices (a large fabric's loops thinned to every k-th sample; the .vtu keeps them all).

Lengths are in the problem's length unit (VTK and PLY carry none; the caller says which).
Input: centrelines (m courses, n wales, S samples, 3) as in :mod:`knit_nlp.weft.output.tubes`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...atomic import temporary_path
from .tubes import SIDES, check_centrelines, course_colours, course_path, thinned, tube_mesh

MESH_VERTICES = 2_000_000      # a .ply's tubes have at most about this many vertices


def polyline_arrays(centrelines: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every course as one polyline: points (N, 3), line cells (N - m, 2) between consecutive
    points of a course, and each point's course and wale (1-based)."""
    pts, lines, course, wale = [], [], [], []
    offset = 0
    for i, loops in enumerate(centrelines):
        path, w = course_path(loops)
        idx = offset + np.arange(len(path))
        pts.append(path)
        lines.append(np.stack([idx[:-1], idx[1:]], axis=1))
        course.append(np.full(len(path), i + 1))
        wale.append(w + 1)
        offset += len(path)
    return (np.concatenate(pts), np.concatenate(lines), np.concatenate(course),
            np.concatenate(wale))


def _write(path: Path, mesh, file_format: str, **kwargs) -> Path:
    """``mesh`` written by meshio to a temporary name beside ``path``, then renamed."""
    import meshio
    with temporary_path(Path(path)) as tmp:
        meshio.write(tmp, mesh, file_format=file_format, **kwargs)
    return Path(path)


def write_centrelines_vtu(path: Path, centrelines: np.ndarray, radius: float,
                          crossings: np.ndarray | None = None) -> Path:
    """``path`` (.vtu): the courses as polylines with the point array ``radius`` (module
    docstring), crossings (k, 3) as vertex cells."""
    import meshio
    c = check_centrelines(centrelines, radius)
    pts, lines, course, wale = polyline_arrays(c)
    x = np.empty((0, 3)) if crossings is None else np.asarray(crossings, dtype=float).reshape(-1, 3)
    cells = [("line", lines)]
    cell_course = [course[lines[:, 0]].astype(np.int32)]
    if len(x):
        cells.append(("vertex", (len(pts) + np.arange(len(x)))[:, None]))
        cell_course.append(np.zeros(len(x), dtype=np.int32))
        pts = np.concatenate([pts, x])
        course, wale = np.r_[course, np.zeros(len(x), int)], np.r_[wale, np.zeros(len(x), int)]
    mesh = meshio.Mesh(pts, cells,
                       point_data={"radius": np.full(len(pts), float(radius)),
                                   "course": course.astype(np.int32),
                                   "wale": wale.astype(np.int32)},
                       cell_data={"course": cell_course})
    return _write(path, mesh, "vtu")


def write_tube_ply(path: Path, centrelines: np.ndarray, radius: float, sides: int = SIDES,
                   vertices: int = MESH_VERTICES) -> Path:
    """``path`` (.ply, binary, float32 coordinates): the tubes of radius r as triangles, vertex
    colours by course. Tubes that would have more than ``vertices`` vertices are built on
    every k-th sample of each loop (its ends kept: ``tubes.thinned``); a 100 x 100 fabric of
    61 samples per loop is written on every 4th (81 MB instead of 410 MB)."""
    import meshio
    c, _ = thinned(check_centrelines(centrelines, radius), sides, vertices)
    tube = tube_mesh(c, radius, sides)
    rgb = np.round(255 * course_colours(len(c))[tube.course, :3]).astype(np.uint8)
    mesh = meshio.Mesh(tube.points.astype(np.float32),
                       [("triangle", tube.triangles.astype(np.int32))],
                       point_data={"red": rgb[:, 0], "green": rgb[:, 1], "blue": rgb[:, 2],
                                   "course": (tube.course + 1).astype(np.int32)})
    return _write(path, mesh, "ply", binary=True)


def write_yarn_3d(stem: Path, centrelines: np.ndarray, radius: float,
                  crossings: np.ndarray | None = None) -> list[Path]:
    """``<stem>.yarn.vtu`` (ParaView) and ``<stem>.tube.ply`` (Blender): the module's docstring."""
    stem = Path(stem)
    return [write_centrelines_vtu(stem.with_name(stem.name + ".yarn.vtu"), centrelines, radius,
                                  crossings),
            write_tube_ply(stem.with_name(stem.name + ".tube.ply"), centrelines, radius)]
