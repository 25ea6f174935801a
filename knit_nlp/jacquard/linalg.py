"""Sparse linear algebra of the static solver's Newton steps (docs/jacquard.md, "Static solver").

The Hessian of the spring energy is ``B^T blockdiag(H_s) B`` (+ ``eps I``): one symmetric 2 x 2
block ``H_s`` per spring, scattered onto the blocks (a,a), (b,b), (a,b), (b,a) of its two
particles. :class:`BlockHessian` computes that block pattern once (particles held by the
boundary are not unknowns: their blocks are dropped) and then assembles the matrix of any
iterate by three ``bincount`` calls, as a scipy BSR matrix with 2 x 2 blocks (one block row
per free particle).

The Newton systems are solved by preconditioned conjugate gradients, the preconditioner one
V-cycle of smoothed-aggregation algebraic multigrid (pyamg) whose near-null space is the two
rigid translations. :class:`Multigrid` cycles pyamg's hierarchy itself, without the two
residual norms per application that pyamg's ``aspreconditioner`` computes for its stopping
test (two fine-grid products of 8 in a cycle).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import LinearOperator, cg, splu


SEED = 20260522
DIRECT_MAX = 4000  # unknowns up to which every Newton system is factorised (SuperLU) instead
REBUILD_CG = 25    # conjugate-gradient iterations that trigger a new multigrid hierarchy
MAX_CG = 400       # conjugate-gradient iterations per Newton system
THETA = 0.05       # strength-of-connection threshold of the aggregation (measured: 0-0.1 alike)


@dataclass(frozen=True)
class BlockHessian:
    """The 2 x 2 block pattern of ``sum_s B_s^T H_s B_s + eps I`` over the free particles.

    ``slot`` (4, ns) gives, for each spring, the position in the block data of its blocks
    (a,a), (b,b), (a,b), (b,a) (-1 where an end is held); ``diagonal`` the position of every
    free particle's diagonal block.
    """

    n_free: int
    indptr: np.ndarray
    indices: np.ndarray
    slot: np.ndarray
    diagonal: np.ndarray

    @classmethod
    def build(cls, a: np.ndarray, b: np.ndarray, free: np.ndarray) -> "BlockHessian":
        """Pattern for springs ``a -> b`` over particles where ``free`` is true."""
        index = np.full(free.size, -1, dtype=np.int64)
        n = int(free.sum())
        index[free] = np.arange(n)
        fa, fb = index[a], index[b]
        rows = np.concatenate([fa, fb, fa, fb, np.arange(n)])
        cols = np.concatenate([fa, fb, fb, fa, np.arange(n)])
        keep = (rows >= 0) & (cols >= 0)
        key = rows * n + cols
        uniq, inverse = np.unique(key[keep], return_inverse=True)
        pos = np.full(key.size, -1, dtype=np.int64)
        pos[keep] = inverse.ravel()
        indptr = np.searchsorted(uniq // max(n, 1), np.arange(n + 1)).astype(np.int64)
        ns = a.size
        return cls(n, indptr, (uniq % max(n, 1)).astype(np.int64), pos[:4 * ns].reshape(4, ns),
                   pos[4 * ns:])

    def matrix(self, hxx: np.ndarray, hxy: np.ndarray, hyy: np.ndarray,
               diagonal: float = 0.0) -> sp.bsr_matrix:
        """The assembled BSR matrix for spring blocks ``[[hxx, hxy], [hxy, hyy]]`` and
        ``diagonal * I``."""
        nb = self.indices.size
        sign = np.array([1.0, 1.0, -1.0, -1.0])[:, None]
        used = self.slot >= 0
        where = self.slot[used]
        data = np.empty((nb, 2, 2))
        for (r, c), h in (((0, 0), hxx), ((0, 1), hxy), ((1, 1), hyy)):
            data[:, r, c] = np.bincount(where, (sign * h[None, :])[used], nb)
        data[:, 1, 0] = data[:, 0, 1]
        data[self.diagonal, 0, 0] += diagonal
        data[self.diagonal, 1, 1] += diagonal
        return sp.bsr_matrix((data, self.indices, self.indptr),
                             shape=(2 * self.n_free, 2 * self.n_free))


class Multigrid:
    """Smoothed-aggregation AMG (pyamg) for a BSR matrix, applied as one V-cycle."""

    def __init__(self, A: sp.bsr_matrix) -> None:
        import pyamg
        n = A.shape[0]
        translations = np.zeros((n, 2))
        translations[0::2, 0] = translations[1::2, 1] = 1.0
        state = np.random.get_state()     # pyamg estimates spectral radii from random vectors:
        np.random.seed(SEED)              # seeded, so that two solves give the same bits
        try:
            self.hierarchy = pyamg.smoothed_aggregation_solver(
                A, B=translations, improve_candidates=None, coarse_solver="splu",
                strength=("symmetric", {"theta": THETA}),
                presmoother=("block_gauss_seidel", {"sweep": "forward"}),
                postsmoother=("block_gauss_seidel", {"sweep": "backward"}))
        finally:
            np.random.set_state(state)
        self.levels = self.hierarchy.levels

    def cycle(self, b: np.ndarray, level: int = 0) -> np.ndarray:
        """One V-cycle for ``A x = b`` from ``x = 0`` (pyamg's cycle, minus its norms)."""
        lev = self.levels[level]
        x = np.zeros_like(b)
        lev.presmoother(lev.A, x, b)
        coarse_b = lev.R @ (b - lev.A @ x)
        if level == len(self.levels) - 2:
            coarse_x = self.hierarchy.coarse_solver(self.levels[-1].A, coarse_b)
        else:
            coarse_x = self.cycle(coarse_b, level + 1)
        x += lev.P @ coarse_x
        lev.postsmoother(lev.A, x, b)
        return x

    def operator(self) -> LinearOperator:
        n = self.levels[0].A.shape[0]
        return LinearOperator((n, n), matvec=self.cycle, dtype=float)


def pcg(A: sp.spmatrix, rhs: np.ndarray, M: LinearOperator, rtol: float,
        max_iter: int) -> tuple[np.ndarray, int, bool]:
    """Conjugate gradients (scipy) from zero to ``|A x - rhs| <= rtol |rhs|``: the solution,
    the iterations taken and whether the tolerance was met."""
    count = [0]

    def tick(_: np.ndarray) -> None:
        count[0] += 1

    x, info = cg(A, rhs, rtol=rtol, atol=0.0, maxiter=max_iter, M=M, callback=tick)
    return x, count[0], info == 0


class DirectSolver:
    """Every Newton system factorised by SuperLU (COLAMD ordering): exact Newton steps. Only
    for small fabrics: its fill grows much faster than the multigrid's work (measured: 0.11 s
    at 50 x 50, 1.1 s at 100 x 100, 7 s at 200 x 200 for one factorisation)."""

    def __init__(self) -> None:
        self.timings = {"factorisation_s": 0.0}
        self.iterations = 0

    def describe(self) -> str:
        return "sparse LU"

    def solve(self, A: sp.spmatrix, rhs: np.ndarray, rtol: float) -> np.ndarray:
        t = time.perf_counter()
        x = splu(A.tocsc()).solve(rhs)
        self.timings["factorisation_s"] += time.perf_counter() - t
        return x


class MultigridCG:
    """Conjugate gradients preconditioned by a multigrid V-cycle. The hierarchy is built on
    the first matrix and kept while the solves stay cheap; a solve that takes more than
    ``REBUILD_CG`` iterations has the next matrix build a new one."""

    def __init__(self) -> None:
        self.timings = {"multigrid_setup_s": 0.0, "cg_s": 0.0}
        self.iterations = 0
        self.multigrid: Multigrid | None = None

    def describe(self) -> str:
        return f"multigrid-preconditioned CG, {self.iterations} CG iterations"

    def solve(self, A: sp.bsr_matrix, rhs: np.ndarray, rtol: float) -> np.ndarray:
        t = time.perf_counter()
        if self.multigrid is None:
            self.multigrid = Multigrid(A)
        t1 = time.perf_counter()
        x, k, _ = pcg(A, rhs, self.multigrid.operator(), rtol, MAX_CG)
        self.timings["multigrid_setup_s"] += t1 - t
        self.timings["cg_s"] += time.perf_counter() - t1
        self.iterations += k
        if k > REBUILD_CG:
            self.multigrid = None
        return x


def linear_solver(n: int) -> DirectSolver | MultigridCG:
    """The solver for Newton systems of ``n`` unknowns."""
    return DirectSolver() if n <= DIRECT_MAX else MultigridCG()
