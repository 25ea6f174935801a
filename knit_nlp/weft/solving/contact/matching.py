"""Contact pairs of one round matched to another's (pairs.py finds each round's pairs anew):
which contacts the new search lost (they are held for the next solve), which held pairs repeat
a found one, which contacts moved along the yarns, and the multipliers a new pair inherits.
Pairs are matched on the same two loops by their material points (s_A, s_B)."""
from __future__ import annotations

import numpy as np

from ...model.contact.pairs import Pairs, same_loops


def unrepeated(found: Pairs, held: Pairs, tol: float) -> Pairs:
    """The held pairs that are neither a found pair nor another held pair (same loops, within
    tol in (s_A, s_B)): reseated, a pair the search found in one round and lost in the next
    and the pair held for it since land on the same points. Kept, such repeats grew by one a
    round (the shipped diagonal pull's last rounds: 2, 3, then 4 slots for one contact), and
    the contact's force was split between them."""
    if len(held) == 0:
        return held
    _, dist = match(found, held)
    held = held.select(~(dist < tol))
    # sorted by loops then s_A, a repeat lies within tol of an earlier pair of its loops, a
    # few places back at most: compare at growing lags (memory linear in the pairs)
    key = held.kA * (int(held.kB.max(initial=0)) + 1) + held.kB
    order = np.lexsort((held.sA, key))
    k, sa, sb = key[order], held.sA[order], held.sB[order]
    repeat = np.zeros(len(held), dtype=bool)
    lag = 1
    while lag < len(held):
        near = (k[lag:] == k[:-lag]) & (sa[lag:] - sa[:-lag] < tol)
        if not near.any():
            break
        repeat[lag:] |= near & (np.hypot(sa[lag:] - sa[:-lag], sb[lag:] - sb[:-lag]) < tol)
        lag += 1
    keep = np.ones(len(held), dtype=bool)
    keep[order[repeat]] = False
    return held.select(keep)


def loop_pair_counts(kA: np.ndarray, kB: np.ndarray) -> dict[tuple[int, int], int]:
    keys, counts = np.unique(np.stack([kA, kB], 1), axis=0, return_counts=True)
    return {(int(a), int(b)): int(c) for (a, b), c in zip(keys, counts)}


def match(old: Pairs, new: Pairs) -> tuple[np.ndarray, np.ndarray]:
    """For each new pair the index of the old pair on the same loops nearest in (s_A, s_B)
    (−1 if none), and that distance."""
    idx = np.full(len(new), -1)
    dist = np.full(len(new), np.inf)
    owner, rows = same_loops(old, new)
    d = np.hypot(old.sA[rows] - new.sA[owner], old.sB[rows] - new.sB[owner])
    best = np.lexsort((d, owner))
    first = best[np.r_[True, owner[best][1:] != owner[best][:-1]]] if best.size else best
    idx[owner[first]] = rows[first]
    dist[owner[first]] = d[first]
    return idx, dist


def contacts_moved(touching: Pairs, pairs: Pairs, tol: float) -> bool:
    """Whether a contact of the last solve (``touching``: the pairs that held a contact) has
    moved along the yarns by more than tol. (With every λ < 0 counted, pairs that did not push
    kept the 4-loop wale pull's last step "moving" through all its rounds with no pair short
    of its gap.)"""
    if len(touching) == 0 or len(pairs) == 0:
        return False
    idx, dist = match(pairs, touching)
    return bool(np.any(dist > tol))


def lost_contacts(touching: Pairs, found: Pairs, tol: float) -> Pairs:
    """The contacts of the last solve (``touching``) that the new search has no pair within
    tol of (``SAME``): they stay for the next solve, A's point against its foot on B now
    (``reseat``: the distance from that point of A to yarn B, a true requirement). Without
    them a contact whose closest points jumped (two near minima) was dropped, its yarns came
    together in the next solve, and the rounds cycled (the 5 x 5 diagonal pull: 12 rounds,
    short 0.5, then 1e-4, then 0.5 ...). Kept at their old points they held the yarns apart
    wider than 2r (a 12 x 12 stretch: smallest gap 1.08 x 2r, no contact of the search
    active)."""
    if len(touching) == 0:
        return Pairs.empty()
    _, dist = match(found, touching)
    return touching.select(~(dist < tol))


def carry(last: tuple[Pairs, np.ndarray], pairs: Pairs) -> np.ndarray:
    """Each new pair's multiplier from the matching pair of the last solve (0 if none)."""
    old, lam = last
    if len(old) == 0:
        return np.zeros(len(pairs))
    idx, _ = match(old, pairs)
    return np.where(idx >= 0, lam[np.maximum(idx, 0)], 0.0)
