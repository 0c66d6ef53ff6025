"""Region labelling of a padded band grid (kernel + pure-Python twin).

Two samples of the image (not the padding ring, whose samples stay regions of their own)
belong to one region when they have the same band and no isoline separates them:
4-neighbours of equal band always (an isoline cannot cross an edge whose ends share a band);
diagonal neighbours of equal band b when the other two corners of their cell are not both on
the same side of b, or when they are and the bilinear saddle value lies in band b too (the
asymptotic decider of _kernels/marching.py, level by level, says exactly this).
Labels are numbered in scan order of each region's first sample (deterministic).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True, nogil=True)
def _union(parent, a, b):
    ra = _find(parent, a)
    rb = _find(parent, b)
    if ra != rb:
        if ra < rb:
            parent[rb] = ra
        else:
            parent[ra] = rb


@njit(cache=True, nogil=True)
def _diag_band(v0, v1, v2, v3, levels):
    # band of the saddle value of the bilinear cell (v0..v3 = TL, TR, BR, BL)
    den = v0 + v2 - v1 - v3
    if den == 0.0:
        return -1
    s = (v0 * v2 - v1 * v3) / den
    return np.searchsorted(levels, s, side="right")


@njit(cache=True, nogil=True)
def label_regions(vals, band, levels):
    """(Hp, Wp) labels (int64, 0..R-1) and R."""
    hp, wp = band.shape
    n = hp * wp
    parent = np.arange(n)
    # the padding ring joins nothing: regions are connected inside the image only, as the
    # decoder sees them (each padding sample stays a region of its own, with no samples)
    for r in range(1, hp - 1):
        for c in range(1, wp - 1):
            i = r * wp + c
            b = band[r, c]
            if c + 1 < wp - 1 and band[r, c + 1] == b:
                _union(parent, i, i + 1)
            if r + 1 < hp - 1 and band[r + 1, c] == b:
                _union(parent, i, i + wp)
    for r in range(1, hp - 2):
        for c in range(1, wp - 2):
            b0 = band[r, c]
            b1 = band[r, c + 1]
            b2 = band[r + 1, c + 1]
            b3 = band[r + 1, c]
            for k in range(2):
                if k == 0:
                    ba, bc, bo1, bo2 = b0, b2, b1, b3
                    ia, ic = r * wp + c, (r + 1) * wp + c + 1
                else:
                    ba, bc, bo1, bo2 = b1, b3, b0, b2
                    ia, ic = r * wp + c + 1, (r + 1) * wp + c
                if ba != bc or bo1 == ba or bo2 == ba:
                    continue
                same_side = (bo1 > ba and bo2 > ba) or (bo1 < ba and bo2 < ba)
                if not same_side or _diag_band(vals[r, c], vals[r, c + 1], vals[r + 1, c + 1], vals[r + 1, c], levels) == ba:
                    _union(parent, ia, ic)
    labels = np.empty(n, np.int64)
    remap = np.full(n, -1, np.int64)
    m = 0
    for i in range(n):
        root = _find(parent, i)
        if remap[root] < 0:
            remap[root] = m
            m += 1
        labels[i] = remap[root]
    return labels.reshape(hp, wp), m


def label_regions_ref(vals, band, levels):
    """Pure-Python twin (breadth-first search), for small grids in tests."""
    hp, wp = band.shape
    labels = -np.ones((hp, wp), np.int64)

    def neighbours(r, c):
        b = band[r, c]
        if not (1 <= r < hp - 1 and 1 <= c < wp - 1):
            return
        for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0)):
            rr, cc = r + dr, c + dc
            if 1 <= rr < hp - 1 and 1 <= cc < wp - 1 and band[rr, cc] == b:
                yield rr, cc
        for dr, dc in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            rr, cc = r + dr, c + dc
            if not (1 <= rr < hp - 1 and 1 <= cc < wp - 1 and 1 <= r < hp - 1 and 1 <= c < wp - 1):
                continue
            if band[rr, cc] != b:
                continue
            o1, o2 = band[r, cc], band[rr, c]
            if o1 == b or o2 == b:
                continue
            r0, c0 = min(r, rr), min(c, cc)
            v = (vals[r0, c0], vals[r0, c0 + 1], vals[r0 + 1, c0 + 1], vals[r0 + 1, c0])
            same = (o1 > b and o2 > b) or (o1 < b and o2 < b)
            den = v[0] + v[2] - v[1] - v[3]
            sb = -1 if den == 0 else int(np.searchsorted(levels, (v[0] * v[2] - v[1] * v[3]) / den, side="right"))
            if not same or sb == b:
                yield rr, cc

    m = 0
    for r in range(hp):
        for c in range(wp):
            if labels[r, c] >= 0:
                continue
            labels[r, c] = m
            stack = [(r, c)]
            while stack:
                a, b_ = stack.pop()
                for nb in neighbours(a, b_):
                    if labels[nb] < 0:
                        labels[nb] = m
                        stack.append(nb)
            m += 1
    return labels, m


@njit(cache=True, nogil=True)
def region_stats(labels, vals, m):
    """Per region (ignoring the padding ring): argmin, argmax (flat indices), sum, count."""
    hp, wp = labels.shape
    flat = vals.ravel()
    amin = np.full(m, -1, np.int64)
    amax = np.full(m, -1, np.int64)
    total = np.zeros(m)
    count = np.zeros(m, np.int64)
    for r in range(1, hp - 1):
        for c in range(1, wp - 1):
            k = labels[r, c]
            i = r * wp + c
            v = vals[r, c]
            if amin[k] < 0 or v < flat[amin[k]]:
                amin[k] = i
            if amax[k] < 0 or v > flat[amax[k]]:
                amax[k] = i
            total[k] += v
            count[k] += 1
    return amin, amax, total, count
