"""Plain NumPy twin of resample.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np


def bilinear_at(field, xs, ys):
    """NumPy twin of :func:`bilinear_at` at the points (xs[k], ys[k]): scipy's order-1
    map_coordinates, nearest mode."""
    from scipy import ndimage

    coords = [np.asarray(ys, np.float64) - 0.5, np.asarray(xs, np.float64) - 0.5]
    return ndimage.map_coordinates(np.asarray(field, np.float64), coords, order=1, mode="nearest")
