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
def joint_reach(points, below, above, band, level, loop, tol, wp, frac):
    """(N,) float64: frac * tol[k] for the crossings that may move, 0 for the others."""
    n = points.shape[0]
    size = band.shape[0]
    hp = size // wp
    # the candidates, chained per sample (head, nxt; int32 keeps the per-sample array small)
    head = np.full(size, -1, np.int32)
    nxt = np.full(n, -1, np.int32)
    near = np.full(n, -1, np.int32)  # a sample index: the grid of MAX_PIXELS has under 2**31
    dist = np.empty(n)
    for k in range(n - 1, -1, -1):  # chains in point order
        lo = below[k]
        hi = above[k]
        r = lo // wp
        a = abs(points[k, 0] - (lo - r * wp - 1) * 0.5) + abs(points[k, 1] - (r - 1) * 0.5)
        r = hi // wp
        b = abs(points[k, 0] - (hi - r * wp - 1) * 0.5) + abs(points[k, 1] - (r - 1) * 0.5)
        # S, the nearer end (the lower-numbered sample on ties), and whether it is in the band
        # next to the crossing's level: the crossings of an edge come in level order (the
        # marching kernel's monotone interpolant), so then none lies between it and S
        if a < b or (a == b and lo < hi):
            s, d, next_to = lo, a, band[lo] == level[k]
        else:
            s, d, next_to = hi, b, band[hi] == level[k] + 1
        dist[k] = d
        r = s // wp
        inside = 1 < r < hp - 2 and 1 < s - r * wp < wp - 2
        if d <= frac * tol[k] and next_to and inside:
            near[k] = s
            nxt[k] = head[s]
            head[s] = k
    reach = np.zeros(n)
    for k in range(n):
        s = near[k]
        if s < 0:
            continue
        # k moves if at most one of the sample's candidates of its loop comes before it
        # (nearer, then first), and its level is the level of the sample's nearest candidate
        best = head[s]
        before = 0
        q = head[s]
        while q >= 0:
            if dist[q] < dist[best]:
                best = q
            if loop[q] == loop[k] and (dist[q] < dist[k] or (dist[q] == dist[k] and q < k)):
                before += 1
            q = nxt[q]
        if before < PER_LOOP and level[k] == level[best]:
            reach[k] = frac * tol[k]
    return reach
