"""Plain NumPy twin of sharpen.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np

from .sharpen import _second_difference


def correction(nv, r, gx, gy):
    """NumPy twin of :func:`correction`."""
    f = np.asarray(nv).astype(np.float64)
    c = np.zeros_like(f)
    if gx > 0.0:
        c -= gx * _second_difference(f, r, 1)
    if gy > 0.0:
        c -= gy * _second_difference(f, r, 0)
    corr = c.astype(np.float32)
    return corr, (f + corr.astype(np.float64)).astype(np.float32)
