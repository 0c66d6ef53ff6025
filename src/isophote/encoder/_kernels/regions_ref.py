"""Plain NumPy twin of regions.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np


def label_regions(vals, band, levels):
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


def _edge(lab):
    """NumPy twin of _is_edge over the image samples (labels without the padding ring)."""
    edge = np.zeros(lab.shape, bool)
    dh = lab[:, :-1] != lab[:, 1:]
    dv = lab[:-1, :] != lab[1:, :]
    edge[:, :-1] |= dh
    edge[:, 1:] |= dh
    edge[:-1, :] |= dv
    edge[1:, :] |= dv
    return edge


def region_stats(labels, vals, m):
    """NumPy twin of :func:`region_stats` (scipy's city-block distance transform)."""
    from scipy.ndimage import distance_transform_cdt

    hp, wp = labels.shape
    lab = labels[1:-1, 1:-1]
    v = vals[1:-1, 1:-1]
    edge = _edge(lab)
    d = distance_transform_cdt(~edge, metric="taxicab") if edge.any() else np.zeros(lab.shape, np.int64)
    rr, cc = np.mgrid[1 : hp - 1, 1 : wp - 1]
    idx = (rr * wp + cc).ravel()
    k = lab.ravel()
    deep = np.full(m, -1, np.int64)
    order = np.lexsort((idx, -d.ravel(), k))  # by region, deepest first, then scan order
    first = np.ones(order.shape[0], bool)
    first[1:] = k[order][1:] != k[order][:-1]
    deep[k[order][first]] = idx[order][first]
    total = np.bincount(k, weights=v.ravel(), minlength=m)
    count = np.bincount(k, minlength=m).astype(np.int64)
    return deep, total, count


def cap_sums(labels, vals, want, L, ramp):
    """NumPy twin of :func:`cap_sums`: an exact distance transform over the whole grid."""
    from scipy.ndimage import distance_transform_edt

    m = want.shape[0]
    lab = labels[1:-1, 1:-1]
    v = vals[1:-1, 1:-1]
    edge = _edge(lab)
    if not edge.any():
        return np.zeros(m), np.zeros(m), False
    d = (distance_transform_edt(~edge) + 0.5) * 0.5
    flat = lab.ravel()
    dmax = np.zeros(m)
    np.maximum.at(dmax, flat, d.ravel())
    ramp_eff = np.minimum(dmax, ramp)[flat]
    f = np.minimum(1.0, d.ravel() / np.maximum(ramp_eff, 1e-9))
    w = want[flat]
    num = np.bincount(flat[w], weights=(v.ravel() - L[flat])[w] * f[w], minlength=m)
    den = np.bincount(flat[w], weights=(f * f)[w], minlength=m)
    return num, den, True


def region_levels(labels, band, above, below, lev_seg, m):
    """NumPy twin of :func:`region_levels`."""
    lab = labels.ravel()
    bf = band.ravel().astype(np.int64)
    lo = np.full(m, np.iinfo(np.int64).max, np.int64)
    hi = np.full(m, -1, np.int64)
    for smp, want in ((above, lev_seg + 1), (below, lev_seg)):
        sel = bf[smp] == want
        np.minimum.at(lo, lab[smp[sel]], lev_seg[sel])
        np.maximum.at(hi, lab[smp[sel]], lev_seg[sel])
    return lo, hi
