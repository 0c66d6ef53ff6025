"""Innermost enclosing loop of test points, by winding numbers along a leftward ray.

Loops never cross, so a loop encloses a point exactly when its winding number there is
non-zero; among the loops that enclose it, the innermost has the smallest |area| (ties, which
only coincident border loops produce, go to the higher level, which lies inside).
Segments are bucketed by the row of the mapped grid (half-pixel rows) they lie in, so each
query looks only at the segments of its own row.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def innermost_enclosing(px, py, exclude, x0, y0, x1, y1, seg_loop, row_start, row_order,
                        area, level, n_rows):
    """For each query point (px[q], py[q]) the innermost loop enclosing it, -1 if none.

    Segments of row k (y in [k/2, (k+1)/2]) are row_order[row_start[k]:row_start[k+1]].
    exclude[q] is a loop id the query ignores (its own loop) or -1.
    """
    nq = px.shape[0]
    nloops = area.shape[0]
    wind = np.zeros(nloops, np.int64)
    touched = np.empty(nloops, np.int64)
    stamp = np.full(nloops, -1, np.int64)  # query that last listed the loop in `touched`
    out = np.full(nq, -1, np.int64)
    for q in range(nq):
        k = int(np.floor(py[q] * 2.0))
        if k < 0:
            k = 0
        if k >= n_rows:
            k = n_rows - 1
        nt = 0
        for a in range(row_start[k], row_start[k + 1]):
            s = row_order[a]
            lp = seg_loop[s]
            if lp == exclude[q]:
                continue
            ya = y0[s]
            yb = y1[s]
            if ya == yb:
                continue
            if (ya <= py[q] < yb) or (yb <= py[q] < ya):
                xc = x0[s] + (py[q] - ya) * (x1[s] - x0[s]) / (yb - ya)
                if xc < px[q]:
                    # list each loop once per query, however often its winding returns to 0
                    if stamp[lp] != q:
                        stamp[lp] = q
                        touched[nt] = lp
                        nt += 1
                    wind[lp] += 1 if yb > ya else -1
        best = -1
        for i in range(nt):
            lp = touched[i]
            if wind[lp] != 0:
                if best < 0:
                    best = lp
                else:
                    ab = abs(area[best])
                    al = abs(area[lp])
                    if al < ab or (al == ab and level[lp] > level[best]):
                        best = lp
            wind[lp] = 0
        out[q] = best
    return out


def innermost_enclosing_ref(px, py, exclude, loops, area, level):
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
