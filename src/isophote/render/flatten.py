"""Bezier chains to line edges (the rasteriser's input).

Each cubic is cut into n equal parameter steps with n from Wang's formula,
n = ceil(sqrt(0.75 * max|P0 - 2P1 + P2|, |P1 - 2P2 + P3|) / tol)), which bounds the distance
between the curve and its chords by tol.
"""

from __future__ import annotations

import numpy as np

MAX_STEPS = 256


def segments(channel):
    """(S, 4, 2) control points of every segment of a channel, and their border flags."""
    pts = channel.points
    offs = channel.offsets
    counts = (np.diff(offs) - 1) // 3
    if counts.sum() == 0:
        return np.zeros((0, 4, 2)), np.zeros(0, bool)
    # segment s of contour k starts at point offs[k] + 3 * s
    within = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    first = np.repeat(offs[:-1], counts) + 3 * within
    idx = first[:, None] + np.arange(4)[None, :]
    return pts[idx], channel.border.copy()


def flatten(segs: np.ndarray, border: np.ndarray, tol: float):
    """Edges (x0, y0, x1, y1, is_source) approximating the segments within tol."""
    if len(segs) == 0:
        z = np.zeros(0)
        return z, z, z, z, np.zeros(0, bool)
    p0, p1, p2, p3 = segs[:, 0], segs[:, 1], segs[:, 2], segs[:, 3]
    dd = np.maximum(np.hypot(*(p0 - 2 * p1 + p2).T), np.hypot(*(p1 - 2 * p2 + p3).T))
    n = np.clip(np.ceil(np.sqrt(0.75 * dd / tol)), 1, MAX_STEPS).astype(np.int64)
    n[border] = 1  # border segments are straight
    total = int(n.sum())
    seg = np.repeat(np.arange(len(segs)), n)
    k = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
    t0 = k / n[seg]
    t1 = (k + 1) / n[seg]

    def point(t, s):
        u = 1.0 - t
        return (
            (u**3)[:, None] * p0[s]
            + (3 * u * u * t)[:, None] * p1[s]
            + (3 * u * t * t)[:, None] * p2[s]
            + (t**3)[:, None] * p3[s]
        )

    a = point(t0, seg)
    b = point(t1, seg)
    # exact chain joints, so consecutive edges meet bit for bit
    a[k == 0] = p0[seg[k == 0]]
    last = k == n[seg] - 1
    b[last] = p3[seg[last]]
    return a[:, 0], a[:, 1], b[:, 0], b[:, 1], ~border[seg]
