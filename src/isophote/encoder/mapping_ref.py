"""Plain NumPy twin of mapping.py's map_pixels (same name, same floating-point expressions,
same result; tests compare them to the bit)."""

from __future__ import annotations

import numpy as np

from .mapping import CUBIC, _interleave, carrato_midpoints


def map_pixels(channel, eps, p=0.5, scale=64.0, cubic=CUBIC):
    """NumPy twin of :func:`map_pixels`."""
    v = np.asarray(channel, dtype=np.float64)
    e = np.broadcast_to(np.asarray(eps, dtype=np.float64), v.shape).copy()
    mid, mid_e = carrato_midpoints(v, e, p, scale, axis=1, cubic=cubic)
    v1 = _interleave(v, mid, 1)
    e1 = _interleave(e, mid_e, 1)
    mid, mid_e = carrato_midpoints(v1, e1, p, scale, axis=0, cubic=cubic)
    g = _interleave(v1, mid, 0)
    ge = _interleave(e1, mid_e, 0)
    g = np.pad(g, 1, mode="edge")
    ge = np.pad(ge, 1, mode="edge")
    return g, ge
