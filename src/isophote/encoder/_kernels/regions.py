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


ROWS = 256  # padded grid rows of values a row source is asked for at a time


def whole(vals):
    """A row source over a whole padded value grid: rows(w0, w1) is vals[w0:w1]."""
    return lambda w0, w1: vals[w0:w1]


def label_regions(vals, band, levels):
    """(Hp, Wp) labels (int32, 0..R-1) and R, of the padded value grid ``vals``."""
    return label_regions_rows(whole(vals), band, levels)


def label_regions_rows(rows, band, levels, step=ROWS):
    """label_regions with the values read from a row source: rows(w0, w1) gives padded rows
    [w0, w1) of the value grid. The same sets (labels are the sets' scan order, whatever
    the order of the unions: shared/unionfind.py)."""
    hp, wp = band.shape
    parent = _unions_by_band(band)
    for r0 in range(1, hp - 2, step):
        r1 = min(r0 + step, hp - 2)
        _diagonals(band, 0, rows(r0, r1 + 1), r0, r0, r1, levels, 0, parent, _NO_PAIRS)
    m = label_in_place(parent)
    return parent.reshape(hp, wp), m


def label_regions_saddles(band, saddles):
    """label_regions without the values: the diagonal unions the bands decide are made here,
    those the bilinear saddle decides are given (``saddles``: (n, 2) flat sample pairs,
    saddle_unions' of every strip, any order)."""
    hp, wp = band.shape
    parent = _unions_by_band(band)
    _diagonals(band, 0, np.zeros((0, 0)), 0, 1, max(hp - 2, 1), np.zeros(0), 1, parent, _NO_PAIRS)
    _union_pairs(parent, saddles)
    m = label_in_place(parent)
    return parent.reshape(hp, wp), m


def saddle_unions(wv, wb, w0, hp, r0, r1, levels):
    """The diagonal unions of label_regions that the bilinear saddle decides, for the cells
    whose top row r is in [r0, r1) of a padded grid of hp rows (wv, wb: padded value and
    band rows from w0 on, holding rows r0 .. r1): (n, 2) int64 flat sample pairs. The march
    records them strip by strip, so the hierarchy labels the regions without the values
    (encoder/strips.py)."""
    r0, r1 = max(r0, 1), min(r1, hp - 2)
    if r1 <= r0:
        return np.zeros((0, 2), np.int64)
    n = _diagonals(wb, w0, wv, w0, r0, r1, levels, 2, _NO_PARENT, _NO_PAIRS)
    out = np.empty((n, 2), np.int64)
    _diagonals(wb, w0, wv, w0, r0, r1, levels, 2, _NO_PARENT, out)
    return out


_NO_PAIRS = np.zeros((0, 2), np.int64)
_NO_PARENT = np.zeros(0, np.int32)


def _unions_by_band(band):
    hp, wp = band.shape
    # the padded grid of MAX_PIXELS has under 2**31 samples
    parent = np.arange(hp * wp, dtype=np.int32)
    _union_bands(parent, band)
    return parent


@njit(cache=True, nogil=True)
def _union_pairs(parent, pairs):
    for i in range(pairs.shape[0]):
        union(parent, pairs[i, 0], pairs[i, 1])


@njit(cache=True, nogil=True)
def _union_bands(parent, band):
    # the padding ring joins nothing: regions are connected inside the image only, as the
    # decoder sees them (each padding sample stays a region of its own, with no samples)
    hp, wp = band.shape
    for r in range(1, hp - 1):
        for c in range(1, wp - 1):
            i = r * wp + c
            b = band[r, c]
            if c + 1 < wp - 1 and band[r, c + 1] == b:
                union(parent, i, i + 1)
            if r + 1 < hp - 1 and band[r + 1, c] == b:
                union(parent, i, i + wp)


@njit(cache=True, nogil=True)
def _diagonals(band, bw0, wv, w0, r0, r1, levels, mode, parent, out):
    """The diagonal unions of the cells whose top row r is in [r0, r1) (band: rows from bw0
    on; wv: padded value rows from w0 on, holding rows r0 .. r1). Diagonal neighbours of
    equal band b join when the other two corners are not both on one side of b (the bands
    decide), or when they are and the cell's bilinear saddle value lies in b (the values
    decide). mode 0: make every union; 1: those the bands decide (wv unread); 2: write
    those the values decide to out (as many as fit) and return their count."""
    wp = band.shape[1]
    n = 0
    for r in range(r0, r1):
        t = r - bw0
        for c in range(1, wp - 2):
            b0 = band[t, c]
            b1 = band[t, c + 1]
            b2 = band[t + 1, c + 1]
            b3 = band[t + 1, c]
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
                if not same_side:
                    if mode != 2:
                        union(parent, ia, ic)
                    continue
                if mode == 1:
                    continue
                q = r - w0
                if _diag_band(wv[q, c], wv[q, c + 1], wv[q + 1, c + 1], wv[q + 1, c], levels) == ba:
                    if mode == 0:
                        union(parent, ia, ic)
                    else:
                        if n < out.shape[0]:
                            out[n, 0] = ia
                            out[n, 1] = ic
                        n += 1
    return n


@njit(cache=True, nogil=True)
def _is_edge(labels, r, c, h, w):
    """Is image sample (r, c) (labels[r + 1, c + 1]) an edge sample: one with a 4-neighbour
    of another region? The padding is no neighbour."""
    k = labels[r + 1, c + 1]
    return ((c + 1 < w and labels[r + 1, c + 2] != k) or (c > 0 and labels[r + 1, c] != k)
            or (r + 1 < h and labels[r + 2, c + 1] != k) or (r > 0 and labels[r, c + 1] != k))


def region_stats(labels, vals, m):
    """Per region (ignoring the padding ring): its deepest sample (flat index), sum and
    count. The deepest sample is the one farthest, in city-block grid steps,
    from every edge sample (an image sample with a 4-neighbour of another region; the padding
    is no neighbour, as in cap_sums), the first in scan order among equals; with no edge at
    all, the first sample."""
    return region_stats_rows(labels, whole(vals), m)


def region_stats_rows(labels, rows, m, step=ROWS):
    """region_stats with the values read from a row source (label_regions_rows), summed in
    the same order."""
    every = np.arange(m, dtype=np.int32)
    deep, count = region_deep(labels, every)
    total, _, _, _ = value_sums_rows(labels, rows, every, np.zeros(m), 1.0, False, step)
    return deep, total, count


def slots_of(want):
    """The slot of each region in per-slot arrays (int32; -1: none) for the regions with
    ``want``, in region order: what region_deep and value_sums_rows take, so that a caller
    asking about a few regions of many holds arrays of the few (the caps: 0.66 M of the
    mosaic luma's 5.2 M regions)."""
    return slots_of_regions(want.shape[0], np.flatnonzero(want))


def slots_of_regions(m, regions):
    """slots_of for the regions listed (ascending) among m."""
    slot = np.full(m, -1, np.int32)
    slot[regions] = np.arange(regions.shape[0], dtype=np.int32)
    return slot


def region_deep(labels, slot):
    """region_stats' deepest sample and count of the regions with a slot (slots_of; every
    region: np.arange(m)), per slot (no values read): int32 (flat indices of a padded grid
    under 2**31 samples)."""
    n = int(slot.max()) + 1 if slot.shape[0] else 0
    deep = np.full(n, -1, np.int32)
    count = np.zeros(n, np.int32)
    _region_deep(labels, _chamfer(labels), slot, deep, count)
    return deep, count


def region_bands(labels, band, slot):
    """The band of each region with a slot (slots_of), per slot (int32; -1: a region with no
    image sample): a region's samples share their band, so its first sample's is read and
    the caller may drop the band grid before the regions' distances (region_deep)."""
    n = int(slot.max()) + 1 if slot.shape[0] else 0
    out = np.full(n, -1, np.int32)
    _region_bands(labels, band, slot, out)
    return out


@njit(cache=True, nogil=True)
def _region_bands(labels, band, slot, out):
    hp, wp = labels.shape
    for r in range(1, hp - 1):
        for c in range(1, wp - 1):
            k = slot[labels[r, c]]
            if k >= 0 and out[k] < 0:
                out[k] = band[r, c]


def value_sums_rows(labels, rows, slot, L, ramp, fit=True, step=ROWS):
    """What the caps read of the values, in one pass over a row source, per slot (slots_of;
    regions without one are not summed): each region's sum of values (region_stats' total)
    and, with ``fit``, cap_sums' num and den (L: the level per slot). Returns (total, num,
    den, has_edge); has_edge False (one region covers the grid, or no fit) leaves num and
    den zeros. The same sums in the same order as region_stats and cap_sums."""
    hp, wp = labels.shape
    n = L.shape[0]
    total = np.zeros(n)
    num = np.zeros(n)
    den = np.zeros(n)
    if fit and n:
        ring, dmax, rad, far, has_edge = _cap_distances(labels, slot, n, ramp)
    else:
        ring, dmax, rad, far, has_edge = np.zeros((1, 0), np.int16), np.zeros(n), 0, 1, False
    filled = np.zeros(1, np.int64)  # image rows of the ring's row distances made so far
    for r0 in range(1, hp - 1, step):
        r1 = min(r0 + step, hp - 1)
        _value_sums(labels, rows(r0, r1), r0, r0, r1, total, slot, has_edge, ring, filled, dmax, rad, far,
                    float(ramp), L, num, den)
    return total, num, den, has_edge


def _chamfer(labels):
    """City-block steps of each image sample to the nearest edge sample (at most h + w + 1):
    2 bytes a sample where that bound fits (an image under about 32 000 pixels across its
    width and height together), else 4 (far below 2**31 on any grid that fits in memory)."""
    hp, wp = labels.shape
    d = np.empty((hp - 2, wp - 2), np.uint16 if hp + wp - 3 < 65535 else np.int32)
    _chamfer_into(labels, d)
    return d


@njit(cache=True, nogil=True)
def _chamfer_into(labels, d):
    hp, wp = labels.shape
    h = hp - 2
    w = wp - 2
    far = h + w + 1
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


@njit(cache=True, nogil=True)
def _region_deep(labels, d, slot, deep, count):
    """region_stats' deepest sample (the first in scan order among equals) and count, per
    slot."""
    hp, wp = labels.shape
    best = np.full(deep.shape[0], -1, np.int32)
    for r in range(1, hp - 1):
        for c in range(1, wp - 1):
            k = slot[labels[r, c]]
            if k < 0:
                continue
            if d[r - 1, c - 1] > best[k]:
                best[k] = d[r - 1, c - 1]
                deep[k] = r * wp + c
            count[k] += 1


@njit(cache=True, nogil=True)
def _value_sums(labels, wv, w0, r0, r1, total, slot, has_edge, ring, filled, dmax, rad, far, ramp, L, num, den):
    """value_sums_rows over padded rows [r0, r1) (wv: padded value rows from w0 on; ring and
    filled: _cap_distances' ring of row distances and how many image rows it has made)."""
    h = labels.shape[0] - 2
    wp = labels.shape[1]
    for r in range(r0, r1):
        if has_edge:
            filled[0] = _fill_ring(labels, ring, filled[0], r - 1 + rad + 1, rad)
        for c in range(1, wp - 1):
            k = slot[labels[r, c]]
            if k < 0:
                continue
            v = wv[r - w0, c]
            total[k] += v
            if has_edge:
                f = min(1.0, _edge_distance(ring, r - 1, c - 1, h, rad, far, ramp) / max(min(dmax[k], ramp), 1e-9))
                num[k] += (v - L[k]) * f
                den[k] += f * f


@njit(cache=True, nogil=True)
def _edge_distance(ring, r, c, h, rad, far, ramp):
    """cap_sums' d at image sample (r, c): from the window's nearest edge sample (the ring's
    row distances of rows r - rad .. r + rad), ramp when none lies within it. An edge sample
    has row distance 0, so its own d is the least, half a grid step."""
    best = far + 1
    nr = ring.shape[0]
    for rr in range(max(0, r - rad), min(h, r + rad + 1)):
        e = ring[rr % nr, c]
        if e <= rad:
            s = (rr - r) * (rr - r) + e * e
            if s < best:
                best = s
    return (math.sqrt(best) + 0.5) * 0.5 if best <= far else ramp


@njit(cache=True, nogil=True)
def _fill_ring(labels, ring, filled, upto, rad):
    """Row distances of image rows [filled, upto) (at most the last) into the ring (row rr
    in slot rr mod its rows): per sample the distance along its row to the nearest edge
    sample within rad columns, rad + 1 when none, from one sweep each way. Returns the rows
    made so far."""
    h = labels.shape[0] - 2
    w = labels.shape[1] - 2
    none = rad + 1
    nr = ring.shape[0]
    upto = min(upto, h)
    for r in range(filled, upto):
        out = ring[r % nr]
        last = -none - 1
        for c in range(w):
            if _is_edge(labels, r, c, h, w):
                last = c
            out[c] = min(c - last, none)
        nxt = w + none + 1
        for c in range(w - 1, -1, -1):
            if out[c] == 0:  # an edge sample (none >= 1: the forward sweep gave 0 to those alone)
                nxt = c
            if nxt - c < out[c]:
                out[c] = nxt - c
    return max(filled, upto)


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
    return cap_sums_rows(labels, whole(vals), want, L, ramp)


def cap_sums_rows(labels, rows, want, L, ramp, step=ROWS):
    """cap_sums with the values read from a row source (label_regions_rows), summed in the
    same order."""
    m = want.shape[0]
    if not want.any():  # nothing to sum: cap_sums still says whether the grid has an edge
        return np.zeros(m), np.zeros(m), bool(_has_edge(labels))
    _, n, d, has_edge = value_sums_rows(labels, rows, slots_of(want), L[want], ramp, True, step)
    num, den = np.zeros(m), np.zeros(m)
    num[want], den[want] = n, d
    return num, den, has_edge


@njit(cache=True, nogil=True)
def _has_edge(labels):
    """Has the grid an edge sample (is it more than one region)?"""
    h = labels.shape[0] - 2
    w = labels.shape[1] - 2
    for r in range(h):
        for c in range(w):
            if _is_edge(labels, r, c, h, w):
                return True
    return False


@njit(cache=True, nogil=True)
def _cap_distances(labels, slot, n, ramp):
    """cap_sums' window radius and dmax per slot: (ring, dmax, rad, far,
    has_edge). The window's nearest edge sample is found separably: a sample's row distance
    is the distance along its row to the nearest edge sample within rad columns (rad + 1:
    none), and the window minimum of dr^2 + dc^2 is the minimum over its rows of dr^2 plus
    their row distance squared (the same value as scanning the whole window). The row
    distances are made row by row into a ring of 2 rad + 1 rows (_fill_ring), here for
    dmax and again for the sums, rather than held for the grid (12 bytes a pixel: the edge
    flags and row distances); d is found twice rather than held (8 bytes a sample)."""
    h = labels.shape[0] - 2
    w = labels.shape[1] - 2
    rad = max(0, int(math.ceil(2.0 * ramp - 1.5)))
    far = (rad + 1) * (rad + 1)
    dmax = np.zeros(n)
    ring = np.zeros((2 * rad + 1, w), np.int16)
    if not _has_edge(labels):
        return ring, dmax, rad, far, False
    filled = 0
    for r in range(h):
        filled = _fill_ring(labels, ring, filled, r + rad + 1, rad)
        for c in range(w):
            k = slot[labels[r + 1, c + 1]]
            if k >= 0:
                dmax[k] = max(dmax[k], _edge_distance(ring, r, c, h, rad, far, ramp))
    return ring, dmax, rad, far, True


@njit(cache=True, nogil=True, inline="always")
def _bound(lab, bf, a, b, lv, lo, hi):
    """A crossing of level lv between samples b (below) and a (above) bounds the region of
    a if a is in band lv + 1, and that of b if b is in band lv."""
    if bf[a] == lv + 1:
        k = lab[a]
        lo[k] = min(lo[k], lv)
        hi[k] = max(hi[k], lv)
    if bf[b] == lv:
        k = lab[b]
        lo[k] = min(lo[k], lv)
        hi[k] = max(hi[k], lv)


@njit(cache=True, nogil=True)
def loop_levels(labels, band, step, below, border, offsets, level, m):
    """The lowest and highest level of the isoline (not border) crossings that bound each
    region (regions_ref.region_levels' rule, its twin), over loops: loop i is segments
    offsets[i] .. offsets[i + 1] - 1, of level level[i]; a segment's above sample is the
    4-neighbour of its below one that its step names (isolines.py: +1, -1, +Wp, -Wp).
    int32 (levels are few); no per-segment level, above sample or selection is made."""
    lab = labels.ravel()
    bf = band.ravel()
    wp = band.shape[1]
    delta = np.array([1, -1, wp, -wp], np.int64)
    lo = np.full(m, np.iinfo(np.int32).max, np.int32)
    hi = np.full(m, -1, np.int32)
    for lp in range(offsets.shape[0] - 1):
        lv = level[lp]
        for s in range(offsets[lp], offsets[lp + 1]):
            if not border[s]:
                _bound(lab, bf, below[s] + delta[step[s]], below[s], lv, lo, hi)
    return lo, hi
