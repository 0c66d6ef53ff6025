"""Plain NumPy twin of flatten.py's flatten (same name, same results; tests compare them)."""

from __future__ import annotations

import numpy as np

from .flatten import MAX_STEPS


def flatten(segs: np.ndarray, border: np.ndarray, tol: float, with_segment: bool = False):
    """NumPy twin of :func:`flatten` (the same edges, vectorised); with ``with_segment``, also
    the (E,) index of every edge's segment."""
    if len(segs) == 0:
        z = np.zeros(0)
        return (z, z, z, z, np.zeros(0, bool)) + ((np.zeros(0, np.int64),) if with_segment else ())
    p0, p1, p2, p3 = segs[:, 0], segs[:, 1], segs[:, 2], segs[:, 3]
    dd = np.maximum(np.hypot(*(p0 - 2 * p1 + p2).T), np.hypot(*(p1 - 2 * p2 + p3).T))
    n = np.clip(np.ceil(np.sqrt(0.75 * dd / tol)), 1, MAX_STEPS).astype(np.int64)
    n[border] = 1  # border segments are straight
    total = int(n.sum())
    seg = np.repeat(np.arange(len(segs)), n)
    k = np.arange(total) - np.repeat(np.cumsum(n) - n, n)
    t0 = k / n[seg]
    t1 = (k + 1) / n[seg]

    def point(t, s):
        u = 1.0 - t
        return (
            (u**3)[:, None] * p0[s]
            + (3 * u * u * t)[:, None] * p1[s]
            + (3 * u * t * t)[:, None] * p2[s]
            + (t**3)[:, None] * p3[s]
        )

    a = point(t0, seg)
    b = point(t1, seg)
    # exact chain joints, so consecutive edges meet bit for bit
    a[k == 0] = p0[seg[k == 0]]
    last = k == n[seg] - 1
    b[last] = p3[seg[last]]
    return (a[:, 0], a[:, 1], b[:, 0], b[:, 1], ~border[seg]) + ((seg,) if with_segment else ())
