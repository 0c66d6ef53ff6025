"""Plain NumPy twin of areas.polyline_areas (same bits; tests/geometry/test_areas.py compares them)."""

from __future__ import annotations

import numpy as np


def polyline_areas(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(C,) signed shoelace areas of closed polylines (loop k: ``points[offsets[k]:offsets[k+1]]``,
    its last point joined back to its first)."""
    x, y = points[:, 0], points[:, 1]
    ends, starts = offsets[1:] - 1, offsets[:-1]
    # cross[k] = x[k] y[next] - x[next] y[k], next the following point of k's loop; two
    # arrays of a float a point (the loops of a whole channel come here)
    cross = np.empty(points.shape[0])
    t = np.empty(points.shape[0])
    np.multiply(x[:-1], y[1:], out=cross[:-1])
    np.multiply(x[1:], y[:-1], out=t[:-1])
    cross[:-1] -= t[:-1]
    del t
    cross[ends] = x[ends] * y[starts] - x[starts] * y[ends]
    np.cumsum(cross, out=cross)
    before = np.zeros(starts.shape[0])  # the sum over the loops before each
    after_first = starts > 0
    before[after_first] = cross[starts[after_first] - 1]
    return 0.5 * (cross[ends] - before)
