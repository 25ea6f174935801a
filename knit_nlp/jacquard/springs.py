"""The spring network generated from the designs, and its forces (docs/jacquard.md: "Fabric, particles",
"Bars and designs", "Springs, forces, mass", "Boundaries", "Zero-energy modes").

Particles are numbered ``j*M + i`` (wale ``i``, course ``j``). A spring joins particle ``a`` to
particle ``b`` displaced by ``shift`` (a multiple of the periods ``M*w``, ``N*h`` where the
spring wraps around a periodic repeat), so its far end is at ``x[b] + shift``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .problem import JacquardProblem

KINDS = ("ground", "fall_plate_longitudinal", "fall_plate_thick", "fall_plate_thin",
         "inlay_longitudinal", "inlay_thick", "inlay_thin", "loop_width")


@dataclass(frozen=True)
class SpringSet:
    """All springs of a problem as flat arrays (length ``ns``)."""

    a: np.ndarray          # int, first end
    b: np.ndarray          # int, second end (position x[b] + shift)
    shift: np.ndarray      # (ns, 2) period offsets
    k: np.ndarray          # stiffness
    l_init: np.ndarray     # length in the natural grid
    l0: np.ndarray         # rest length rho * l_init (loop-width springs: l_init)
    limit: np.ndarray      # lambda_max * l_init (inf for loop-width springs)
    compress: np.ndarray   # bool: compression-only loop-width spring (extension)
    kind: np.ndarray       # int index into KINDS

    @property
    def n(self) -> int:
        return int(self.a.size)


@dataclass(frozen=True)
class Network:
    """Springs plus what the solvers need about the particles and boundaries."""

    natural: np.ndarray        # (Np, 2) natural positions (i*w, j*h)
    springs: SpringSet
    fixed: np.ndarray          # bool (Np,): held at the natural position
    order_left: np.ndarray     # order constraint X[right] + offset - X[left] >= 0
    order_right: np.ndarray
    order_offset: np.ndarray
    components: np.ndarray     # (M,) label of each wale's connected component
    floating: list[np.ndarray]  # particle indices of each component holding no fixed particle
    held: np.ndarray           # (Np, 2) where fixed particles are held (natural, or pulled)

    @property
    def zero_modes(self) -> int:
        """Zero-energy modes beyond the removed rigid translation: 2 per floating component."""
        return 2 * len(self.floating)


def natural_positions(p: JacquardProblem) -> np.ndarray:
    """P(i,j) at (i*w, j*h), row ``j*M + i``."""
    jj, ii = np.meshgrid(np.arange(p.courses), np.arange(p.wales), indexing="ij")
    return np.column_stack([ii.ravel() * p.w, jj.ravel() * p.h]).astype(float)


def _link(p: JacquardProblem, i: np.ndarray, j: np.ndarray, di: np.ndarray, dj: int):
    """Springs P(i,j) - P(i+di, j+dj): (a, b, shift) with periodic wrapping or edge dropping."""
    i2, j2 = i + di, j + dj
    if p.boundary == "fixed":
        keep = (i2 >= 0) & (i2 < p.wales) & (j2 >= 0) & (j2 < p.courses)
        i, j, i2, j2 = i[keep], j[keep], i2[keep], j2[keep]
    ib, jb = np.mod(i2, p.wales), np.mod(j2, p.courses)
    shift = np.column_stack([(i2 - ib) * p.w, (j2 - jb) * p.h]).astype(float)
    return j * p.wales + i, jb * p.wales + ib, shift


def zigzag_direction(p: JacquardProblem, j: np.ndarray) -> np.ndarray:
    """d_j of the guide's zigzag: ``zigzag`` on even courses, its opposite on odd ones."""
    return np.where(j % 2 == 0, p.zigzag, -p.zigzag)


def build_springs(p: JacquardProblem) -> SpringSet:
    """Pillar springs, each system's longitudinal springs and underlaps (docs/jacquard.md, "Bars and designs")."""
    m, n = p.wales, p.courses
    jj, ii = np.meshgrid(np.arange(n), np.arange(m), indexing="ij")
    i_all, j_all = ii.ravel(), jj.ravel()
    parts: list[tuple] = []   # (a, b, shift, k, rho, kind)

    def add(a, b, shift, k, rho, kind):
        if k > 0 and a.size:
            parts.append((a, b, shift, np.full(a.size, k), np.full(a.size, rho),
                          np.full(a.size, KINDS.index(kind))))

    a, b, s = _link(p, i_all, j_all, np.zeros_like(i_all), 1)
    add(a, b, s, p.ground_stiffness, p.ground_pretension, "ground")
    for sys in p.systems:
        add(a, b, s, sys.stiffness["longitudinal"], sys.pretension["longitudinal"],
            f"{sys.name}_longitudinal")
        codes = sys.codes.ravel()
        for code, struct in ((2, "thick"), (1, "thin")):
            cell = codes == code
            offset = sys.span[struct] - 1
            if not cell.any() or offset == 0:
                continue
            ci, cj = i_all[cell], j_all[cell]
            la, lb, ls = _link(p, ci, cj, zigzag_direction(p, cj) * offset, 1)
            add(la, lb, ls, sys.stiffness[struct], sys.pretension[struct], f"{sys.name}_{struct}")
    if p.loop_width_stiffness > 0 and m > 1:
        la, lb, ls = _link(p, i_all, j_all, np.ones_like(i_all), 0)
        add(la, lb, ls, p.loop_width_stiffness, 1.0, "loop_width")
    a, b, shift, k, rho, kind = (np.concatenate(c) for c in zip(*parts))
    nat = natural_positions(p)
    l_init = np.hypot(*(nat[b] + shift - nat[a]).T)
    compress = kind == KINDS.index("loop_width")
    limit = np.where(compress, np.inf, p.lambda_max * l_init)
    return SpringSet(a.astype(np.int64), b.astype(np.int64), shift, k, l_init, rho * l_init,
                     limit, compress, kind)


def _order_pairs(p: JacquardProblem) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs for X(i+1,j) - X(i,j) >= 0 (paper 3.4.1), wrapping with offset M*w if periodic."""
    m, n = p.wales, p.courses
    last = m if p.boundary == "periodic" and m > 1 else m - 1
    jj, ii = np.meshgrid(np.arange(n), np.arange(last), indexing="ij")
    i, j = ii.ravel(), jj.ravel()
    right = np.mod(i + 1, m)
    return j * m + i, j * m + right, np.where(i + 1 >= m, m * p.w, 0.0)


def edge_particles(p: JacquardProblem, edge: str) -> np.ndarray:
    """Particle indices of a fabric edge. A corner belongs to the bottom or top edge (both are
    always held with a fixed boundary), so a left or right edge is courses 1..N-2 only."""
    grid = np.arange(p.n_particles).reshape(p.courses, p.wales)
    rows = {"bottom": grid[0], "top": grid[-1], "left": grid[1:-1, 0], "right": grid[1:-1, -1]}
    return rows[edge]


def _fixed_mask(p: JacquardProblem) -> np.ndarray:
    fixed = np.zeros(p.n_particles, dtype=bool)
    if p.boundary == "periodic":
        fixed[0] = True               # P(0,0): removes the rigid translation
    else:
        for e in p.fixed_edges:
            fixed[edge_particles(p, e)] = True
    return fixed


def held_positions(p: JacquardProblem) -> np.ndarray:
    """Natural positions with every pulled edge moved by its displacement ([[pull]])."""
    x = natural_positions(p)
    for pull in p.pulls:
        x[edge_particles(p, pull.edge)] += pull.displacement
    return x


def wale_components(p: JacquardProblem, s: SpringSet) -> np.ndarray:
    """Label the wales by connected component of the spring graph (union-find over wales).

    Every wale is one chain (pillar springs), so particle connectivity reduces to which wales
    the lateral (underlap, loop-width) springs join.
    """
    parent = list(range(p.wales))

    def root(u: int) -> int:
        while parent[u] != u:
            parent[u] = parent[parent[u]]
            u = parent[u]
        return u

    wa, wb = s.a % p.wales, s.b % p.wales
    for u, v in set(zip(wa[wa != wb].tolist(), wb[wa != wb].tolist())):
        ru, rv = root(u), root(v)
        if ru != rv:
            parent[max(ru, rv)] = min(ru, rv)
    return np.array([root(u) for u in range(p.wales)])


def build_network(p: JacquardProblem) -> Network:
    """Springs, natural grid, boundary, order pairs and zero-energy-mode detection."""
    s = build_springs(p)
    fixed = _fixed_mask(p)
    comp = wale_components(p, s)
    wale_of = np.arange(p.n_particles) % p.wales
    anchored = set(comp[wale_of[fixed]].tolist())
    floating = [np.flatnonzero(comp[wale_of] == c) for c in sorted(set(comp.tolist()))
                if c not in anchored]
    left, right, off = _order_pairs(p)
    return Network(natural_positions(p), s, fixed, left, right, off, comp, floating,
                   held_positions(p))


def spring_geometry(x: np.ndarray, s: SpringSet) -> tuple[np.ndarray, np.ndarray]:
    """Spring vectors d = x[b] + shift - x[a] and lengths."""
    d = x[s.b] + s.shift - x[s.a]
    return d, np.hypot(d[:, 0], d[:, 1])


def tensions(length: np.ndarray, s: SpringSet) -> np.ndarray:
    """Rope law: k(l - l0)+ (tension only); loop-width springs push: -k(l0 - l)+."""
    stretch = np.where(s.compress, -np.maximum(s.l0 - length, 0.0), np.maximum(length - s.l0, 0.0))
    return s.k * stretch


def spring_energy(x: np.ndarray, s: SpringSet) -> float:
    """Sum of 1/2 k (l - l0)+^2 (and 1/2 k (l0 - l)+^2 for loop-width springs)."""
    _, length = spring_geometry(x, s)
    return float(0.5 * np.sum(tensions(length, s) ** 2 / s.k))


def accumulate(n: int, s: SpringSet, f: np.ndarray) -> np.ndarray:
    """Net force on each particle from per-spring forces ``f`` acting on end a (−f on end b)."""
    fx = np.bincount(s.a, f[:, 0], n) - np.bincount(s.b, f[:, 0], n)
    fy = np.bincount(s.a, f[:, 1], n) - np.bincount(s.b, f[:, 1], n)
    return np.column_stack([fx, fy])


def spring_hessians(x: np.ndarray, s: SpringSet) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The 2 x 2 Hessian of each spring's energy in its vector d, entries (xx, xy, yy).

    For a spring in force (rope: l > l0; loop-width: l < l0), with u = d / l,
    ``H = k [(1 - l0/l) I + (l0/l) u u^T]`` (the second derivative of 1/2 k (l - l0)^2);
    zero otherwise (rope springs are convex: H is positive semidefinite).
    """
    d, length = spring_geometry(x, s)
    active = np.where(s.compress, length < s.l0, length > s.l0)
    safe = np.where(active, length, 1.0)
    ratio = np.where(active, s.l0 / safe, 0.0)
    iso = np.where(active, s.k * (1.0 - ratio), 0.0)
    aniso = s.k * ratio / safe ** 2
    return (iso + aniso * d[:, 0] ** 2, aniso * d[:, 0] * d[:, 1], iso + aniso * d[:, 1] ** 2)


def spring_forces(x: np.ndarray, s: SpringSet, v: np.ndarray | None = None,
                  damping: float = 0.0) -> np.ndarray:
    """Net spring force (and eq. 2 damping k_d (v_q - v_p) if ``v`` given) on every particle."""
    d, length = spring_geometry(x, s)
    f = (tensions(length, s) / np.maximum(length, 1e-300))[:, None] * d
    if v is not None and damping > 0:
        f = f + damping * (v[s.b] - v[s.a])
    return accumulate(x.shape[0], s, f)


def edge_reaction(x: np.ndarray, net: Network, particles: np.ndarray) -> np.ndarray:
    """The force a grip holding ``particles`` applies to the fabric: minus the net spring force
    on them (= dE/d(displacement) at equilibrium, the envelope theorem, while no order or
    length constraint on them is active)."""
    return -spring_forces(x, net.springs)[particles].sum(axis=0)


def residual_force(x: np.ndarray, net: Network) -> float:
    """Largest net spring force on a particle that is not held by the boundary."""
    f = spring_forces(x, net.springs)[~net.fixed]
    return float(np.max(np.hypot(f[:, 0], f[:, 1]))) if f.size else 0.0
