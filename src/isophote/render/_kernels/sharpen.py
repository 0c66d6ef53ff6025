"""The enlargement sharpening's correction at the nodes (kernel; its NumPy twin is sharpen_ref.py); the model and
its measurements: render/sharpen.py.

corr = -(gx d2x + gy d2y): the second differences of the nodes' fill values r nodes (one
source pixel) apart along each axis, 0 along an axis where a neighbour r nodes away lies off
the grid. The kernel also returns nv + corr, what the samples read (_kernels/diffuse.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def correction(nv, r, gx, gy):
    """(corr, nv + corr), both float32 like nv (nr, nc)."""
    nr, nc = nv.shape
    corr = np.zeros((nr, nc), np.float32)
    sharp = np.empty((nr, nc), np.float32)
    for i in range(nr):
        for j in range(nc):
            f = np.float64(nv[i, j])
            c = 0.0
            if gx > 0.0 and j >= r and j + r < nc:
                c -= gx * (np.float64(nv[i, j - r]) - 2.0 * f + np.float64(nv[i, j + r]))
            if gy > 0.0 and i >= r and i + r < nr:
                c -= gy * (np.float64(nv[i - r, j]) - 2.0 * f + np.float64(nv[i + r, j]))
            corr[i, j] = c
            sharp[i, j] = f + np.float64(np.float32(c))
    return corr, sharp


def _second_difference(f: np.ndarray, r: int, axis: int) -> np.ndarray:
    """f[k - r] - 2 f[k] + f[k + r] along axis, 0 where k - r or k + r leaves the grid."""
    out = np.zeros_like(f)
    n = f.shape[axis]
    if n > 2 * r:
        inner = [slice(None)] * f.ndim
        lo = list(inner)
        hi = list(inner)
        inner[axis] = slice(r, n - r)
        lo[axis] = slice(0, n - 2 * r)
        hi[axis] = slice(2 * r, n)
        out[tuple(inner)] = f[tuple(lo)] - 2.0 * f[tuple(inner)] + f[tuple(hi)]
    return out
