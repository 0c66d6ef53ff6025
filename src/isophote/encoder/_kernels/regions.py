"""Region labelling of a padded band grid (kernel; its pure-Python twin is regions_ref.py).

Two samples of the image (not the padding ring, whose samples stay regions of their own)
belong to one region when they have the same band and no isoline separates them:
4-neighbours of equal band always (an isoline cannot cross an edge whose ends share a band);
diagonal neighbours of equal band b when the other two corners of their cell are not both on
the same side of b, or when they are and the bilinear saddle value lies in band b too (the
asymptotic decider of _kernels/marching.py, level by level, says exactly this).
Labels are numbered in scan order of each region's first sample (deterministic).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...shared.unionfind import label_in_place, union


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
    """(Hp, Wp) labels (int32, 0..R-1) and R."""
    hp, wp = band.shape
    n = hp * wp
    parent = np.empty(n, np.int32)  # the padded grid of MAX_PIXELS has under 2**31 samples
    for i in range(n):
        parent[i] = i
    # the padding ring joins nothing: regions are connected inside the image only, as the
    # decoder sees them (each padding sample stays a region of its own, with no samples)
    for r in range(1, hp - 1):
        for c in range(1, wp - 1):
            i = r * wp + c
            b = band[r, c]
            if c + 1 < wp - 1 and band[r, c + 1] == b:
                union(parent, i, i + 1)
            if r + 1 < hp - 1 and band[r + 1, c] == b:
                union(parent, i, i + wp)
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
                    union(parent, ia, ic)
    m = label_in_place(parent)
    return parent.reshape(hp, wp), m


@njit(cache=True, nogil=True)
def _is_edge(labels, r, c, h, w):
    """Is image sample (r, c) (labels[r + 1, c + 1]) an edge sample: one with a 4-neighbour
    of another region? The padding is no neighbour."""
    k = labels[r + 1, c + 1]
    return ((c + 1 < w and labels[r + 1, c + 2] != k) or (c > 0 and labels[r + 1, c] != k)
            or (r + 1 < h and labels[r + 2, c + 1] != k) or (r > 0 and labels[r, c + 1] != k))


@njit(cache=True, nogil=True)
def region_stats(labels, vals, m):
    """Per region (ignoring the padding ring): its deepest sample (flat index), sum and
    count. The deepest sample is the one farthest, in city-block grid steps,
    from every edge sample (an image sample with a 4-neighbour of another region; the padding
    is no neighbour, as in cap_sums), the first in scan order among equals; with no edge at
    all, the first sample."""
    hp, wp = labels.shape
    h = hp - 2
    w = wp - 2
    deep = np.full(m, -1, np.int64)
    total = np.zeros(m)
    count = np.zeros(m, np.int64)
    far = h + w + 1
    d = np.empty((h, w), np.int32)  # city-block steps: far below 2**31 on any grid that fits in memory
    for r in range(h):  # forward chamfer pass: edges are 0, the rest 1 + the nearer of up, left
        for c in range(w):
            if _is_edge(labels, r, c, h, w):
                d[r, c] = 0
            else:
                v = far
                if r > 0 and d[r - 1, c] + 1 < v:
                    v = d[r - 1, c] + 1
                if c > 0 and d[r, c - 1] + 1 < v:
                    v = d[r, c - 1] + 1
                d[r, c] = v
    for r in range(h - 1, -1, -1):  # backward pass: down, right
        for c in range(w - 1, -1, -1):
            v = d[r, c]
            if r + 1 < h and d[r + 1, c] + 1 < v:
                v = d[r + 1, c] + 1
            if c + 1 < w and d[r, c + 1] + 1 < v:
                v = d[r, c + 1] + 1
            d[r, c] = min(v, far)
    best = np.full(m, -1, np.int64)
    for r in range(1, hp - 1):
        for c in range(1, wp - 1):
            k = labels[r, c]
            i = r * wp + c
            if d[r - 1, c - 1] > best[k]:
                best[k] = d[r - 1, c - 1]
                deep[k] = i
            total[k] += vals[r, c]
            count[k] += 1
    return deep, total, count


@njit(cache=True, nogil=True)
def _edge_distance(edge, hd, r, c, h, rad, far, ramp):
    """cap_sums' d at image sample (r, c): from the window's nearest edge sample (hd), ramp
    when none lies within it."""
    best = far + 1
    if edge[r, c]:
        best = 0
    else:
        for rr in range(max(0, r - rad), min(h, r + rad + 1)):
            e = hd[rr, c]
            if e <= rad:
                s = (rr - r) * (rr - r) + e * e
                if s < best:
                    best = s
    return (math.sqrt(best) + 0.5) * 0.5 if best <= far else ramp


@njit(cache=True, nogil=True)
def cap_sums(labels, vals, want, L, ramp):
    """Least-squares sums of the cap profile fit (encoder/hierarchy.py) for the regions k
    with want[k]: num[k] = sum (v - L[k]) f and den[k] = sum f^2 over the region's samples,
    f = min(1, d / min(dmax[k], ramp)). d is the distance, in pixels, from a sample to the
    nearest edge sample (one with a 4-neighbour of another region; the padding is no
    neighbour) plus half a grid step, the grid step being half a pixel; dmax[k] is the
    largest d in region k. Returns (num, den, has_edge); has_edge False means one region
    covers the whole grid (then num and den are zeros).

    Only d < ramp matters (f = 1 beyond, and min(dmax, ramp) = ramp as soon as one sample
    of the region is that far), so edges are looked for in a window of radius R around
    each sample, R + 1.5 >= 2 ramp grid steps; a sample with no edge within R + 1 steps is
    given d = ramp.
    """
    hp, wp = labels.shape
    h = hp - 2
    w = wp - 2
    m = want.shape[0]
    num = np.zeros(m)
    den = np.zeros(m)
    edge = np.zeros((h, w), np.bool_)
    has_edge = False
    for r in range(h):
        for c in range(w):
            e = _is_edge(labels, r, c, h, w)
            edge[r, c] = e
            has_edge = has_edge or e
    if not has_edge:
        return num, den, False
    rad = max(0, int(math.ceil(2.0 * ramp - 1.5)))
    far = (rad + 1) * (rad + 1)
    # the window's nearest edge sample, separably: hd[r, c] is the distance along row r to
    # the nearest edge sample within rad columns of c (rad + 1: none), from one sweep each
    # way; the window minimum of dr^2 + dc^2 is then the minimum over its rows of
    # dr^2 + hd^2 (the same value as scanning the whole window)
    none = rad + 1
    hd = np.empty((h, w), np.int16)
    for r in range(h):
        last = -none - 1
        for c in range(w):
            if edge[r, c]:
                last = c
            hd[r, c] = min(c - last, none)
        nxt = w + none + 1
        for c in range(w - 1, -1, -1):
            if edge[r, c]:
                nxt = c
            if nxt - c < hd[r, c]:
                hd[r, c] = nxt - c
    # d is found twice, for dmax and for the sums, rather than held (8 bytes a sample)
    dmax = np.zeros(m)
    for r in range(h):
        for c in range(w):
            k = labels[r + 1, c + 1]
            if want[k]:
                dmax[k] = max(dmax[k], _edge_distance(edge, hd, r, c, h, rad, far, ramp))
    for r in range(h):
        for c in range(w):
            k = labels[r + 1, c + 1]
            if not want[k]:
                continue
            f = min(1.0, _edge_distance(edge, hd, r, c, h, rad, far, ramp) / max(min(dmax[k], ramp), 1e-9))
            num[k] += (vals[r + 1, c + 1] - L[k]) * f
            den[k] += f * f
    return num, den, True


@njit(cache=True, nogil=True)
def region_levels(labels, band, above, below, lev_seg, m):
    """Lowest and highest level of the crossings that bound each region: a crossing of
    level l (segment start points; above/below are its samples, flat indices) touches the
    region of its above sample if that sample is in band l + 1, and the region of its below
    sample if that one is in band l. Returns (lo, hi) (m,) int64; regions no crossing touches
    keep lo = int64 max, hi = -1."""
    lab = labels.ravel()
    bf = band.ravel()
    lo = np.full(m, np.iinfo(np.int64).max, np.int64)
    hi = np.full(m, -1, np.int64)
    for s in range(lev_seg.shape[0]):
        lv = lev_seg[s]
        a = above[s]
        if bf[a] == lv + 1:
            k = lab[a]
            lo[k] = min(lo[k], lv)
            hi[k] = max(hi[k], lv)
        b = below[s]
        if bf[b] == lv:
            k = lab[b]
            lo[k] = min(lo[k], lv)
            hi[k] = max(hi[k], lv)
    return lo, hi
