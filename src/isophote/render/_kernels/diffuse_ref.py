"""Plain NumPy twins of diffuse.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np

from . import diffuse as _diffuse
from .diffuse import D, HALF, MODE_MANHATTAN, NF, PROBE, SX, SY, TX, TY, V


def propagate(F, band, offs, mode, max_iter=10000):
    """NumPy twin for the path-length metrics: Jacobi relaxation of the same graph, with whole-
    array shifts, to the same fixed point (shortest paths within each band)."""
    F = F.copy()
    nr, nc = band.shape
    all_offs = np.concatenate([offs, -offs])
    for _ in range(max_iter):
        changed = False
        for di, dj in all_offs:
            # node (i, j) receives from (i + di, j + dj)
            src_i = slice(max(di, 0), nr + min(di, 0))
            dst_i = slice(max(-di, 0), nr + min(-di, 0))
            src_j = slice(max(dj, 0), nc + min(dj, 0))
            dst_j = slice(max(-dj, 0), nc + min(-dj, 0))
            same = band[src_i, src_j] == band[dst_i, dst_j]
            # in the fields' own precision, or float32 rounding never lets the relaxation settle
            w = F.dtype.type(abs(di) + abs(dj) if mode == MODE_MANHATTAN else np.hypot(di, dj))
            for s in range(2):
                cand = F[s, D][src_i, src_j] + w
                better = same & (cand < F[s, D][dst_i, dst_j] - 1e-12)
                if better.any():
                    changed = True
                    for f in (SX, SY, V):
                        F[s, f][dst_i, dst_j] = np.where(better, F[s, f][src_i, src_j], F[s, f][dst_i, dst_j])
                    F[s, D][dst_i, dst_j] = np.where(better, cand, F[s, D][dst_i, dst_j])
        if not changed:
            break
    return F


def label_nodes(band):
    """NumPy twin of :func:`label_nodes`: scipy's 8-connected labelling of each band, the
    regions then numbered in scan order of their first node."""
    from scipy import ndimage

    band = np.asarray(band)
    raw = np.zeros(band.shape, np.int64)
    m = 0
    for b in np.unique(band):
        lab, k = ndimage.label(band == b, structure=np.ones((3, 3), bool))
        raw[lab > 0] = lab[lab > 0] + m
        m += k
    _, first = np.unique(raw.ravel(), return_index=True)  # each region's first node
    rank = np.empty(m + 1, np.int64)
    rank[raw.ravel()[np.sort(first)]] = np.arange(first.shape[0])
    return rank[raw].astype(np.int32), int(first.shape[0])


# ---------------------------------------------------------------------------------------
# seed, region_caps, band_widths, evaluate: whole-array NumPy, in the kernels' own float
# types (float32 fields, float64 arithmetic), so that they agree with them exactly
# ---------------------------------------------------------------------------------------


def metric(dx, dy, mode):
    """Twin of :func:`diffuse.metric`, elementwise."""
    if mode == 1:
        return np.abs(dx) + np.abs(dy)
    return np.sqrt(dx * dx + dy * dy)


def seg_dist(px, py, sx, sy, tx, ty, mode):
    """Twin of :func:`diffuse.seg_dist`, elementwise (float64)."""
    dx = np.asarray(px, np.float64) - sx
    dy = np.asarray(py, np.float64) - sy
    along = dx * tx + dy * ty
    along = np.where(along > HALF, along - HALF, np.where(along < -HALF, along + HALF, 0.0))
    perp = dx * ty - dy * tx
    rx = along * tx + perp * ty
    ry = along * ty - perp * tx
    return metric(rx, ry, mode)


def offer_coarse(F, band, levels, Fc, k, i0, j0, cuts, mode):
    """Twin of :func:`diffuse.offer_coarse`, on a copy of F (returned): the cut edges' nodes
    as arrays, the edges in the kernel's order (a corner node is offered twice, as there)."""
    F = F.copy()
    nr, nc = band.shape
    nrc, ncc = Fc.shape[2:]
    nl = levels.shape[0]
    edges = [(np.zeros(nc, int), np.arange(nc)), (np.full(nc, nr - 1), np.arange(nc)),
             (np.arange(nr), np.zeros(nr, int)), (np.arange(nr), np.full(nr, nc - 1))]
    for e, (I, J) in enumerate(edges):
        if not cuts[e]:
            continue
        b = band[I, J].astype(np.int64)
        ci = np.minimum(((i0 + I + 0.5) / k).astype(np.int64), nrc - 1)
        cj = np.minimum(((j0 + J + 0.5) / k).astype(np.int64), ncc - 1)
        for s in range(2):
            lv = b - 1 if s == 0 else b
            ok = (lv >= 0) & (lv < nl)
            lvc = np.clip(lv, 0, nl - 1)
            ok &= (Fc[s, D, ci, cj] != np.inf) & (Fc[s, V, ci, cj] == levels[lvc].astype(np.float32))
            # float64 arithmetic on the float32 fields, as the kernel's; stored as float32
            sx = Fc[s, SX, ci, cj].astype(np.float64) * k - j0
            sy = Fc[s, SY, ci, cj].astype(np.float64) * k - i0
            tx, ty = Fc[s, TX, ci, cj].astype(np.float64), Fc[s, TY, ci, cj].astype(np.float64)
            d = seg_dist(J + 0.5, I + 0.5, sx, sy, tx, ty, mode)
            better = ok & (d < F[s, D, I, J])
            for f, val in ((SX, sx), (SY, sy), (TX, tx), (TY, ty), (D, d), (V, levels[lvc])):
                F[s, f, I[better], J[better]] = np.asarray(val)[better] if np.ndim(val) else val
    return F


def _unit(a, b):
    """(a, b) / |(a, b)| in float64, each product in its operand's own type (as numba does
    with a float32 slope and a float64 one)."""
    a = np.asarray(a)
    b = np.asarray(b)
    n = np.sqrt((a * a).astype(np.float64) + (b * b).astype(np.float64))
    return a / n, b / n


def empty_fields(nr, nc):
    """F as seed() lays it out: node-major float32 storage indexed F[side, field, i, j]."""
    F = np.zeros((nr, nc, 2, NF), np.float32).transpose((2, 3, 0, 1))
    F[:, D] = np.inf
    return F


def seed(band, H, Vc, levels, mode):
    """Twin of :func:`diffuse.seed`: the four offers (right, left, below, above crossings) of
    every node in the kernel's order, each over the whole grid at once."""
    hfx, hfd, hlx, hld, hfs, hls = H
    vfx, vfd, vlx, vld, vfs, vls = Vc
    band = np.asarray(band).astype(np.int64)
    levels = np.asarray(levels, np.float64)
    nr, nc = band.shape
    nl = levels.shape[0]
    F = empty_fields(nr, nc)
    ii, jj = np.meshgrid(np.arange(nr), np.arange(nc), indexing="ij")
    xc = jj + 0.5
    yc = ii + 0.5
    ones = np.ones((nr, nc))
    # (winding change, crossing x, crossing y, tangent, going up) of each offer
    offers = (
        (hfd[:, 1:nc + 1], hfx[:, 1:nc + 1], yc, _unit(hfs[:, 1:nc + 1], ones), hfd[:, 1:nc + 1] > 0),
        (hld[:, :nc], hlx[:, :nc], yc, _unit(hls[:, :nc], ones), hld[:, :nc] < 0),
        (vfd[:nc, 1:nr + 1].T, xc, vfx[:nc, 1:nr + 1].T, _unit(ones, vfs[:nc, 1:nr + 1].T), vfd[:nc, 1:nr + 1].T < 0),
        (vld[:nc, :nr].T, xc, vlx[:nc, :nr].T, _unit(ones, vls[:nc, :nr].T), vld[:nc, :nr].T > 0),
    )
    for dw, sx, sy, (tx, ty), up in offers:
        ok = (dw != 0) & (band >= 0) & (band <= nl) & np.where(up, band < nl, band >= 1)
        side = np.where(up, 1, 0)
        v = levels[np.clip(np.where(up, band, band - 1), 0, max(nl - 1, 0))] if nl else np.zeros((nr, nc))
        with np.errstate(invalid="ignore"):  # no crossing: x = +-inf, masked out by ok
            d = seg_dist(xc, yc, sx, sy, tx, ty, mode)
        for s in range(2):
            take = ok & (side == s) & (d < F[s, D])
            for f, val in ((SX, sx), (SY, sy), (TX, tx), (TY, ty), (D, d), (V, v)):
                F[s, f][take] = np.broadcast_to(val, (nr, nc))[take]
    return F


def region_caps(F, band, labels, m, cap_x, cap_y, cap_band, cap_value):
    """Twin of :func:`diffuse.region_caps`: per region the largest finite distance of each
    side, and the value of the first cap whose nearest node of its band (within the 3 x 3
    nodes around it, first in scan order on ties) lies in the region."""
    nr, nc = band.shape
    dmax = np.zeros((m, 2), np.float64)
    for s in range(2):
        d = F[s, D]
        fin = d != np.inf
        np.maximum.at(dmax[:, s], labels[fin], d[fin].astype(np.float64))
    capv = np.full(m, np.nan)
    cap_x = np.asarray(cap_x, np.float64)
    cap_y = np.asarray(cap_y, np.float64)
    if cap_x.shape[0] == 0:
        return dmax, capv
    ci = np.floor(cap_y).astype(np.int64)[:, None]
    cj = np.floor(cap_x).astype(np.int64)[:, None]
    di, dj = np.divmod(np.arange(9), 3)
    i = ci + di - 1
    j = cj + dj - 1
    inside = (i >= 0) & (i < nr) & (j >= 0) & (j < nc)
    ic = np.clip(i, 0, nr - 1)
    jc = np.clip(j, 0, nc - 1)
    ok = inside & (band[ic, jc] == np.asarray(cap_band)[:, None])
    dd = np.where(ok, (j + 0.5 - cap_x[:, None]) ** 2 + (i + 0.5 - cap_y[:, None]) ** 2, np.inf)
    best = np.argmin(dd, axis=1)  # the first of equal distances, as the kernel's strict <
    rows = np.arange(cap_x.shape[0])
    bk = np.where(ok[rows, best], labels[ic[rows, best], jc[rows, best]], -1)
    for c in range(cap_x.shape[0]):  # in cap order: the first cap of a region wins
        if bk[c] >= 0 and np.isnan(capv[bk[c]]):
            capv[bk[c]] = cap_value[c]
    return dmax, capv


def band_widths(F, band, labels, dmax, capv, ramp):
    """Twin of :func:`diffuse.band_widths`."""
    d0, d1 = F[0, D], F[1, D]
    v0, v1 = F[0, V], F[1, V]
    both = (d0 != np.inf) & (d1 != np.inf)
    cv = capv[labels]
    one = ((d0 != np.inf) | (d1 != np.inf)) & ~both & ~np.isnan(cv)
    peak = one & (d1 == np.inf)
    pit = one & (d0 == np.inf)
    bw = np.zeros(band.shape + (2,), np.float32)
    bw[both, 0] = (d0 + d1)[both]
    bw[both, 1] = (v1 - v0)[both]
    bw[peak, 0] = np.minimum(dmax[labels, 0], ramp)[peak]
    bw[peak, 1] = (cv - v0)[peak]
    bw[pit, 0] = np.minimum(dmax[labels, 1], ramp)[pit]
    bw[pit, 1] = (v1 - cv)[pit]
    return bw


def _mid(levels, b):
    """Twin of :func:`diffuse._mid`, elementwise over bands b."""
    levels = np.asarray(levels, np.float64)
    nl = levels.shape[0]
    if nl == 0:
        return np.full(np.shape(b), 127.5)
    step_lo = levels[1] - levels[0] if nl > 1 else 10.0
    step_hi = levels[nl - 1] - levels[nl - 2] if nl > 1 else 10.0
    lo_b = np.where(b >= 1, levels[np.clip(b - 1, 0, nl - 1)], levels[0] - step_lo)
    hi_b = np.where(b < nl, levels[np.clip(b, 0, nl - 1)], levels[nl - 1] + step_hi)
    return 0.5 * (lo_b + hi_b)


def _bilinear_at(field, x, y):
    """The kernel's bilinear reading (resample.bilinear_at, clamped axes) at points x, y."""
    def axis(p, n):
        q = p - 0.5
        i = np.floor(q).astype(np.int64)
        low = i < 0
        high = i >= n - 1
        w = np.where(low | high, 0.0, q - i)
        return np.where(low, 0, np.where(high, n - 1, i)), w

    nr, nc = field.shape
    i0, fy = axis(y, nr)
    j0, fx = axis(x, nc)
    i1 = np.minimum(i0 + 1, nr - 1)
    j1 = np.minimum(j0 + 1, nc - 1)
    top = (1.0 - fx) * field[i0, j0] + fx * field[i0, j1]
    bot = (1.0 - fx) * field[i1, j0] + fx * field[i1, j1]
    return (1.0 - fy) * top + fy * bot


def _across(bw, nband, want, x, y, sx, sy, d):
    """Twin of :func:`diffuse._across`, elementwise: (width, step) in float64."""
    nr, nc = nband.shape
    width = np.zeros(np.shape(d))
    step = np.zeros(np.shape(d))
    pending = d > 1e-6
    dd = np.where(pending, d, 1.0)
    ux = (sx - x) / dd
    uy = (sy - y) / dd
    for k in range(1, 3):
        i = np.floor(sy + uy * PROBE * k)
        j = np.floor(sx + ux * PROBE * k)
        inside = (i >= 0) & (i < nr) & (j >= 0) & (j < nc)
        ic = np.clip(np.nan_to_num(i), 0, nr - 1).astype(np.int64)
        jc = np.clip(np.nan_to_num(j), 0, nc - 1).astype(np.int64)
        pending &= inside
        hit = pending & (nband[ic, jc] == want)
        width = np.where(hit, bw[ic, jc, 0].astype(np.float64), width)
        step = np.where(hit, bw[ic, jc, 1].astype(np.float64), step)
        pending &= ~hit
    return width, step


def _pchip_slope(s_here, w_here, s_next, w_next):
    """Twin of :func:`diffuse._pchip_slope`, elementwise."""
    a = 2.0 * w_here + w_next
    c = w_here + 2.0 * w_next
    keep = (w_next <= 0.0) | (s_next * s_here <= 0.0)
    return np.where(keep, s_here, (a + c) / (a / s_here + c / s_next))


# The Hermite basis is a formula, not an algorithm: the kernel's own (plain Python, elementwise
# on arrays) rather than a copy of its six lines.
_cubic = _diffuse._cubic.py_func


def _ratio(num, den):
    """num / den where den > 0, else 0 (the slope of a band read across an isoline)."""
    return np.where(den > 0.0, num / np.where(den > 0.0, den, 1.0), 0.0)


def _nearest_sources(F, nband, labels, b, x, y, i0, j0, mode):
    """The exact evaluation's search, for samples (b, x, y) in cells (i0, j0): the nodes of the
    2 x 2 ring around the sample, then (unless that ring holds a node of the sample's band,
    or both sides' sources) the 4 x 4 ring, scanned as the kernel scans them (ties go to the
    first). Returns the region of the nearest node of band b (-1: none) and, per side, the
    distance (inf: none), value and position of the nearest source."""
    nr, nc = nband.shape
    ring0 = [(0, 0), (0, 1), (1, 0), (1, 1)]
    ring1 = [(di, dj) for di in range(-1, 3) for dj in range(-1, 3)]
    offs = np.array(ring0 + ring1)
    i = i0[:, None] + offs[:, 0]
    j = j0[:, None] + offs[:, 1]
    inside = (i >= 0) & (i < nr) & (j >= 0) & (j < nc)
    ic = np.clip(i, 0, nr - 1)
    jc = np.clip(j, 0, nc - 1)
    bn = np.where(inside, nband[ic, jc].astype(np.int64), np.iinfo(np.int64).min)
    bb = b[:, None]
    own = bn == bb
    xn = x[:, None]
    yn = y[:, None]
    dn2 = np.where(own, (jc + 0.5 - xn) ** 2 + (ic + 0.5 - yn) ** 2, np.inf)
    sides = []
    for side, other in ((0, bb - 1), (1, bb + 1)):
        s = np.where(own, side, 1 - side)  # a neighbouring band's node offers its other side
        dn = F[s, D, ic, jc]
        ok = (own | (bn == other)) & (dn != np.inf)
        sx, sy = F[s, SX, ic, jc], F[s, SY, ic, jc]
        tx, ty = F[s, TX, ic, jc], F[s, TY, ic, jc]
        with np.errstate(invalid="ignore"):
            cand = seg_dist(xn, yn, sx, sy, tx, ty, mode)
            if mode != 0:  # the path to the node, its last leg re-aimed at the sample
                cand = np.where(own, cand + (dn - seg_dist(jc + 0.5, ic + 0.5, sx, sy, tx, ty, mode)), cand)
        sides.append((np.where(ok, cand, np.inf), F[s, V, ic, jc], sx, sy))
    n0 = len(ring0)
    first = own[:, :n0].any(axis=1) | ((sides[0][0][:, :n0] < np.inf).any(axis=1)
                                       & (sides[1][0][:, :n0] < np.inf).any(axis=1))
    width = np.where(first, n0, offs.shape[0])[:, None]
    beyond = np.arange(offs.shape[0]) >= width  # nodes the search did not reach
    rows = np.arange(b.shape[0])
    dn2 = np.where(beyond, np.inf, dn2)
    k = np.argmin(dn2, axis=1)
    reg = np.where(dn2[rows, k] < np.inf, labels[ic[rows, k], jc[rows, k]], -1)
    best = []
    for cand, v, sx, sy in sides:
        cand = np.where(beyond, np.inf, cand)
        k = np.argmin(cand, axis=1)
        best.append((cand[rows, k], v[rows, k].astype(np.float64), sx[rows, k].astype(np.float64),
                     sy[rows, k].astype(np.float64)))
    return reg, best


def _exact(F, nband, labels, dmax, capv, ramp, b, x, y, levels, mode, smooth, bw):
    """The exactly evaluated fill at samples (b, x, y): between the two nearest sources, or a
    cap's profile where one side has none (the kernel's branches, as masks)."""
    i0 = np.floor(y - 0.5).astype(np.int64)
    j0 = np.floor(x - 0.5).astype(np.int64)
    reg, ((d0, v0, sx0, sy0), (d1, v1, sx1, sy1)) = _nearest_sources(F, nband, labels, b, x, y, i0, j0, mode)
    mid = _mid(levels, b)
    cv = np.where(reg >= 0, capv[np.maximum(reg, 0)], np.nan)
    none0, none1 = d0 == np.inf, d1 == np.inf
    with np.errstate(invalid="ignore", divide="ignore"):
        # both sides: the straight line or the Hermite profile across the band
        tot = d0 + d1
        if smooth:
            sl = (v1 - v0) / tot
            wl, dl = _across(bw, nband, b - 1, x, y, sx0, sy0, d0)
            wh, dh = _across(bw, nband, b + 1, x, y, sx1, sy1, d1)
            m0 = _pchip_slope(sl, tot, _ratio(dl, wl), wl)
            m1 = _pchip_slope(sl, tot, _ratio(dh, wh), wh)
            between = _cubic(v0, v1, m0, m1, tot, d0 / tot)
        else:
            between = (v0 * d1 + v1 * d0) / tot
        between = np.where(tot <= 0.0, 0.5 * (v0 + v1), between)
        # one side: a cap (peak: only the lower level; pit: only the upper)
        pit = none0
        lvl = np.where(pit, v1, v0)
        d = np.where(pit, d1, d0)
        s_other = np.where(pit, 1, 0)
        dm = np.minimum(dmax[np.maximum(reg, 0), s_other] if dmax.shape[0] else np.zeros(b.shape), ramp)
        if smooth:
            s_cap = (cv - lvl) / dm
            wn0, dn0 = _across(bw, nband, b - 1, x, y, sx0, sy0, d)
            wn1, dn1 = _across(bw, nband, b + 1, x, y, sx1, sy1, d)
            wn = np.where(pit, wn1, wn0)
            sn = np.where(pit, _ratio(-dn1, wn1), _ratio(dn0, wn0))
            ramp_v = _cubic(lvl, cv, _pchip_slope(s_cap, dm, sn, wn), 0.0, dm, d / dm)
        else:
            ramp_v = lvl + (cv - lvl) * d / dm
        cap = np.where((dm <= 0.0) | (d >= dm), cv, ramp_v)
        cap = np.where(np.isnan(cv), 0.5 * (lvl + mid), cap)
    out = np.where(none0 | none1, cap, between)
    return np.where(none0 & none1, np.where(np.isnan(cv), mid, cv), out)


def evaluate(F, nband, labels, dmax, capv, ramp, tband, xs, ys, levels, mode, flat, nv, out, smooth, bw,
             corr):
    """Twin of :func:`diffuse.evaluate` (same arguments; fills out): each sample is a node
    (read nv), in a cell of its own band (bilinear in nv) or evaluated exactly, as masks."""
    n, m = tband.shape
    nr, nc = nband.shape
    nl = np.asarray(levels).shape[0]
    b = np.clip(tband.astype(np.int64), 0, nl)
    x = np.broadcast_to(np.asarray(xs, np.float64)[None, :], (n, m))
    y = np.broadcast_to(np.asarray(ys, np.float64)[:, None], (n, m))
    if flat:
        out[:] = _mid(levels, b)
        return
    i0 = np.floor(y - 0.5).astype(np.int64)
    j0 = np.floor(x - 0.5).astype(np.int64)
    res = np.zeros((n, m))
    done = np.zeros((n, m), bool)
    if nv.shape[0] == nr:
        ic, jc = np.clip(i0, 0, nr - 1), np.clip(j0, 0, nc - 1)
        node = ((i0 >= 0) & (i0 < nr) & (j0 >= 0) & (j0 < nc) & (x == j0 + 0.5) & (y == i0 + 0.5)
                & (nband[ic, jc] == b))
        res[node] = nv[ic, jc][node]
        done |= node
        if nr > 1 and nc > 1:
            ic, jc = np.clip(i0, 0, nr - 2), np.clip(j0, 0, nc - 2)
            cell = (~done & (i0 >= -1) & (i0 < nr) & (j0 >= -1) & (j0 < nc) & (nband[ic, jc] == b)
                    & (nband[ic, jc + 1] == b) & (nband[ic + 1, jc] == b) & (nband[ic + 1, jc + 1] == b))
            fx = x - (jc + 0.5)
            fy = y - (ic + 0.5)
            bil = ((1.0 - fy) * ((1.0 - fx) * nv[ic, jc] + fx * nv[ic, jc + 1])
                   + fy * ((1.0 - fx) * nv[ic + 1, jc] + fx * nv[ic + 1, jc + 1]))
            res[cell] = bil[cell]
            done |= cell
    exact = ~done
    res[exact] = _exact(F, nband, labels, dmax, capv, ramp, b[exact], x[exact], y[exact], levels, mode, smooth, bw)
    out[:] = res
    if corr.shape[0] > 0:  # the sharpening at the exactly evaluated samples, added to the stored value
        out[exact] = out[exact] + _bilinear_at(corr, x[exact], y[exact])
