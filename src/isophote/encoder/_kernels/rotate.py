"""Each fitted chain rotated to start at its first joint in scan order (kernel; its NumPy
twin is rotate_ref.py). Used by :func:`isophote.encoder.start_at_first_joint`."""

from __future__ import annotations

import numpy as np
from numba import njit


def rotate_chains(points: np.ndarray, offsets: np.ndarray, border: np.ndarray):
    """(points, border) with each chain (points offsets[i] .. offsets[i + 1] - 1, 1 + 3 n
    of them, its last point its first; n border flags a chain) rotated to start at the
    joint of least y, then least x, then the first: one pass a chain, no index array a
    point."""
    new_points = np.empty_like(points)
    new_border = np.empty_like(border)
    _rotate(points, offsets, border, new_points, new_border)
    return new_points, new_border


@njit(cache=True, nogil=True)
def _rotate(points, offsets, border, new_points, new_border):
    sb = 0  # the chain's first segment
    for lp in range(offsets.shape[0] - 1):
        o = offsets[lp]
        n_pts = offsets[lp + 1] - o
        ns = (n_pts - 1) // 3
        best = 0
        for g in range(1, ns):
            y = points[o + 3 * g, 1]
            by = points[o + 3 * best, 1]
            if y < by or (y == by and points[o + 3 * g, 0] < points[o + 3 * best, 0]):
                best = g
        for g in range(ns):
            new_border[sb + g] = border[sb + (g + best) % ns]
        body = max(n_pts - 1, 1)
        for i in range(n_pts):
            k = o + (i + 3 * best) % body
            new_points[o + i, 0] = points[k, 0]
            new_points[o + i, 1] = points[k, 1]
        sb += ns
