"""Plain NumPy twin of enclose.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np


def innermost_enclosing(px, py, exclude, loops, area, level):
    """Plain twin: loops is a list of (n, 2) closed polylines; O(points x all segments)."""
    out = []
    for q in range(len(px)):
        best = -1
        for i, lp in enumerate(loops):
            if i == exclude[q]:
                continue
            a, b = lp, np.roll(lp, -1, axis=0)
            ya, yb = a[:, 1], b[:, 1]
            cross = ((ya <= py[q]) & (py[q] < yb)) | ((yb <= py[q]) & (py[q] < ya))
            with np.errstate(divide="ignore", invalid="ignore"):
                xc = a[:, 0] + (py[q] - ya) * (b[:, 0] - a[:, 0]) / (yb - ya)
            sel = cross & (xc < px[q])
            w = int(np.sum(np.where(yb[sel] > ya[sel], 1, -1)))
            if w != 0:
                if best < 0 or abs(area[i]) < abs(area[best]) or (abs(area[i]) == abs(area[best]) and level[i] > level[best]):
                    best = i
        out.append(best)
    return np.asarray(out, np.int64)
