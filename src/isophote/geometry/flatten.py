"""Bezier chains to line edges (the rasteriser's input).

Each cubic is cut into n equal parameter steps with n from Wang's formula,
n = ceil(sqrt(0.75 * max|P0 - 2P1 + P2|, |P1 - 2P2 + P3|) / tol)), which bounds the distance
between the curve and its chords by tol.
"""

from __future__ import annotations

import numpy as np
from numba import njit

MAX_STEPS = 256


def flatten(segs: np.ndarray, border: np.ndarray, tol: float):
    """Edges (x0, y0, x1, y1, is_source) approximating the segments within tol."""
    segs = np.ascontiguousarray(segs, np.float64).reshape(-1, 4, 2)
    return _flatten_kernel(segs, np.ascontiguousarray(border, np.bool_), float(tol), MAX_STEPS)


@njit(cache=True, nogil=True)
def _flatten_kernel(segs, border, tol, max_steps):
    n_seg = segs.shape[0]
    steps = np.empty(n_seg, np.int64)
    total = 0
    for k in range(n_seg):
        if border[k]:
            n = 1
        else:
            ax = segs[k, 0, 0] - 2.0 * segs[k, 1, 0] + segs[k, 2, 0]
            ay = segs[k, 0, 1] - 2.0 * segs[k, 1, 1] + segs[k, 2, 1]
            bx = segs[k, 1, 0] - 2.0 * segs[k, 2, 0] + segs[k, 3, 0]
            by = segs[k, 1, 1] - 2.0 * segs[k, 2, 1] + segs[k, 3, 1]
            dd = max(np.sqrt(ax * ax + ay * ay), np.sqrt(bx * bx + by * by))
            n = int(np.ceil(np.sqrt(0.75 * dd / tol)))
            n = min(max(n, 1), max_steps)
        steps[k] = n
        total += n
    x0 = np.empty(total)
    y0 = np.empty(total)
    x1 = np.empty(total)
    y1 = np.empty(total)
    src = np.empty(total, np.bool_)
    e = 0
    for k in range(n_seg):
        n = steps[k]
        px, py = segs[k, 0, 0], segs[k, 0, 1]
        for q in range(1, n + 1):
            if q == n:  # exact chain joints, so consecutive edges meet bit for bit
                qx, qy = segs[k, 3, 0], segs[k, 3, 1]
            else:
                t = q / n
                u = 1.0 - t
                b0 = u * u * u
                b1 = 3.0 * u * u * t
                b2 = 3.0 * u * t * t
                b3 = t * t * t
                qx = b0 * segs[k, 0, 0] + b1 * segs[k, 1, 0] + b2 * segs[k, 2, 0] + b3 * segs[k, 3, 0]
                qy = b0 * segs[k, 0, 1] + b1 * segs[k, 1, 1] + b2 * segs[k, 2, 1] + b3 * segs[k, 3, 1]
            x0[e] = px
            y0[e] = py
            x1[e] = qx
            y1[e] = qy
            src[e] = not border[k]
            e += 1
            px, py = qx, qy
    return x0, y0, x1, y1, src


def flatten_ref(segs: np.ndarray, border: np.ndarray, tol: float, with_segment: bool = False):
    """NumPy twin of :func:`flatten` (the same edges, vectorised); with ``with_segment``, also
    the (E,) index of every edge's segment."""
    if len(segs) == 0:
        z = np.zeros(0)
        return (z, z, z, z, np.zeros(0, bool)) + ((np.zeros(0, np.int64),) if with_segment else ())
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
    return (a[:, 0], a[:, 1], b[:, 0], b[:, 1], ~border[seg]) + ((seg,) if with_segment else ())


def contour_edges(channel, tol: float):
    """Line edges (x0, y0, x1, y1, contour) within ``tol`` of a channel's chains, every
    segment (border ones too) cut by Wang's formula: the SVG reader's band map."""
    from .chains import chain_segments

    segs, owner = chain_segments(channel.points, channel.offsets)
    x0, y0, x1, y1, _, seg = flatten_ref(segs, np.zeros(len(segs), bool), tol, with_segment=True)
    return x0, y0, x1, y1, owner[seg]
