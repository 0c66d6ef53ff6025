"""NumPy twin of rotate.py: each chain rotated to start at its first joint in scan order."""

from __future__ import annotations

import numpy as np


def rotate_chains(points: np.ndarray, offsets: np.ndarray, border: np.ndarray):
    """The kernel's (points, border), by a lexicographic sort of every segment's joint."""
    n_loops = offsets.shape[0] - 1
    if n_loops == 0:
        return points, border
    n_pts = np.diff(offsets)
    n_seg = (n_pts - 1) // 3
    seg_loop = np.repeat(np.arange(n_loops), n_seg)
    seg_base = np.cumsum(n_seg) - n_seg
    g = np.arange(seg_loop.shape[0]) - seg_base[seg_loop]  # each segment's place in its chain
    joints = points[offsets[:-1][seg_loop] + 3 * g]  # each segment's first point
    order = np.lexsort((np.arange(seg_loop.shape[0]), joints[:, 0], joints[:, 1], seg_loop))
    first = np.ones(order.shape[0], bool)
    first[1:] = seg_loop[order[1:]] != seg_loop[order[:-1]]
    rot = order[first] - seg_base  # (n_loops,) the segment each chain starts at
    # segments: new g takes old (g + rot) mod n_seg
    src_seg = seg_base[seg_loop] + (g + rot[seg_loop]) % np.maximum(n_seg[seg_loop], 1)
    new_border = border[src_seg]
    # points: a chain's body (all but its last point) rolls by 3 rot; its last point is its first
    p_loop = np.repeat(np.arange(n_loops), n_pts)
    i = np.arange(points.shape[0]) - offsets[:-1][p_loop]
    body = np.maximum(n_pts[p_loop] - 1, 1)
    src = offsets[:-1][p_loop] + (i + 3 * rot[p_loop]) % body
    return points[src], new_border
