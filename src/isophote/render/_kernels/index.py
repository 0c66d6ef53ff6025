"""The segment index of a level (render/segment_index.py): kernels; their NumPy twins are
index_ref.py.

Boxes are the segments' control-point hulls in node units (float32, as the block windows test
them). A segment is *culled* when its box holds no node row, no node column and no sample row
(of the lattice given, in sample units): the rasteriser counts an edge only on the rows (and,
transposed, the columns) it crosses, and a segment's edges lie in its box, so a culled segment
changes no band, no crossing and no field. CULL_SLACK (in node or sample units) is far above
the rounding of the coordinates and of the flattening, so the test only ever keeps too many.
"""

from __future__ import annotations

import numpy as np
from numba import njit

CULL_SLACK = 1e-4


@njit(cache=True, nogil=True, inline="always")
def _holds_row(lo, hi):
    """Whether [lo, hi] (widened by CULL_SLACK) holds a lattice row i + 0.5."""
    return np.floor(hi - 0.5 + CULL_SLACK) >= np.ceil(lo - 0.5 - CULL_SLACK)


@njit(cache=True, nogil=True)
def segment_boxes(points, first, r, cull, sky, soff):
    """(kept ids (K,) int32 ascending, boxes (4, K) float32 [x_lo, x_hi, y_lo, y_hi] in node
    units at r nodes a source pixel). With ``cull`` only the segments whose box holds a node
    row or column, or (sky > 0) a sample row at y * sky - soff = I + 0.5."""
    n = first.shape[0]
    ids = np.empty(n, np.int32)
    box = np.empty((4, n), np.float32)
    kept = 0
    for k in range(n):
        f = first[k]
        xlo = min(min(points[f, 0], points[f + 1, 0]), min(points[f + 2, 0], points[f + 3, 0]))
        xhi = max(max(points[f, 0], points[f + 1, 0]), max(points[f + 2, 0], points[f + 3, 0]))
        ylo = min(min(points[f, 1], points[f + 1, 1]), min(points[f + 2, 1], points[f + 3, 1]))
        yhi = max(max(points[f, 1], points[f + 1, 1]), max(points[f + 2, 1], points[f + 3, 1]))
        if cull:
            keep = _holds_row(ylo * r, yhi * r) or _holds_row(xlo * r, xhi * r)
            if not keep and sky > 0.0:
                keep = _holds_row(ylo * sky - soff, yhi * sky - soff)
            if not keep:
                continue
        ids[kept] = k
        box[0, kept] = np.float32(xlo * r)
        box[1, kept] = np.float32(xhi * r)
        box[2, kept] = np.float32(ylo * r)
        box[3, kept] = np.float32(yhi * r)
        kept += 1
    return ids[:kept].copy(), box[:, :kept].copy()


@njit(cache=True, nogil=True, inline="always")
def _cell(v, size, nb):
    """The block of node coordinate v (float32 arithmetic, as NumPy does on the boxes)."""
    c = np.floor(v / np.float32(size))
    if c < 0:
        return 0
    if c > nb - 1:
        return nb - 1
    return int(c)


@njit(cache=True, nogil=True)
def grid_index(box, size, nbr, nbc):
    """CSR of the boxes by the blocks (row-major, ``size`` nodes a side) they reach widened by
    a node: (index (N,) int32 positions into the boxes, ascending within each block; starts
    (nbr * nbc + 1,))."""
    n = box.shape[1]
    one = np.float32(1.0)
    starts = np.zeros(nbr * nbc + 1, np.int64)
    for k in range(n):
        r0, r1 = _cell(box[2, k] - one, size, nbr), _cell(box[3, k] + one, size, nbr)
        c0, c1 = _cell(box[0, k] - one, size, nbc), _cell(box[1, k] + one, size, nbc)
        for b in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                starts[b * nbc + c + 1] += 1
    for b in range(nbr * nbc):
        starts[b + 1] += starts[b]
    index = np.empty(starts[-1], np.int32)
    pos = starts[:-1].copy()
    for k in range(n):
        r0, r1 = _cell(box[2, k] - one, size, nbr), _cell(box[3, k] + one, size, nbr)
        c0, c1 = _cell(box[0, k] - one, size, nbc), _cell(box[1, k] + one, size, nbc)
        for b in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                index[pos[b * nbc + c]] = k
                pos[b * nbc + c] += 1
    return index, starts


@njit(cache=True, nogil=True)
def select(index, starts, nbc, b0, b1, c0, c1, box, x_lo, x_hi, y_lo, y_hi):
    """Positions (ascending, each once) of the boxes listed in blocks rows b0..b1 x columns
    c0..c1 that reach [x_lo, x_hi] x [y_lo, y_hi]."""
    lo = np.iinfo(np.int64).max
    hi = -1
    for b in range(b0, b1 + 1):
        for q in range(starts[b * nbc + c0], starts[b * nbc + c1 + 1]):
            k = index[q]
            lo = min(lo, k)
            hi = max(hi, k)
    if hi < 0:
        return np.zeros(0, np.int64)
    mark = np.zeros(hi - lo + 1, np.bool_)
    count = 0
    for b in range(b0, b1 + 1):
        for q in range(starts[b * nbc + c0], starts[b * nbc + c1 + 1]):
            k = index[q]
            if mark[k - lo]:
                continue
            if box[1, k] >= x_lo and box[0, k] <= x_hi and box[3, k] >= y_lo and box[2, k] <= y_hi:
                mark[k - lo] = True
                count += 1
    out = np.empty(count, np.int64)
    e = 0
    for k in range(hi - lo + 1):
        if mark[k]:
            out[e] = k + lo
            e += 1
    return out
