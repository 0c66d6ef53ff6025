"""Which isoline crossings may become joints on the sample grid (kernel + NumPy twin).

Used by :mod:`isophote.encoder` (its ``_joint_reach``), which documents the rule: a crossing
may move onto the nearer end S of its grid edge when S lies within ``frac`` of its tolerance,
no other crossing of that edge lies between it and S, and no crossing of another level is
nearer S (then the first in point order among equals). Grid samples are flat indices of the
padded grid (``wp`` samples a row; sample (r, c) sits at ((c - 1) / 2, (r - 1) / 2) px).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def joint_reach(points, below, above, level, tol, wp, size, frac):
    """(N,) float64: frac * tol[k] for the crossings that may move, 0 for the others."""
    n = points.shape[0]
    # per grid edge (its lower sample and direction), its crossings nearest either end; per
    # sample, the nearest candidate: indices (int32, -1 for none) keep these arrays small
    first = np.full(2 * size, -1, np.int32)
    last = np.full(2 * size, -1, np.int32)
    along = np.empty(n)
    dist = np.empty(n)
    for k in range(n):
        lo = min(below[k], above[k])
        hi = max(below[k], above[k])
        r = lo // wp
        a = abs(points[k, 0] - (lo - r * wp - 1) * 0.5) + abs(points[k, 1] - (r - 1) * 0.5)
        r = hi // wp
        b = abs(points[k, 0] - (hi - r * wp - 1) * 0.5) + abs(points[k, 1] - (r - 1) * 0.5)
        e = 2 * lo + (1 if hi - lo != 1 else 0)
        along[k] = a
        dist[k] = min(a, b)
        if first[e] < 0 or a < along[first[e]]:
            first[e] = k
        if last[e] < 0 or a > along[last[e]]:
            last[e] = k
    best = np.full(size, -1, np.int32)
    reach = np.zeros(n)
    for k in range(n):
        lo = min(below[k], above[k])
        hi = max(below[k], above[k])
        a = along[k]
        e = 2 * lo + (1 if hi - lo != 1 else 0)
        to_lo = a == dist[k]  # S is the edge's lower sample
        end = along[first[e]] if to_lo else along[last[e]]
        if dist[k] <= frac * tol[k] and a == end:
            reach[k] = 1.0  # a candidate, for now
            s = lo if to_lo else hi
            if best[s] < 0 or dist[k] < dist[best[s]]:
                best[s] = k
    for k in range(n):
        if reach[k] > 0.0:
            lo = min(below[k], above[k])
            hi = max(below[k], above[k])
            s = lo if along[k] == dist[k] else hi
            reach[k] = frac * tol[k] if level[k] == level[best[s]] else 0.0
    return reach


def joint_reach_ref(points, below, above, level, tol, wp, size, frac):
    """NumPy twin of :func:`joint_reach`."""
    n = points.shape[0]

    def xy(s):
        r = s // wp
        return np.stack([(s - r * wp - 1) * 0.5, (r - 1) * 0.5], axis=1)

    lo = np.minimum(below, above)
    hi = np.maximum(below, above)
    along = np.abs(points - xy(lo)).sum(axis=1)  # from the edge's lower sample (one term is 0)
    d_hi = np.abs(points - xy(hi)).sum(axis=1)
    to_lo = along <= d_hi
    near = np.where(to_lo, lo, hi)
    dist = np.where(to_lo, along, d_hi)
    # the crossing nearest either end of each edge
    _, edge = np.unique(lo * size + hi, return_inverse=True)
    first = np.full(edge.max() + 1 if n else 0, np.inf)
    last = np.full_like(first, -np.inf)
    np.minimum.at(first, edge, along)
    np.maximum.at(last, edge, along)
    ok = (dist <= frac * tol) & np.where(to_lo, along == first[edge], along == last[edge])
    # per sample, the level of the nearest candidate (then the first)
    cand = np.flatnonzero(ok)
    order = cand[np.lexsort((cand, dist[cand], near[cand]))]
    start = np.ones(order.shape[0], bool)
    start[1:] = near[order[1:]] != near[order[:-1]]
    lv = level[order]
    keep = lv == lv[start][np.cumsum(start) - 1]
    reach = np.zeros(n)
    reach[order[keep]] = frac * tol[order[keep]]
    return reach
