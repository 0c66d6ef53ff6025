"""Bilinear reading of a node-grid field at a point (kernel; its NumPy twin is resample_ref.py).

Node (i, j) sits at (j + 0.5, i + 0.5) in node units, as in _kernels/diffuse.py. A point
(x, y) in node units reads the four nodes around it; outside the outermost nodes the field
extends as the nearest node's value (clamped coordinates).
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
def bilinear_at(field, x, y):
    """The bilinear interpolation of field (nr, nc) at (x, y)."""
    nr, nc = field.shape
    i0, fy = _axis(y, nr)
    j0, fx = _axis(x, nc)
    i1 = min(i0 + 1, nr - 1)
    j1 = min(j0 + 1, nc - 1)
    top = (1.0 - fx) * field[i0, j0] + fx * field[i0, j1]
    bot = (1.0 - fx) * field[i1, j0] + fx * field[i1, j1]
    return (1.0 - fy) * top + fy * bot
