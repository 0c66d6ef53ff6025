"""Bilinear resampling of a node-grid field onto target samples (kernel + NumPy twin).

Node (i, j) sits at (j + 0.5, i + 0.5) in node units, as in _kernels/diffuse.py. A target
sample at (x, y) in node units reads the four nodes around it; outside the outermost nodes
the field extends as the nearest node's value (clamped coordinates).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _axis(p, n):
    """The lower node and the weight of the upper one for position p on an axis of n nodes."""
    q = p - 0.5
    i = int(np.floor(q))
    if i < 0:
        return 0, 0.0
    if i >= n - 1:
        return n - 1, 0.0
    return i, q - i


@njit(cache=True, nogil=True)
def add_bilinear(out, field, xs, ys):
    """out[a, b] += the bilinear interpolation of field (nr, nc) at (xs[b], ys[a])."""
    nr, nc = field.shape
    m = xs.shape[0]
    j0 = np.empty(m, np.int64)
    fx = np.empty(m, np.float64)
    for b in range(m):
        j0[b], fx[b] = _axis(xs[b], nc)
    for a in range(ys.shape[0]):
        i0, fy = _axis(ys[a], nr)
        i1 = min(i0 + 1, nr - 1)
        for b in range(m):
            j = j0[b]
            j1 = min(j + 1, nc - 1)
            wx = fx[b]
            top = (1.0 - wx) * field[i0, j] + wx * field[i0, j1]
            bot = (1.0 - wx) * field[i1, j] + wx * field[i1, j1]
            out[a, b] += (1.0 - fy) * top + fy * bot


def add_bilinear_ref(out, field, xs, ys):
    """NumPy twin of :func:`add_bilinear` (scipy's order-1 map_coordinates, nearest mode)."""
    from scipy import ndimage

    yy, xx = np.meshgrid(np.asarray(ys, np.float64) - 0.5, np.asarray(xs, np.float64) - 0.5, indexing="ij")
    out += ndimage.map_coordinates(np.asarray(field, np.float64), [yy, xx], order=1, mode="nearest").astype(out.dtype)
