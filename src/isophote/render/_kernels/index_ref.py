"""Plain NumPy twins of index.py's kernels (same names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np

from .index import CULL_SLACK


def _holds_row(lo, hi):
    return np.floor(hi - 0.5 + CULL_SLACK) >= np.ceil(lo - 0.5 - CULL_SLACK)


def fill_firsts(offsets, out):
    from ...geometry import segment_starts

    out[:] = segment_starts(offsets)[0]
    return out


def _boxes(points, first):
    p = points[first[:, None] + np.arange(4)]  # (S, 4, 2)
    return p[:, :, 0].min(axis=1), p[:, :, 0].max(axis=1), p[:, :, 1].min(axis=1), p[:, :, 1].max(axis=1)


def kept_segments(points, first, r, cull, sky, soff):
    xlo, xhi, ylo, yhi = _boxes(points, first)
    keep = np.ones(len(first), bool)
    if cull:
        keep = _holds_row(ylo * r, yhi * r) | _holds_row(xlo * r, xhi * r)
        if sky > 0:
            keep |= _holds_row(ylo * sky - soff, yhi * sky - soff)
    return np.flatnonzero(keep).astype(np.int32)


def segment_boxes(points, first, ids, r):
    """(4, K) float32 [x_lo, x_hi, y_lo, y_hi] in node units of the segments ids: the boxes
    index.py's kernels compute where they test them (_node_box), never held there."""
    xlo, xhi, ylo, yhi = _boxes(points, first[ids])
    return np.stack([xlo * r, xhi * r, ylo * r, yhi * r]).astype(np.float32)


def grid_index(points, first, ids, r, size, nbr, nbc):
    box = segment_boxes(points, first, ids, r)
    r0 = np.clip(np.floor((box[2] - 1.0) / size), 0, nbr - 1).astype(np.int64)
    r1 = np.clip(np.floor((box[3] + 1.0) / size), 0, nbr - 1).astype(np.int64)
    c0 = np.clip(np.floor((box[0] - 1.0) / size), 0, nbc - 1).astype(np.int64)
    c1 = np.clip(np.floor((box[1] + 1.0) / size), 0, nbc - 1).astype(np.int64)
    nrow, ncol = r1 - r0 + 1, c1 - c0 + 1
    count = nrow * ncol
    seg = np.repeat(np.arange(len(r0)), count)
    k = np.arange(len(seg)) - np.repeat(np.cumsum(count) - count, count)  # rank within its segment
    bucket = (r0[seg] + k // ncol[seg]) * nbc + c0[seg] + k % ncol[seg]
    order = np.argsort(bucket, kind="stable")
    return ids[seg[order]].astype(np.int32), np.searchsorted(bucket[order], np.arange(nbr * nbc + 1))


def select(index, starts, nbc, b0, b1, c0, c1, points, first, r, x_lo, x_hi, y_lo, y_hi):
    parts = [index[starts[b * nbc + c0]:starts[b * nbc + c1 + 1]] for b in range(b0, b1 + 1)]
    idx = np.unique(np.concatenate(parts)).astype(np.int64) if parts else np.zeros(0, np.int64)
    bx = segment_boxes(points, first, idx, r)
    return idx[(bx[1] >= x_lo) & (bx[0] <= x_hi) & (bx[3] >= y_lo) & (bx[2] <= y_hi)]
