"""Caps after a warp: their points move with the map; a cap whose point left the canvas is
re-homed at the pixel of its source region that lands deepest inside the canvas (or dropped
when its region left altogether); each uncovered component gets a background cap."""

from __future__ import annotations

import math

import numpy as np

from ...model import Channel, VectorImage
from .bands import band_map
from .transforms import Transform


def background_points(cover: np.ndarray) -> np.ndarray:
    """One point per uncovered component: its pixel farthest from the covered part."""
    from scipy import ndimage

    lab, n = ndimage.label(~cover)
    if n == 0:
        return np.zeros((0, 2))
    dist = ndimage.distance_transform_edt(~cover)
    idx = ndimage.maximum_position(dist, lab, index=np.arange(1, n + 1))
    return np.array([[j + 0.5, i + 0.5] for i, j in idx], float).reshape(-1, 2)


CAP_MARGIN = 0.5  # pixels: a re-homed cap point lies at least this far inside the canvas


def move_caps(ch: Channel, vi: VectorImage, t: Transform, w: int, h: int):
    """(K, 2) moved cap points and (K,) bool: the caps that stay."""
    k = ch.cap_xy.shape[0]
    if k == 0:
        return np.zeros((0, 2)), np.zeros(0, bool)
    xy = t(ch.cap_xy)
    ok = np.isfinite(xy).all(axis=1) & (xy[:, 0] >= 0) & (xy[:, 0] <= w) & (xy[:, 1] >= 0) & (xy[:, 1] <= h)
    lost = np.flatnonzero(~ok)
    if lost.size:
        xy, ok = _rehome_caps(ch, vi, t, w, h, xy, ok, lost)
    return xy, ok


def _rehome_caps(ch, vi, t, w, h, xy, ok, lost):
    """Caps whose point left the canvas: find the pixel of their source region that lands
    deepest inside the canvas."""
    from scipy import ndimage

    bands = band_map(ch, vi.width, vi.height)
    labelled = {}  # band -> (labels, pixel order, starts): components of that band
    xy = xy.copy()
    ok = ok.copy()
    for c in lost:
        x, y = ch.cap_xy[c]
        b = int(ch.cap_band[c])
        # the cap's sample, or a neighbour in its band (cap points sit on half pixels)
        i0, j0 = int(math.floor(y)), int(math.floor(x))
        cands = [(i, j) for i in (i0, i0 - 1, i0 + 1) for j in (j0, j0 - 1, j0 + 1)
                 if 0 <= i < vi.height and 0 <= j < vi.width and bands[i, j] == b]
        if not cands:
            continue
        if b not in labelled:
            lab, n = ndimage.label(bands == b)
            flat = lab.ravel()
            order = np.argsort(flat, kind="stable")
            labelled[b] = (lab, order, np.searchsorted(flat[order], np.arange(n + 2)))
        lab, order, starts = labelled[b]
        r = lab[cands[0]]
        pix = order[starts[r] : starts[r + 1]]
        if len(pix) > 20000:
            pix = pix[:: len(pix) // 20000 + 1]
        q = t(np.column_stack([pix % vi.width + 0.5, pix // vi.width + 0.5]))
        depth = np.minimum(np.minimum(q[:, 0], w - q[:, 0]), np.minimum(q[:, 1], h - q[:, 1]))
        best = int(np.argmax(depth))
        if depth[best] >= CAP_MARGIN:
            xy[c] = q[best]
            ok[c] = True
    return xy, ok
