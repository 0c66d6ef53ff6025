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


def contour_edges(channel, tol: float):
    """Line edges (x0, y0, x1, y1, contour) within ``tol`` of a channel's chains, every
    segment (border ones too) cut by Wang's formula: the SVG reader's band map."""
    from .chains import chain_segments
    from .flatten_ref import flatten as flatten_ref

    segs, owner = chain_segments(channel.points, channel.offsets)
    x0, y0, x1, y1, _, seg = flatten_ref(segs, np.zeros(len(segs), bool), tol, with_segment=True)
    return x0, y0, x1, y1, owner[seg]
