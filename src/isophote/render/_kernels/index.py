"""The segment index of a level (render/segment_index.py): kernels; their NumPy twins are
index_ref.py.

Boxes are the segments' control-point hulls in node units (float32, as the block windows test
them), computed from the points wherever they are tested and never held (16 bytes a kept
segment: 170 MB for the luma of a 16 MP `high` master). A segment is *culled* when its box holds no node row, no node column and no sample row
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
def fill_firsts(offsets, out):
    """out[k]: the index in the points of segment k's first control point (chains.segment_starts'
    first), in out's own dtype: int32 for every channel under 2**31 points, half the bytes."""
    e = 0
    for c in range(offsets.shape[0] - 1):
        for f in range(offsets[c], offsets[c + 1] - 1, 3):
            out[e] = f
            e += 1
    return out


@njit(cache=True, nogil=True, inline="always")
def _box(points, f, r):
    """Segment points[f:f + 4]'s control-point hull times r: (x_lo, x_hi, y_lo, y_hi)."""
    xlo = min(min(points[f, 0], points[f + 1, 0]), min(points[f + 2, 0], points[f + 3, 0]))
    xhi = max(max(points[f, 0], points[f + 1, 0]), max(points[f + 2, 0], points[f + 3, 0]))
    ylo = min(min(points[f, 1], points[f + 1, 1]), min(points[f + 2, 1], points[f + 3, 1]))
    yhi = max(max(points[f, 1], points[f + 1, 1]), max(points[f + 2, 1], points[f + 3, 1]))
    return xlo * r, xhi * r, ylo * r, yhi * r


@njit(cache=True, nogil=True, inline="always")
def _node_box(points, f, r):
    """The segment's box in node units, float32 (what the blocks and windows test)."""
    xlo, xhi, ylo, yhi = _box(points, f, r)
    return np.float32(xlo), np.float32(xhi), np.float32(ylo), np.float32(yhi)


@njit(cache=True, nogil=True, inline="always")
def _kept(points, f, r, sky, soff):
    xlo, xhi, ylo, yhi = _box(points, f, 1.0)
    keep = _holds_row(ylo * r, yhi * r) or _holds_row(xlo * r, xhi * r)
    if not keep and sky > 0.0:
        keep = _holds_row(ylo * sky - soff, yhi * sky - soff)
    return keep


@njit(cache=True, nogil=True)
def kept_segments(points, first, r, cull, sky, soff):
    """(K,) int32 ascending: the segments kept at r nodes a source pixel; with ``cull`` only
    those whose box holds a node row or column, or (sky > 0) a sample row at
    y * sky - soff = I + 0.5. Two passes, so that nothing of the segments' count but a byte
    each is held beside the result."""
    n = first.shape[0]
    keep = np.ones(n, np.bool_)
    kept = n
    if cull:
        kept = 0
        for k in range(n):
            keep[k] = _kept(points, first[k], r, sky, soff)
            kept += keep[k]
    ids = np.empty(kept, np.int32)
    e = 0
    for k in range(n):
        if keep[k]:
            ids[e] = k
            e += 1
    return ids


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
def grid_index(points, first, ids, r, size, nbr, nbc):
    """CSR of the segments ids (ascending) by the blocks (row-major, ``size`` nodes a side)
    their boxes (_node_box, at r nodes a source pixel) reach widened by a node: (index
    (N,) int32 segment ids, ascending within each block; starts (nbr * nbc + 1,))."""
    n = ids.shape[0]
    one = np.float32(1.0)
    starts = np.zeros(nbr * nbc + 1, np.int64)
    for k in range(n):
        x0, x1, y0, y1 = _node_box(points, first[ids[k]], r)
        r0, r1 = _cell(y0 - one, size, nbr), _cell(y1 + one, size, nbr)
        c0, c1 = _cell(x0 - one, size, nbc), _cell(x1 + one, size, nbc)
        for b in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                starts[b * nbc + c + 1] += 1
    for b in range(nbr * nbc):
        starts[b + 1] += starts[b]
    index = np.empty(starts[-1], np.int32)
    pos = starts[:-1].copy()
    for k in range(n):
        x0, x1, y0, y1 = _node_box(points, first[ids[k]], r)
        r0, r1 = _cell(y0 - one, size, nbr), _cell(y1 + one, size, nbr)
        c0, c1 = _cell(x0 - one, size, nbc), _cell(x1 + one, size, nbc)
        for b in range(r0, r1 + 1):
            for c in range(c0, c1 + 1):
                index[pos[b * nbc + c]] = ids[k]
                pos[b * nbc + c] += 1
    return index, starts


@njit(cache=True, nogil=True)
def select(index, starts, nbc, b0, b1, c0, c1, points, first, r, x_lo, x_hi, y_lo, y_hi):
    """The segments (ascending ids, each once) listed in blocks rows b0..b1 x columns
    c0..c1 (grid_index) whose boxes (_node_box) reach [x_lo, x_hi] x [y_lo, y_hi]. The ids
    met are marked in a bitmap over their range (a bit an id: a window of a 16 MP luma spans
    millions of ids, for a few ten thousand kept), read back a 64-bit word at a time."""
    lo = np.iinfo(np.int64).max
    hi = -1
    for b in range(b0, b1 + 1):
        for q in range(starts[b * nbc + c0], starts[b * nbc + c1 + 1]):
            k = index[q]
            lo = min(lo, k)
            hi = max(hi, k)
    if hi < 0:
        return np.zeros(0, np.int64)
    mark = np.zeros(((hi - lo) >> 6) + 1, np.uint64)
    count = 0
    for b in range(b0, b1 + 1):
        for q in range(starts[b * nbc + c0], starts[b * nbc + c1 + 1]):
            k = index[q]
            w, bit = (k - lo) >> 6, np.uint64(1) << np.uint64((k - lo) & 63)
            if mark[w] & bit:
                continue
            bx0, bx1, by0, by1 = _node_box(points, first[k], r)
            if bx1 >= x_lo and bx0 <= x_hi and by1 >= y_lo and by0 <= y_hi:
                mark[w] |= bit
                count += 1
    out = np.empty(count, np.int64)
    e = 0
    for w in range(mark.shape[0]):
        v = mark[w]
        j = 0
        while v:
            if v & np.uint64(1):
                out[e] = lo + (w << 6) + j
                e += 1
            v >>= np.uint64(1)
            j += 1
    return out
