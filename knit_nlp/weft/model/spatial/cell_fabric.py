"""A clamped specimen whose material is the 3-D model's periodic cell: two scales in one NLP
(FE², docs/real_fabric.md, "The clamped specimen of cells").

The uniaxial cell (``periodic``) is a fabric with no edges and no clamps: its spacing across the
pull is free (uniaxial stress) or, ``held``, fixed (plane strain). A measured specimen is
neither: the wale specimen is 95.9 mm wide between clamps 45.3 mm apart, held at its clamped
edges and free at its sides. Here the specimen is a mesh of linear triangles in its reference
plane, and every triangle is one periodic cell whose lattice follows the triangle's
deformation gradient (the Cauchy-Born rule):

    F_e = [x_j − x_i, x_k − x_i] [X_j − X_i, X_k − X_i]⁻¹            (E1)
    a₁ = F_e A₁,  a₂ = F_e A₂                                         (E2)
    w = |a₁|,  s = a₁·a₂ / w,  c = (a₁ × a₂) / w                      (E3)

A₁ the course period (the relaxed cell's w₀ along the fabric's courses), A₂ the wale period
(c₀ along its wales); (w, c, s) the cell's lattice in its own frame, a₁ along x (a rigid
rotation of the triangle changes nothing). The specimen's energy is the cells' energies over
their areas,

    U = Σ_e (A_e / (w₀ c₀)) · U_cell(y_e; w_e, c_e, s_e)              (E4)

minimised over the free nodes x and every cell's own loop y_e = (a, b, σ_u, σ_l), with each
cell's rows (closure, N2, its wraps' closest points; ``periodic.cell_expressions``). The bottom
clamp's nodes are fixed, the top clamp's moved by the travel δ along the pull and held across
it; the sides are free. The force is the travel row's multiplier, F = dU/dδ (the envelope
theorem), in N when the mesh is in mm and the cell's energy in N·mm.

Each cell keeps its own equilibrium, so the cells' non-uniqueness (``periodic``) is every
triangle's: a pull is stepped and warm-started, as the uniaxial cell's.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ....ipopt import succeeded
from ..compression import SoftShell
from .natural3d import Natural3D
from .periodic import DIRECTIONS, cell_expressions, cell_solver_options

SAMPLES = 48                    # other-contact samples per loop (the uniaxial cell's 80: its
                                # held wale pull 2 % stiffer at 10 %; docs/real_fabric.md)
REACH = 1.6                     # other pairs listed: naturally closer than REACH · 2r (the
                                # uniaxial cell's 2.5: the same forces and narrowing to 20 %)

TOL = 1e-9


@dataclass(frozen=True)
class Mesh:
    """A rectangle ``width`` (across the pull, X) by ``height`` (along it, Y) in mm, split into
    nx × ny rectangles of two triangles each, the diagonals alternating (a criss-cross that keeps
    the mesh's left-right symmetry); node (i, j) is ``j·(nx + 1) + i``."""

    width: float
    height: float
    nx: int
    ny: int
    nodes: np.ndarray            # (N, 2) reference positions, mm
    triangles: np.ndarray        # (E, 3) node indices, counter-clockwise

    @property
    def bottom(self) -> np.ndarray:
        return np.arange(self.nx + 1)

    @property
    def top(self) -> np.ndarray:
        return np.arange(self.nx + 1) + self.ny * (self.nx + 1)

    def areas(self) -> np.ndarray:
        P = self.nodes[self.triangles]
        d1, d2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
        return 0.5 * (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])


def specimen_mesh(width: float, height: float, nx: int, ny: int, grading: float = 1.0) -> Mesh:
    """The rectangle's criss-cross mesh (``Mesh``); with ``grading`` g > 1 the rows shrink by g
    from the middle toward each clamp (where the clamps' hold on the width decays)."""
    if nx < 1 or ny < 1 or width <= 0 or height <= 0 or grading < 1:
        raise ValueError("the mesh needs a positive size, at least one square each way and "
                         "a grading of at least 1")
    k = np.minimum(np.arange(ny), np.arange(ny)[::-1]).astype(float)   # rows from a clamp
    rows = grading ** k
    ys = np.concatenate([[0.0], np.cumsum(rows)]) / rows.sum() * height
    X, Y = np.meshgrid(np.linspace(0, width, nx + 1), ys)
    nodes = np.column_stack([X.ravel(), Y.ravel()])
    tris = []
    for j in range(ny):
        for i in range(nx):
            a, b = j * (nx + 1) + i, j * (nx + 1) + i + 1
            c, d = a + nx + 1, b + nx + 1
            left = (i < nx / 2) == (j % 2 == 0)
            tris += [(a, b, d), (a, d, c)] if left else [(a, b, c), (b, d, c)]
    return Mesh(width, height, nx, ny, nodes, np.array(tris, dtype=int))


def lattice_vectors(direction: str, w0: float, c0: float) -> tuple[np.ndarray, np.ndarray]:
    """(A₁, A₂) in the specimen's frame (X across the pull, Y along it), right-handed: pulled
    along the wales, the courses run across (A₁ = (w₀, 0), A₂ = (0, c₀)); pulled along the
    courses, A₁ = (0, w₀) and A₂ = (−c₀, 0)."""
    if direction not in DIRECTIONS:
        raise ValueError(f"direction must be one of {DIRECTIONS}, not {direction!r}")
    if direction == "wales":
        return np.array([w0, 0.0]), np.array([0.0, c0])
    return np.array([0.0, w0]), np.array([-c0, 0.0])


def cell_lattice(F: ca.MX, A1: np.ndarray, A2: np.ndarray) -> tuple[ca.MX, ca.MX, ca.MX]:
    """(w, c, s) of the cell under deformation gradient F (E2, E3)."""
    a1, a2 = ca.mtimes(F, ca.DM(A1)), ca.mtimes(F, ca.DM(A2))
    w = ca.norm_2(a1)
    return w, (a1[0] * a2[1] - a1[1] * a2[0]) / w, ca.dot(a1, a2) / w


@dataclass
class CellFabric:
    """The clamped specimen's NLP (module docstring): z = (free nodes' X, Y, every cell's y,
    the travel δ); p = (δ, R_f, k)."""

    mesh: Mesh
    direction: str
    spacings: tuple[float, float]      # the reference cell's (w₀, c₀)
    cell_unknowns: int
    free: np.ndarray                   # the nodes that are unknowns
    solver: ca.Function
    positions: ca.Function             # z -> (N, 2) node positions
    lattices: ca.Function              # z -> (E, 3) each cell's (w, c, s)
    lbz: np.ndarray
    ubz: np.ndarray

    def start(self, y_rest: np.ndarray) -> np.ndarray:
        """z at the reference: nodes unmoved, every cell the reference cell ``y_rest``."""
        free = self.mesh.nodes[self.free].ravel()
        cells = np.tile(y_rest, len(self.mesh.triangles))
        return np.concatenate([free, cells, [0.0]])

    def cells(self, z: np.ndarray) -> np.ndarray:
        """(E, cell unknowns): every cell's y at z."""
        n = 2 * self.free.size
        return z[n:n + self.cell_unknowns * len(self.mesh.triangles)].reshape(
            len(self.mesh.triangles), self.cell_unknowns)


def build_cell_fabric(shape: Natural3D, law: SoftShell, direction: str, mesh: Mesh,
                      spacings: tuple[float, float], samples: int = SAMPLES,
                      straight: bool = False, thin: bool = False, reach: float = REACH,
                      max_iter: int = 300, max_time: float | None = None) -> CellFabric:
    """The NLP of ``mesh`` clamped at its bottom and top, pulled along ``direction``, its
    cells the periodic cell of ``shape`` and ``law`` (``periodic.cell_expressions``) at the
    reference lattice ``spacings`` = (w₀, c₀)."""
    n = len(shape.s_upper)
    ny = len(shape.coeffs) + len(shape.elevation) + 2 * n
    y, lat = ca.MX.sym("y", ny), ca.MX.sym("lattice", 3)
    R_f, k = ca.MX.sym("R_f"), ca.MX.sym("k")
    ex = cell_expressions(shape, law, y, (lat[0], lat[1], lat[2]), R_f, k, samples, straight,
                          reach, thin)
    # the energy and the rows as two Functions: the rows' Jacobian then never differentiates
    # the other pairs' sum (one Function of both: 0.84 s per Jacobian on 64 cells)
    cell_U = ca.Function("cell_energy", [y, lat, R_f, k], [ex.energy])
    cell_g = ca.Function("cell_rows", [y, lat], [ca.vertcat(*ex.rows)])
    clamped = np.zeros(len(mesh.nodes), dtype=bool)
    clamped[mesh.bottom] = clamped[mesh.top] = True
    free = np.flatnonzero(~clamped)
    E = len(mesh.triangles)
    z = ca.MX.sym("z", 2 * free.size + ny * E + 1)
    p = ca.MX.sym("p", 3)                                   # (δ, R_f, k)
    delta = z[-1]
    pos = [None] * len(mesh.nodes)
    for m, i in enumerate(free):
        pos[i] = z[2 * m:2 * m + 2]
    for i in mesh.bottom:
        pos[i] = ca.DM(mesh.nodes[i])
    for i in mesh.top:
        pos[i] = ca.DM(mesh.nodes[i]) + ca.vertcat(0, delta)
    A1, A2 = lattice_vectors(direction, *spacings)
    weight = mesh.areas() / (spacings[0] * spacings[1])     # cells per triangle (E4)
    lats = []
    base = 2 * free.size
    for i, j, m in mesh.triangles:
        ref = np.column_stack([mesh.nodes[j] - mesh.nodes[i], mesh.nodes[m] - mesh.nodes[i]])
        F = ca.mtimes(ca.horzcat(pos[j] - pos[i], pos[m] - pos[i]), ca.DM(np.linalg.inv(ref)))
        lats.append(ca.vertcat(*cell_lattice(F, A1, A2)))
    Y = ca.reshape(z[base:base + ny * E], ny, E)
    LAT = ca.horzcat(*lats)
    U, G = cell_U.map(E)(Y, LAT, p[1], p[2]), cell_g.map(E)(Y, LAT)
    energy = ca.mtimes(U, ca.DM(weight))
    g = ca.vertcat(ca.vec(G), delta - p[0])                 # the cells' rows, the travel
    lbz, ubz = np.full(z.numel(), -np.inf), np.full(z.numel(), np.inf)
    sig = np.arange(ny - 2 * n, ny)                          # each cell's σ_u, σ_l
    for e in range(E):
        lbz[base + ny * e + sig], ubz[base + ny * e + sig] = 0.0, shape.length
    solver = ca.nlpsol("cell_fabric", "ipopt", {"x": z, "p": p, "f": energy, "g": g},
                       cell_solver_options(TOL, max_iter, max_time))
    positions = ca.Function("positions", [z], [ca.horzcat(*pos).T])
    return CellFabric(mesh, direction, tuple(spacings), ny, free, solver, positions,
                      ca.Function("lattices", [z], [LAT.T]), lbz, ubz)


@dataclass(frozen=True)
class FabricSolution:
    """One solve of the clamped specimen: state z, energy U (N·mm), force F (N) through the
    clamps."""

    z: np.ndarray
    U: float
    F: float
    success: bool
    status: str
    iterations: int


def solve_cell_fabric(fab: CellFabric, travel: float, R_f: float, k: float,
                      z0: np.ndarray) -> FabricSolution:
    """The specimen with its top clamp moved ``travel`` mm along the pull, from z0."""
    sol = fab.solver(x0=z0, p=[travel, R_f, k], lbx=fab.lbz, ubx=fab.ubz, lbg=0.0, ubg=0.0)
    st = fab.solver.stats()
    return FabricSolution(np.asarray(sol["x"]).ravel(), float(sol["f"]),
                          -float(sol["lam_g"][-1]), succeeded(st["return_status"]),
                          st["return_status"], int(st["iter_count"]))


def locate(mesh: Mesh, point: np.ndarray) -> tuple[int, np.ndarray]:
    """The triangle holding reference ``point`` and its barycentric coordinates."""
    for e, tri in enumerate(mesh.triangles):
        P = mesh.nodes[tri]
        T = np.column_stack([P[1] - P[0], P[2] - P[0]])
        l12 = np.linalg.solve(T, point - P[0])
        lam = np.array([1 - l12.sum(), *l12])
        if lam.min() >= -1e-12:
            return e, lam
    raise ValueError(f"{point} is outside the specimen")


def displaced(fab: CellFabric, z: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Where reference ``points`` (K, 2) are at state z (linear in each triangle)."""
    x = np.asarray(fab.positions(z))
    out = []
    for q in np.atleast_2d(points):
        e, lam = locate(fab.mesh, q)
        out.append(lam @ x[fab.mesh.triangles[e]])
    return np.array(out)
