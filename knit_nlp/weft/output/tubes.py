"""The yarn in three dimensions as a tube of radius r (issue 39, item 3): the tube's surface
around each course's centreline, as rings and as a triangle mesh (the PNG:
:mod:`knit_nlp.weft.output.picture3d`; the files: :mod:`knit_nlp.weft.output.files3d`).

Every function takes plain arrays, so any model that has space curves can use it:
``centrelines`` (m courses, n wales, S samples, 3) in the problem's length unit, each loop's
samples from its start to its end (a loop's last sample is the next loop's first, as the planar
model's ``.npz`` arrays have them); ``radius`` the yarn's radius r in that unit.

The tube is the surface swept by a circle of radius r in the plane normal to the centreline:
ring q around centreline point c_q is c_q + r (cos α u_q + sin α v_q), with (t_q, u_q, v_q) a
rotation-minimising frame (the double-reflection method of Wang, Jüttler, Zheng and Liu,
ACM TOG 27(1), 2008), so rings do not twist along the yarn and every vertex lies at distance r
from its centreline point, in the plane normal to the tangent there (tangents by central
differences, second order at the ends). The ends are left open.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SIDES = 12                  # vertices per ring of a tube
FACE_BUDGET = 40_000        # the oblique view's tube faces: samples are thinned to stay below


def check_centrelines(centrelines: np.ndarray, radius: float) -> np.ndarray:
    """``centrelines`` as a float array (m, n, S, 3), or ValueError naming what is wrong."""
    c = np.asarray(centrelines, dtype=float)
    if c.ndim != 4 or c.shape[-1] != 3 or c.shape[2] < 2 or 0 in c.shape:
        raise ValueError("centrelines must be (courses, wales, samples >= 2, 3); got shape "
                         f"{c.shape}")
    if not np.isfinite(c).all():
        raise ValueError("centrelines hold NaN or infinite coordinates")
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"the yarn radius must be a positive number; got {radius!r}")
    return c


def course_path(course: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One course's loops (n, S, 3) as a single polyline, and the wale (0-based) of each of its
    points: a loop's first sample is dropped where it repeats the previous loop's last."""
    scale = max(float(np.ptp(course.reshape(-1, 3), axis=0).max()), 1.0)
    pts, wale = [course[0]], [np.zeros(len(course[0]), dtype=int)]
    for j, loop in enumerate(course[1:], start=1):
        same = np.linalg.norm(loop[0] - pts[-1][-1]) <= 1e-12 * scale
        pts.append(loop[1:] if same else loop)
        wale.append(np.full(len(pts[-1]), j))
    return np.concatenate(pts), np.concatenate(wale)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot products of (..., 3) arrays, kept as (..., 1)."""
    return np.einsum("...i,...i->...", a, b)[..., None]


def unit_tangents(path: np.ndarray) -> np.ndarray:
    """Unit tangents of polylines (..., P, 3) by central differences (second-order one-sided
    at the ends)."""
    t = np.gradient(path, axis=-2, edge_order=2 if path.shape[-2] > 2 else 1)
    norm = np.linalg.norm(t, axis=-1, keepdims=True)
    if np.any(norm <= 0):
        raise ValueError("a centreline has two equal consecutive samples: no tangent there")
    return t / norm


def rotation_minimising_frames(path: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normals u and binormals v (..., P, 3) along polylines (..., P, 3) with unit tangents t,
    by double reflection (Wang et al. 2008, algorithm 1): u is carried from sample to sample
    by the reflection in the bisector plane of the chord, then in that of the tangents; each u
    is made exactly normal to its tangent (Gram-Schmidt) against rounding. Polylines of one
    length are carried together (the loop runs along the samples only)."""
    helper = np.eye(3)[np.argmin(np.abs(t[..., 0, :]), axis=-1)]
    u = np.empty_like(path)
    first = np.cross(t[..., 0, :], helper)
    u[..., 0, :] = first / np.linalg.norm(first, axis=-1, keepdims=True)
    for q in range(path.shape[-2] - 1):
        v1 = path[..., q + 1, :] - path[..., q, :]
        c1 = _dot(v1, v1)
        r_l = u[..., q, :] - (2.0 / c1) * _dot(v1, u[..., q, :]) * v1
        t_l = t[..., q, :] - (2.0 / c1) * _dot(v1, t[..., q, :]) * v1
        v2 = t[..., q + 1, :] - t_l
        c2 = _dot(v2, v2)
        turn = c2 > 1e-30                   # tangents that do not turn: one reflection
        nxt = np.where(turn, r_l - (2.0 / np.where(turn, c2, 1.0)) * _dot(v2, r_l) * v2, r_l)
        nxt -= _dot(nxt, t[..., q + 1, :]) * t[..., q + 1, :]
        u[..., q + 1, :] = nxt / np.linalg.norm(nxt, axis=-1, keepdims=True)
    return u, np.cross(t, u)


def tube_rings(path: np.ndarray, radius: float, sides: int = SIDES) -> np.ndarray:
    """The tubes' vertices (..., P, sides, 3) about polylines (..., P, 3): ring q is
    path[q] + r (cos α u_q + sin α v_q), α = 2πk/sides."""
    t = unit_tangents(path)
    u, v = rotation_minimising_frames(path, t)
    a = 2 * np.pi * np.arange(sides) / sides
    return path[..., None, :] + radius * (np.cos(a)[:, None] * u[..., None, :]
                                          + np.sin(a)[:, None] * v[..., None, :])


@dataclass(frozen=True)
class TubeMesh:
    """Triangulated tubes of every course: ``points`` (N, 3), ``triangles`` (T, 3) indices into
    them, and for each point its course and wale (0-based) and the centreline point its ring is
    centred on (``centres``, (N, 3))."""

    points: np.ndarray
    triangles: np.ndarray
    course: np.ndarray
    wale: np.ndarray
    centres: np.ndarray


def _ring_triangles(rings: int, sides: int, offset: int) -> np.ndarray:
    """Two triangles per quad between consecutive rings (counter-clockwise seen from outside
    for rings that go counter-clockwise about the tangent)."""
    q, k = np.meshgrid(np.arange(rings - 1), np.arange(sides), indexing="ij")
    a = offset + q * sides + k
    b = offset + q * sides + (k + 1) % sides
    c, d = a + sides, b + sides
    return np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3),
                           np.stack([a, d, c], -1).reshape(-1, 3)])


def tube_mesh(centrelines: np.ndarray, radius: float, sides: int = SIDES) -> TubeMesh:
    """The tubes of radius ``radius`` around every course's centreline (one tube per course,
    open at its ends), as a triangle mesh."""
    c = check_centrelines(centrelines, radius)
    paths = [course_path(course) for course in c]
    rings: dict[int, np.ndarray] = {}
    for size in {len(p) for p, _ in paths}:          # courses of one length: one batch
        same = [i for i, (p, _) in enumerate(paths) if len(p) == size]
        rings.update(zip(same, tube_rings(np.stack([paths[i][0] for i in same]), radius, sides)))
    pts, tris, course, wale, centres = [], [], [], [], []
    offset = 0
    for i, (path, w) in enumerate(paths):
        pts.append(rings[i].reshape(-1, 3))
        centres.append(np.repeat(path, sides, axis=0))
        course.append(np.full(len(path) * sides, i))
        wale.append(np.repeat(w, sides))
        tris.append(_ring_triangles(len(path), sides, offset))
        offset += len(path) * sides
    return TubeMesh(np.concatenate(pts), np.concatenate(tris), np.concatenate(course),
                    np.concatenate(wale), np.concatenate(centres))


def course_colours(m: int) -> np.ndarray:
    """RGBA (m, 4) of courses 1..m: viridis, as the plan view's course key."""
    import matplotlib
    return matplotlib.colormaps["viridis"]((np.arange(m) + 0.5) / m)


def thinned(centrelines: np.ndarray, sides: int = SIDES,
            budget: int = FACE_BUDGET) -> tuple[np.ndarray, int]:
    """The centrelines with every k-th sample of each loop (its ends kept) so that their tubes
    have at most ``budget`` faces, and k."""
    m, n, s, _ = centrelines.shape
    step = max(1, int(np.ceil(m * n * (s - 1) * sides / budget)))
    keep = np.unique(np.r_[np.arange(0, s, step), s - 1])
    return centrelines[:, :, keep], step
