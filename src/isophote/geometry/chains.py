"""A channel's chains as segments, and back.

A channel stores its contours as concatenated closed chains (model.py): contour k is
``points[offsets[k]:offsets[k+1]]``, 1 + 3n points for n cubic segments, consecutive segments
sharing their joint. Every consumer that works segment by segment (the rasteriser, the SVG
writer, the overlay, warps, equalisation) takes them from here.
"""

from __future__ import annotations

import numpy as np


GATHER_CHUNK = 1 << 16  # segments chain_segments gathers at a time from float32 points


def segment_starts(offsets: np.ndarray):
    """(first (S,), counts (C,)): the index in ``points`` of every segment's first control
    point, and each contour's number of segments."""
    counts = (np.diff(offsets) - 1) // 3
    n = int(counts.sum())
    within = np.arange(n) - np.repeat(np.cumsum(counts) - counts, counts)
    return np.repeat(offsets[:-1], counts) + 3 * within, counts


def chain_segments(points: np.ndarray, offsets: np.ndarray):
    """(S, 4, 2) control points of every segment of concatenated chains, and (S,) int64 owning
    contour."""
    first, counts = segment_starts(offsets)
    if len(first) == 0:
        return np.zeros((0, 4, 2)), np.zeros(0, np.int64)
    owner = np.repeat(np.arange(len(counts)), counts)
    if points.dtype == np.float64:
        return points[first[:, None] + np.arange(4)], owner
    # a compact master's float32 points (isophote.load): float64 segments, the same values,
    # gathered a chunk at a time (no float32 copy of them all beside)
    segs = np.empty((len(first), 4, 2))
    for a in range(0, len(first), GATHER_CHUNK):
        segs[a : a + GATHER_CHUNK] = points[first[a : a + GATHER_CHUNK, None] + np.arange(4)]
    return segs, owner


def segments(channel):
    """(S, 4, 2) control points of every segment of a channel, and their border flags."""
    segs, _ = chain_segments(channel.points, channel.offsets)
    if len(segs) == 0:
        return segs, np.zeros(0, bool)
    return segs, channel.border.copy()


def join_segments(segs: np.ndarray, owner: np.ndarray, n_contours: int):
    """Inverse of :func:`chain_segments`: (points, offsets) from segments in contour order
    (each contour's segments consecutive, ``owner`` sorted)."""
    counts = np.bincount(owner, minlength=n_contours)
    if len(segs) == 0:
        return np.zeros((0, 2)), np.zeros(n_contours + 1, np.int64)
    body = segs[:, :3].reshape(-1, 2)
    # each contour: its segments' first three points, then the closing point
    ends = np.cumsum(counts)
    pieces_start = np.concatenate([[0], ends[:-1]])
    out, offs = [], [0]
    for k in range(n_contours):
        if counts[k] == 0:
            offs.append(offs[-1])
            continue
        a, b = pieces_start[k], ends[k]
        out.append(body[3 * a : 3 * b])
        out.append(segs[b - 1, 3][None])
        offs.append(offs[-1] + 3 * (b - a) + 1)
    return np.vstack(out), np.asarray(offs, np.int64)


def line_segment(a, b) -> np.ndarray:
    """(4, 2) the straight cubic from a to b (handles at a third and two thirds), as the
    encoder writes border segments."""
    return np.array([a, a + (b - a) / 3.0, a + 2.0 * (b - a) / 3.0, b])
