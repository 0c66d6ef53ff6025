"""Which isoline crossings may become joints on the sample grid (kernel; its NumPy twin is anchors_ref.py).

Used by :mod:`isophote.encoder` (its ``_joint_reach``). A crossing may move onto the nearer
end S of its grid edge when S lies within ``frac`` of its tolerance and inside the image (not
on its frame, where the contour would touch the border), no other crossing of that edge lies
between it and S (S is in the band next to its level: an edge's crossings come in level
order), no crossing of another level is nearer S (then the first in point order among
equals), and at most PER_LOOP crossings of its loop lie nearer S (so no loop shrinks onto a
sample). Grid samples are flat indices of the padded grid (``wp`` samples a row; sample
(r, c) sits at ((c - 1) / 2, (r - 1) / 2) px); ``band`` is the padded band grid, flat.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# At most this many crossings of one loop move onto one sample: two are a corner the loop
# cuts at the sample; four would shrink a loop round the sample onto it (area 0; a perspective
# warp turned such a loop inside out; measured: benchmarks/results/design_choices.md#per-loop).
PER_LOOP = 2


@njit(cache=True, nogil=True)
def _nearer_end(points, below, above, band, lev, k, wp):
    """Crossing k's nearer grid sample S (the lower-numbered one on ties), its city-block
    distance, and whether S is in the band next to its level ``lev``: the crossings of an
    edge come in level order (the marching kernel's monotone interpolant), so then none lies
    between it and S."""
    lo = below[k]
    hi = above[k]
    r = lo // wp
    a = abs(points[k, 0] - (lo - r * wp - 1) * 0.5) + abs(points[k, 1] - (r - 1) * 0.5)
    r = hi // wp
    b = abs(points[k, 0] - (hi - r * wp - 1) * 0.5) + abs(points[k, 1] - (r - 1) * 0.5)
    if a < b or (a == b and lo < hi):
        return lo, a, band[lo] == lev
    return hi, b, band[hi] == lev + 1


@njit(cache=True, nogil=True)
def joint_reach(points, below, above, band, offsets, loop_level, tol, wp, frac):
    """(N,) float64: frac * tol[k] for the crossings that may move, 0 for the others."""
    moves = joint_moves(points, below, above, band, offsets, loop_level, tol, wp, frac)
    reach = np.zeros(points.shape[0])
    for k in range(points.shape[0]):
        if moves[k]:
            reach[k] = frac * tol[k]
    return reach


@njit(cache=True, nogil=True)
def joint_moves(points, below, above, band, offsets, loop_level, tol, wp, frac):
    """(N,) bool: the crossings that may move (joint_reach's, a byte a crossing: the encoder
    holds this and makes the reaches batch by batch).

    Loop i is points[offsets[i]:offsets[i + 1]], of level loop_level[i]. Besides the result
    the kernel holds 4 bytes a crossing (the per-sample chains' links) and 4 a sample (their
    heads): a crossing's loop and distance are found again when its sample is visited."""
    n = points.shape[0]
    size = band.shape[0]
    hp = size // wp
    n_loops = offsets.shape[0] - 1
    # the candidates, chained per sample in point order (head, nxt; int32 keeps them small)
    head = np.full(size, -1, np.int32)
    nxt = np.empty(n, np.int32)  # read only along the chains
    for lp in range(n_loops - 1, -1, -1):
        lev = loop_level[lp]
        for k in range(offsets[lp + 1] - 1, offsets[lp] - 1, -1):
            s, d, next_to = _nearer_end(points, below, above, band, lev, k, wp)
            r = s // wp
            inside = 1 < r < hp - 2 and 1 < s - r * wp < wp - 2
            if d <= frac * tol[k] and next_to and inside:
                nxt[k] = head[s]
                head[s] = k
    longest = 0
    for s in range(size):
        m = 0
        q = head[s]
        while q >= 0:
            m += 1
            q = nxt[q]
        longest = max(longest, m)
    ck = np.empty(longest, np.int64)  # one sample's candidates: point, loop, distance
    cl = np.empty(longest, np.int64)
    cd = np.empty(longest)
    moves = np.zeros(n, np.bool_)
    for s in range(size):
        q = head[s]
        if q < 0:
            continue
        r = s // wp
        sx = (s - r * wp - 1) * 0.5
        sy = (r - 1) * 0.5
        m = 0
        while q >= 0:
            ck[m] = q
            cl[m] = np.searchsorted(offsets, q, "right") - 1
            cd[m] = abs(points[q, 0] - sx) + abs(points[q, 1] - sy)  # _nearer_end's, to the bit
            m += 1
            q = nxt[q]
        # k moves if at most PER_LOOP - 1 of the sample's candidates of its loop come before
        # it (nearer, then first), and its level is the level of the sample's nearest
        # candidate (then the first)
        best = 0
        for i in range(m):
            if cd[i] < cd[best]:
                best = i
        for i in range(m):
            before = 0
            for j in range(m):
                if cl[j] == cl[i] and (cd[j] < cd[i] or (cd[j] == cd[i] and ck[j] < ck[i])):
                    before += 1
            if before < PER_LOOP and loop_level[cl[i]] == loop_level[cl[best]]:
                moves[ck[i]] = True
    return moves
