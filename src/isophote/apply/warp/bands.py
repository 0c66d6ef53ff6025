"""Band maps on the pixel centres: the windings of a chain set (for the warp's coverage mask)
and a channel's band of every pixel (for re-homing caps)."""

from __future__ import annotations

import numpy as np

from ...geometry.pen import EdgesPen
from ...model import Channel


def winding_map(x0, y0, x1, y1, width, height):
    """(height, width) int32: sum of edge windings at every pixel centre (the renderer's
    rule: an edge going down adds +1 to the samples on its right)."""
    delta = np.zeros((height, width + 1), np.int64)
    lo, hi = np.minimum(y0, y1), np.maximum(y0, y1)
    dw = np.where(y1 > y0, 1, -1)
    i0 = np.clip(np.ceil(lo - 0.5), 0, height).astype(np.int64)
    i1 = np.clip(np.ceil(hi - 0.5), 0, height).astype(np.int64)
    cnt = np.maximum(i1 - i0, 0)
    cnt[y0 == y1] = 0
    if cnt.sum():
        e = np.repeat(np.arange(len(x0)), cnt)
        i = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt) + i0[e]
        yc = i + 0.5
        x = x0[e] + (yc - y0[e]) * (x1[e] - x0[e]) / (y1[e] - y0[e])
        k = np.clip(np.floor(x + 0.5), 0, width).astype(np.int64)
        np.add.at(delta, (i, k), dw[e])
    return np.cumsum(delta, axis=1)[:, :width].astype(np.int32)


def channel_edges(channel: Channel, tol: float = 0.05):
    """(x0, y0, x1, y1) line edges within ``tol`` of a channel's chains."""
    pen = EdgesPen(tol)
    channel.draw(pen)
    x0, y0, x1, y1, _ = pen.edges()
    return x0, y0, x1, y1


def band_map(channel: Channel, width: int, height: int) -> np.ndarray:
    """(height, width) band of every pixel centre (base_band + windings)."""
    return winding_map(*channel_edges(channel), width, height) + channel.base_band

