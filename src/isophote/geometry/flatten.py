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
    n = len(segs)
    return _flatten_kernel(segs.reshape(-1, 2), np.arange(n) * 4, np.arange(n),
                           np.ascontiguousarray(border, np.bool_), float(tol), MAX_STEPS)


def flatten_selected(points: np.ndarray, first: np.ndarray, border: np.ndarray, ids: np.ndarray, tol: float):
    """The edges of flatten() for the segments ``ids`` (in that order) of concatenated chains:
    segment k's control points are points[first[k]:first[k] + 4] (chains.segment_starts), its
    border flag border[k]; nothing is copied out of ``points``."""
    return _flatten_kernel(points, first, np.ascontiguousarray(ids, np.int64), border, float(tol), MAX_STEPS)


@njit(cache=True, nogil=True, inline="always")
def steps(points, f, is_border, tol, max_steps):
    """Edges of the cubic points[f:f + 4] within tol (Wang's formula; 1 for a border segment)."""
    if is_border:
        return 1
    ax = points[f, 0] - 2.0 * points[f + 1, 0] + points[f + 2, 0]
    ay = points[f, 1] - 2.0 * points[f + 1, 1] + points[f + 2, 1]
    bx = points[f + 1, 0] - 2.0 * points[f + 2, 0] + points[f + 3, 0]
    by = points[f + 1, 1] - 2.0 * points[f + 2, 1] + points[f + 3, 1]
    dd = max(np.sqrt(ax * ax + ay * ay), np.sqrt(bx * bx + by * by))
    n = int(np.ceil(np.sqrt(0.75 * dd / tol)))
    return min(max(n, 1), max_steps)


@njit(cache=True, nogil=True, inline="always")
def point(points, f, i, n):
    """The end of edge i (1..n) of n of the cubic points[f:f + 4]: the curve at t = i / n, and
    the exact end point for the last, so that consecutive edges meet bit for bit."""
    if i == n:
        return points[f + 3, 0], points[f + 3, 1]
    t = i / n
    u = 1.0 - t
    b0 = u * u * u
    b1 = 3.0 * u * u * t
    b2 = 3.0 * u * t * t
    b3 = t * t * t
    return (b0 * points[f, 0] + b1 * points[f + 1, 0] + b2 * points[f + 2, 0] + b3 * points[f + 3, 0],
            b0 * points[f, 1] + b1 * points[f + 1, 1] + b2 * points[f + 2, 1] + b3 * points[f + 3, 1])


@njit(cache=True, nogil=True)
def _flatten_kernel(points, first, ids, border, tol, max_steps):
    n_seg = ids.shape[0]
    nsteps = np.empty(n_seg, np.int64)
    total = 0
    for q in range(n_seg):
        k = ids[q]
        nsteps[q] = steps(points, first[k], border[k], tol, max_steps)
        total += nsteps[q]
    x0 = np.empty(total)
    y0 = np.empty(total)
    x1 = np.empty(total)
    y1 = np.empty(total)
    src = np.empty(total, np.bool_)
    e = 0
    for q in range(n_seg):
        k = ids[q]
        f = first[k]
        n = nsteps[q]
        s = not border[k]
        px, py = points[f, 0], points[f, 1]
        for i in range(1, n + 1):
            qx, qy = point(points, f, i, n)
            x0[e] = px
            y0[e] = py
            x1[e] = qx
            y1[e] = qy
            src[e] = s
            e += 1
            px, py = qx, qy
    return x0, y0, x1, y1, src


def contour_edges(channel, tol: float):
    """Line edges (x0, y0, x1, y1, contour) within ``tol`` of a channel's chains, every
    segment (border ones too) cut by Wang's formula: the SVG reader's band map."""
    from .chains import chain_segments
    from .flatten_ref import flatten as flatten_ref

    segs, owner = chain_segments(channel.points, channel.offsets)
    x0, y0, x1, y1, _, seg = flatten_ref(segs, np.zeros(len(segs), bool), tol, with_segment=True)
    return x0, y0, x1, y1, owner[seg]
