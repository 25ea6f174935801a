"""Other contacts of the 3-D model (docs/weft3d.md, "Other contacts"): the pairs of yarn pieces
that are no designed crossing (legs of neighbouring wales at the sinker, legs inside the head
below, courses two apart) repel each other by the soft-shell law.

**Law.** The contact energy of two yarn pieces is the double integral ∫∫ v(|x₁ − x₂|) ds₁ ds₂
of the soft-shell energy density v (``compression.SoftShell``; stitch-by-stitch's
``contact_energy``): zero beyond touch (2r) with zero slope there, growing to +∞ at the hard
core 2R_c. Each loop is sampled at S midpoints s_q = (q + ½)·L/S (``samples_for``: spaced
closer than ``SPACING``·max(2R_c, r), so that two yarns cannot pass each other's core between
samples; at least ``SAMPLES``, at most ``MOST``), each carrying the length w = L/S, and the integral is its midpoint rule over the pairs in the neighbour list
(R1):

    U_other = Σ_(a, b) w² v(d′_ab),   d′_ab = 2R_c + a_ab (|x_a − x_b| + c_ab − 2R_c)   (C3),

a_ab = Δ/(d⁰_ab − 2R_c) for a pair naturally closer than touch (d⁰ its natural distance): the
law starts where the natural fabric puts it, so the natural state carries no force (the planar
contact's "naturally closer pairs keep their natural gap"), and keeps its hard core at 2R_c,
where the independent check judges; a_ab = 1 otherwise. c_ab = 0 but for pairs the rounds
add (``rounds3d``), which start at most half way into the shell.

**Neighbour list.** From the topology: every pair of loops within two courses and two wales of
each other (a loop with itself included), and of their sample points those naturally closer
than ``REACH``·2r, except (1) points of one course closer than EXCLUSION·π·r along the yarn (one
piece: the planar rule, ``contact/natural.py``) and (2) a designed contact's own pair, where its
energy (S7) acts (``Windows``): for touching crossings (thin yarns) both points within
``proximity.DESIGNED``·2r along their yarns of one of the crossings of the natural projections
(``proximity.reference_crossings``); for wraps both within ``WRAP_WINDOW``·2r of the wrap's
closest points, so that the legs pressing on the head below away from the wraps are other
contacts. Pairs that come close only after deformation are added by the solve's rounds
(``missing``), from the independent check (``proximity``), judged by the same windows centred
on each crossing's current material coordinates σ (S5: the yarn slides through its
crossings), so that a pair pressed where a crossing was is added, and its law thinned by its
natural distance (C3) as the list's own.
"""
from __future__ import annotations

from dataclasses import dataclass

from typing import Callable

import casadi as ca
import numpy as np

from ..compression import SoftShell
from ..contact.natural import EXCLUSION
from .natural3d import WRAPS, Natural3D
from .proximity import DESIGNED, Courses, Near, reference_crossings

SAMPLES = 12               # fewest sample points per loop
MOST = 48                  # most sample points per loop (the pairs grow as its square)
SPACING = 0.75             # samples closer than SPACING·2R_c along the yarn: the acrylic's 12
#                            (0.94 mm against a core of 0.65 mm) let a leg pass between two samples
#                            of the head below in a 3 mm diagonal push of a 2 x 2 fabric; 21: clean
REACH = 1.25               # natural pairs closer than REACH·2r are listed (measured: 1.5 and
#                            16 samples listed 3,810 pairs on the 6 x 6 acrylic, the Hessian 3.2x
#                            the NLP's without them; 1.25 and 12: 1,250 pairs, 1.3x)
WRAP_WINDOW = 0.25          # a wrap's own contact: within WRAP_WINDOW·2r along both yarns
OFFSETS = ((0, 0), (0, 1), (0, 2)) + tuple((di, dj) for di in (1, 2) for dj in range(-2, 3))


def none(samples: int) -> "Neighbours":
    """An empty neighbour list."""
    return Neighbours(*(np.zeros(0, int) for _ in range(4)), np.zeros(0), np.zeros(0), samples)


def samples_for(L: float, core_radius: float, radius: float) -> int:
    """S of the module docstring: sample points per loop of length L, spaced closer than
    SPACING times the core's diameter, or the yarn's radius where the core is thinner (a law
    with next to no core, as the acrylic's compression fit, has no core to resolve: its samples
    resolve the shell)."""
    return int(np.clip(np.ceil(L / (SPACING * max(2 * core_radius, radius))), SAMPLES, MOST))


def sample_s(L: float, samples: int) -> np.ndarray:
    """The material points of a loop's samples (midpoints of S equal pieces)."""
    return (np.arange(samples) + 0.5) * L / samples


@dataclass(frozen=True)
class Neighbours:
    """The neighbour list: sample points (loop ``ka``, sample ``qa``) and (``kb``, ``qb``), loop
    index k = i·n + j (0-based), and each pair's shift c and thinning a (R1, C3); S samples per
    loop."""

    ka: np.ndarray
    qa: np.ndarray
    kb: np.ndarray
    qb: np.ndarray
    shift: np.ndarray
    scale: np.ndarray
    samples: int

    def __len__(self) -> int:
        return len(self.ka)

    def keys(self) -> np.ndarray:
        """One integer per pair, the same for (a, b) and (b, a)."""
        a = self.ka.astype(np.int64) * self.samples + self.qa
        b = self.kb.astype(np.int64) * self.samples + self.qb
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        return lo * (1 << 31) + hi

    def plus(self, other: "Neighbours") -> "Neighbours":
        return Neighbours(*(np.concatenate([getattr(self, f), getattr(other, f)])
                            for f in ("ka", "qa", "kb", "qb", "shift", "scale")), self.samples)


def natural_neighbours(shape: Natural3D, shell: SoftShell, courses: int, wales: int,
                       samples: int | None = None, reach: float = REACH) -> Neighbours:
    """The neighbour list of a fabric of natural 3-D loops (module docstring): pairs naturally
    closer than ``reach``·2r."""
    L, r = shape.length, shape.radius
    samples = samples or samples_for(L, shell.core_radius, shell.radius)
    s = sample_s(L, samples)
    x = shape.xyz(s)
    lattice = np.array([shape.wale_spacing, shape.course_spacing])
    windows = _designed(shape) if courses > 1 else None
    parts = []
    for di, dj in OFFSETS:
        if di >= courses or abs(dj) >= wales:
            continue
        shift = np.array([dj * lattice[0], di * lattice[1], 0.0])
        d0 = np.linalg.norm(x[:, None] - (x[None] + shift), axis=-1)     # (qa, qb)
        keep = d0 < reach * 2 * r
        if di == 0:
            keep &= np.abs(dj * L + s[None] - s[:, None]) >= EXCLUSION * np.pi * r
            if dj == 0:
                keep &= np.triu(np.ones_like(keep), 1)
        if di == 1 and windows is not None:
            keep &= ~_in_window(windows, s, dj, L)
        qa, qb = np.nonzero(keep)
        i, j = np.meshgrid(np.arange(max(0, -di), courses - di),
                           np.arange(max(0, -dj), wales - max(dj, 0)), indexing="ij")
        ka = (i * wales + j).ravel()
        kb = ka + di * wales + dj
        a = shell.thinning(d0[qa, qb])
        parts.append((np.repeat(ka, len(qa)), np.tile(qa, len(ka)), np.repeat(kb, len(qa)),
                      np.tile(qb, len(ka)), np.zeros(len(ka) * len(qa)), np.tile(a, len(ka))))
    if not parts:
        return none(samples)
    return Neighbours(*(np.concatenate(p) for p in zip(*parts)), samples)


@dataclass(frozen=True)
class Windows:
    """Where a designed contact's own law acts (module docstring, (2)): per contact, its
    material point on the upper loop ``su`` and its offset on the lower course ``sl`` from the
    same wale's start, and the half-width ``w`` along both yarns."""

    su: np.ndarray
    sl: np.ndarray
    w: float


def _designed(shape: Natural3D) -> Windows:
    """The designed contacts' windows. Touching crossings (thin yarns): the crossings of the
    natural projections (from two courses of three natural loops), DESIGNED·2r wide. Wraps: the
    wraps' closest points, WRAP_WINDOW·2r wide: the wrap's law (S7) is the energy of two
    crossing lines near their closest points, and every other pair of the two loops (the legs
    on the head below, away from the wraps) is an other contact, which holds a course that
    would otherwise hang on two nearly collinear points."""
    if shape.labels == WRAPS:
        return Windows(shape.s_upper, shape.s_lower, _width(shape))
    s = np.linspace(0.0, shape.length, 241)
    lines = shape.xyz(s)[None, None] + shape.starts(2, 3)[:, :, None, :]
    return Windows(*reference_crossings(Courses.of(lines, shape.length)), _width(shape))


def _in_window(windows: Windows, s: np.ndarray, dj: int, L: float) -> np.ndarray:
    """(qa, qb) of lower loop a and upper loop b = a + (1, dj) inside a designed contact's
    window: one of the upper wale's contacts (or its neighbours') within w along both."""
    out = np.zeros((len(s), len(s)), dtype=bool)
    for k in (-1, 0, 1):
        for c_u, c_l in zip(windows.su, windows.sl):
            up = np.abs(s - (k * L + c_u)) < windows.w
            low = np.abs(s - ((dj + k) * L + c_l)) < windows.w
            out |= low[:, None] & up[None, :]
    return out


def pair_energy(shell: SoftShell, weight: float) -> ca.Function:
    """Function (x_a (3), x_b (3), c, a) -> w² v(d′), one term of (R1), d′ of (C3)."""
    xa, xb, c, a = ca.SX.sym("x_a", 3), ca.SX.sym("x_b", 3), ca.SX.sym("c"), ca.SX.sym("a")
    d = shell.seen(ca.norm_2(xa - xb), a, c)
    return ca.Function("pair_energy", [xa, xb, c, a], [weight ** 2 * shell.casadi_energy(d)],
                       ["x_a", "x_b", "c", "a"], ["E"])


def repulsion_energy(shell: SoftShell, weight: float, points: ca.MX, pairs: Neighbours,
                     mapped: Callable[..., list[ca.MX]] | None = None) -> ca.MX:
    """U_other (R1) of lifted sample points (3 × N·S, column k·S + q). ``mapped(name, fn,
    count, *args)`` maps the pair term over the pairs (default ``fn.map``; the 3-D NLP passes
    ``Elements.call``, so that its derivatives are assembled pair by pair)."""
    if not len(pairs):
        return ca.MX(0)
    a = (pairs.ka * pairs.samples + pairs.qa).tolist()
    b = (pairs.kb * pairs.samples + pairs.qb).tolist()
    if mapped is None:
        def mapped(name: str, fn: ca.Function, count: int, *args: ca.MX) -> list[ca.MX]:
            return [fn.map(count, "serial")(*args)]
    return ca.sum2(mapped("repulsion", pair_energy(shell, weight), len(pairs), points[:, a],
                          points[:, b], ca.DM(pairs.shift).T, ca.DM(pairs.scale).T)[0])


def missing(close: Near | None, listed: Neighbours, L: float, wales: int,
            shape: Natural3D, sigma: np.ndarray | None = None) -> Neighbours:
    """The sample-point pairs nearest the check's other pairs closer than touch (``close``)
    that the list does not hold (each pair with its neighbours along both yarns, shift 0),
    except pairs inside a designed crossing's window (module docstring, (2)), centred where
    each crossing is now: ``sigma`` (2 × K: σ_u, σ_l of every crossing, S5) when given, else
    where the natural fabric has it. Under a large pull the yarn slides through its crossings
    (σ moves by up to 1.6 mm on the 12 × 12 course pull to +50 %, against a window of
    ±0.37 mm): windows left at the natural σ₀ would drop pairs beside the wrap that the
    check finds inside the core, round after round."""
    S = listed.samples
    if close is None or not len(close.d):
        return none(S)
    ka, qa = _sample_of(close.ca, close.ua, L, wales, S)
    kb, qb = _sample_of(close.cb, close.ub, L, wales, S)
    n_loops = (int(max(close.ca.max(), close.cb.max())) + 1) * wales
    rows = []
    for da in (-1, 0, 1):
        for db in (-1, 0, 1):
            rows.append(_step(ka, qa, da, S, n_loops, wales) + _step(kb, qb, db, S, n_loops, wales))
    cand = np.unique(np.concatenate([np.stack(r, 1) for r in rows]), axis=0)
    cand = cand[(cand[:, 0] >= 0) & (cand[:, 2] >= 0) & ~((cand[:, 0] == cand[:, 2])
                                                         & (cand[:, 1] == cand[:, 3]))]
    new = Neighbours(cand[:, 0], cand[:, 1], cand[:, 2], cand[:, 3], np.zeros(len(cand)),
                     np.ones(len(cand)), S)
    keep = ~np.isin(new.keys(), listed.keys()) & ~_designed_pair(new, shape, wales, sigma)
    keep &= ~_same_piece(new, L, wales, shape.radius)
    k = np.flatnonzero(keep)
    _, first = np.unique(new.keys()[k], return_index=True)
    k = k[first]
    return Neighbours(new.ka[k], new.qa[k], new.kb[k], new.qb[k], new.shift[k], new.scale[k], S)


def natural_distance(pairs: Neighbours, shape: Natural3D, courses: int, wales: int
                     ) -> np.ndarray:
    """d⁰ of (C3) of any listed pairs: their sample points' distance in the natural fabric
    (loops on their lattice, ``Natural3D.starts``)."""
    s = sample_s(shape.length, pairs.samples)
    x = shape.starts(courses, wales).reshape(-1, 3)
    return np.linalg.norm(x[pairs.ka] + shape.xyz(s[pairs.qa])
                          - x[pairs.kb] - shape.xyz(s[pairs.qb]), axis=1)


def _sample_of(course: np.ndarray, u: np.ndarray, L: float, wales: int, S: int
               ) -> tuple[np.ndarray, np.ndarray]:
    j = np.clip(np.floor(u / L).astype(int), 0, wales - 1)
    q = np.clip(np.floor((u - j * L) / L * S).astype(int), 0, S - 1)
    return course * wales + j, q


def _step(k: np.ndarray, q: np.ndarray, dq: int, S: int, n_loops: int, wales: int
          ) -> tuple[np.ndarray, np.ndarray]:
    """The sample dq further along the course (across the loop's end into its neighbour;
    −1 where the course ends)."""
    q2 = q + dq
    k2 = k + np.floor_divide(q2, S)
    same_course = (k2 // wales == k // wales) & (k2 >= 0) & (k2 < n_loops)
    return np.where(same_course, k2, -1), np.mod(q2, S)


def _same_piece(p: Neighbours, L: float, wales: int, r: float) -> np.ndarray:
    s = sample_s(L, p.samples)
    ua = (p.ka % wales) * L + s[p.qa]
    ub = (p.kb % wales) * L + s[p.qb]
    return (p.ka // wales == p.kb // wales) & (np.abs(ua - ub) < EXCLUSION * np.pi * r)


def _designed_pair(p: Neighbours, shape: Natural3D, wales: int,
                   sigma: np.ndarray | None = None) -> np.ndarray:
    """Pairs of loops one course apart inside a designed crossing's window: at the natural
    crossings (``_designed``), or, given ``sigma`` (2 × K), centred on each crossing's
    current material coordinates (``_tracked``)."""
    out = np.zeros(len(p), dtype=bool)
    if not shape.s_upper.size or not len(p):
        return out
    L, S = shape.length, p.samples
    s = sample_s(L, S)
    up_is_b = p.kb // wales == p.ka // wales + 1
    up_is_a = p.ka // wales == p.kb // wales + 1
    low_k, low_q = np.where(up_is_b, p.ka, p.kb), np.where(up_is_b, p.qa, p.qb)
    up_k, up_q = np.where(up_is_b, p.kb, p.ka), np.where(up_is_b, p.qb, p.qa)
    if sigma is not None:
        return _tracked(up_is_a | up_is_b, (up_k, s[up_q]), (low_k, s[low_q]), shape, wales,
                        np.asarray(sigma, dtype=float))
    dj = up_k % wales - low_k % wales
    windows = _designed(shape)
    for d in np.unique(dj[up_is_a | up_is_b]):
        mask = _in_window(windows, s, int(d), L)
        sel = (up_is_a | up_is_b) & (dj == d)
        out[sel] = mask[low_q[sel], up_q[sel]]
    return out


def _width(shape: Natural3D) -> float:
    """A designed contact's window half-width along both yarns (module docstring, (2))."""
    return (WRAP_WINDOW if shape.labels == WRAPS else DESIGNED) * 2 * shape.radius


def _tracked(pair: np.ndarray, up: tuple[np.ndarray, np.ndarray],
             low: tuple[np.ndarray, np.ndarray], shape: Natural3D, wales: int,
             sigma: np.ndarray) -> np.ndarray:
    """Which of the pairs ``pair`` (upper point: loop, s; lower point: loop, s) lie within
    ``_width`` along both yarns of a crossing's current points: crossing c of upper loop
    (i, J) (c = ((i − 1)·n + J)·P + kind, P per loop) is at J·L + σ_u[c] along course i and
    J·L + σ_l[c] along course i − 1 (σ_l from the lower loop (i − 1, J)'s start); the upper
    point's wale and its two neighbours are looked at."""
    L, per, w = shape.length, shape.s_upper.size, _width(shape)
    (ku, su), (kl, sl) = up, low
    u_up, u_low = (ku % wales) * L + su, (kl % wales) * L + sl
    course = ku // wales
    out = np.zeros(len(pair), dtype=bool)
    for dj in (-1, 0, 1):
        J = ku % wales + dj
        valid = pair & (course >= 1) & (J >= 0) & (J < wales)
        for q in range(per):
            c = np.where(valid, ((course - 1) * wales + J) * per + q, 0)
            out |= valid & (np.abs(u_up - (J * L + sigma[0, c])) < w) & (
                np.abs(u_low - (J * L + sigma[1, c])) < w)
    return out
