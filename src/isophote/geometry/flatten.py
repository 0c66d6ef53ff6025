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


@njit(cache=True, nogil=True)
def _flatten_kernel(points, first, ids, border, tol, max_steps):
    n_seg = ids.shape[0]
    steps = np.empty(n_seg, np.int64)
    total = 0
    for q in range(n_seg):
        k = ids[q]
        f = first[k]
        if border[k]:
            n = 1
        else:
            ax = points[f, 0] - 2.0 * points[f + 1, 0] + points[f + 2, 0]
            ay = points[f, 1] - 2.0 * points[f + 1, 1] + points[f + 2, 1]
            bx = points[f + 1, 0] - 2.0 * points[f + 2, 0] + points[f + 3, 0]
            by = points[f + 1, 1] - 2.0 * points[f + 2, 1] + points[f + 3, 1]
            dd = max(np.sqrt(ax * ax + ay * ay), np.sqrt(bx * bx + by * by))
            n = int(np.ceil(np.sqrt(0.75 * dd / tol)))
            n = min(max(n, 1), max_steps)
        steps[q] = n
        total += n
    x0 = np.empty(total)
    y0 = np.empty(total)
    x1 = np.empty(total)
    y1 = np.empty(total)
    src = np.empty(total, np.bool_)
    e = 0
    for q in range(n_seg):
        k = ids[q]
        f = first[k]
        n = steps[q]
        p0x, p0y = points[f, 0], points[f, 1]
        p1x, p1y = points[f + 1, 0], points[f + 1, 1]
        p2x, p2y = points[f + 2, 0], points[f + 2, 1]
        p3x, p3y = points[f + 3, 0], points[f + 3, 1]
        s = not border[k]
        px, py = p0x, p0y
        for i in range(1, n + 1):
            if i == n:  # exact chain joints, so consecutive edges meet bit for bit
                qx, qy = p3x, p3y
            else:
                t = i / n
                u = 1.0 - t
                b0 = u * u * u
                b1 = 3.0 * u * u * t
                b2 = 3.0 * u * t * t
                b3 = t * t * t
                qx = b0 * p0x + b1 * p1x + b2 * p2x + b3 * p3x
                qy = b0 * p0y + b1 * p1y + b2 * p2y + b3 * p3y
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
