"""Plain NumPy twin of anchors.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np

from .anchors import PER_LOOP


def joint_reach(points, below, above, band, offsets, loop_level, tol, wp, frac):
    """NumPy twin of :func:`joint_reach`."""
    n = points.shape[0]
    counts = np.diff(offsets)
    level = np.repeat(np.asarray(loop_level, np.int64), counts)
    loop = np.repeat(np.arange(counts.shape[0]), counts)
    size = band.shape[0]

    def xy(s):
        r = s // wp
        return np.stack([(s - r * wp - 1) * 0.5, (r - 1) * 0.5], axis=1)

    a = np.abs(points - xy(below)).sum(axis=1)
    b = np.abs(points - xy(above)).sum(axis=1)
    to_below = (a < b) | ((a == b) & (below < above))
    near = np.where(to_below, below, above)
    dist = np.where(to_below, a, b)
    next_to = np.where(to_below, band[below] == level, band[above] == level + 1)
    r, c = np.divmod(near, wp)
    inside = (r > 1) & (r < size // wp - 2) & (c > 1) & (c < wp - 2)
    ok = (dist <= frac * tol) & next_to & inside
    # per sample, the level of the nearest candidate (then the first); per sample and loop,
    # the PER_LOOP nearest candidates (then the first)
    cand = np.flatnonzero(ok)
    order = cand[np.lexsort((cand, dist[cand], near[cand]))]
    start = np.ones(order.shape[0], bool)
    start[1:] = near[order[1:]] != near[order[:-1]]
    lv = level[order]
    same_level = lv == lv[start][np.cumsum(start) - 1]
    order2 = cand[np.lexsort((cand, dist[cand], loop[cand], near[cand]))]
    group = np.ones(order2.shape[0], bool)
    group[1:] = (near[order2[1:]] != near[order2[:-1]]) | (loop[order2[1:]] != loop[order2[:-1]])
    pos = np.arange(order2.shape[0])
    rank = pos - np.maximum.accumulate(np.where(group, pos, 0))
    keep = np.zeros(n, bool)
    keep[order[same_level]] = True
    nearest = np.zeros(n, bool)
    nearest[order2[rank < PER_LOOP]] = True
    keep &= nearest
    reach = np.zeros(n)
    reach[keep] = frac * tol[keep]
    return reach
