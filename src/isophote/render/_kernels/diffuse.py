"""Distance fields of the double-diffusion fill (kernels; their NumPy twins are diffuse_ref.py).

Node grid: node (i, j) sits at (j + 0.5, i + 0.5) in node units. For every node and each
side (0 = lower, 1 = upper) the fields hold the nearest source: its position (sx, sy), the
isoline's unit tangent there (tx, ty), the distance d to it (path length in the chosen
metric) and its value v (the level). d = inf where no source was found.

A source is a crossing of the isoline with a node row or column; it stands for the piece
of isoline around it, a segment of half-length HALF along the tangent, so that a point
between two node rows measures its distance to the curve, not to the nearest crossing.

Sources are the exact isoline crossings between neighbouring nodes (from the rasteriser).
Propagation only passes between nodes of the same band (the paper's dist within R - S), in
alternating forward and backward raster sweeps until nothing changes.

G1 profiles (fill "diffusion"): the paper's blend C = (v0 d1 + v1 d0) / (d0 + d1) is a
straight line across each band, so the slope jumps at every isoline, and those kinks read as
faint contour lines (Mach bands) in smooth areas and at enlargements. Instead the profile
across a band is the cubic Hermite curve through the same two levels whose slope at each
isoline is the PCHIP harmonic mean of the slopes of the two bands that meet there; the other
band's width and step are read at the first node PROBE (or 2 PROBE) past the isoline. The
same slope is computed from both sides (the mean is symmetric), so the fill is G1 across
isolines; the mean is monotone, so no overshoot; a ramp stays exactly a ramp. Its weights
lean towards the wider band's own slope: the standard PCHIP weighting leans the other way,
and streaked smooth skies where the neighbour read changes between samples. A cap's ramp
becomes the Hermite curve from its isoline (blended slope) to its plateau (zero slope). G1
beats the linear blend on the corpus at 1x on every metric, and PROBE 0.5 beat the other
distances tried (measured: benchmarks/results/design_choices.md#g1-profiles).
Fill "linear" keeps the paper's formula.

Shortcut at enlargements: a sample whose four surrounding nodes share its band
lies in a cell no isoline crosses, and takes the bilinear interpolation of the four nodes'
fill values; only samples in cells an isoline crosses are evaluated exactly. It stays very
close to exact evaluation everywhere, differing visibly only on a tiny share of pixels
where a band's fill has a crease (the medial axis between two sources of one side) that
the bilinear cell rounds off, and it about halves the render time of large enlargements
(measured: benchmarks/results/design_choices.md#bilinear-shortcut). (Until 2026-11 the
shortcut also asked every node to lie 2.5 nodes from every source, which left half the
cells to exact evaluation.)

Caps: a region (8-connected nodes of one band) with sources on one side only is a peak or a
pit, rendered with the cap profile of model.py: C = L + (v_cap - L) * min(1, d / min(d_max,
ramp)), d_max being the region's largest distance from its contour. A region with no source
at all takes the cap value everywhere.

Metrics (MODE_*):
  euclidean  the straight-line distance to the nearest source reached through the band
             (vector propagation, like dead reckoning);
  manhattan  the 4-neighbour path length (the paper's §4.2);
  geodesic   the path length with 5x5 chamfer steps (1, sqrt 2, sqrt 5).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...shared.unionfind import label_in_place, union
from .regions import cap_values
from .resample import bilinear_at

MODE_EUCLIDEAN, MODE_MANHATTAN, MODE_GEODESIC = 0, 1, 2
SX, SY, D, V, TX, TY = 0, 1, 2, 3, 4, 5
NF = 6
PROBE = 0.5  # node units past an isoline where the neighbouring band is read (_across)
SEED_TILE = 64  # nodes a side of the tiles seed() visits
# node units; the best PSNR of the half-lengths tried
# (measured: benchmarks/results/design_choices.md#source-half-length)
HALF = 0.25

_OFFS = {
    MODE_EUCLIDEAN: [(-1, -1), (-1, 0), (-1, 1), (0, -1)],
    MODE_MANHATTAN: [(-1, 0), (0, -1)],
    MODE_GEODESIC: [(-1, -1), (-1, 0), (-1, 1), (0, -1), (-1, -2), (-1, 2), (-2, -1), (-2, 1)],
}


def offsets(mode: int) -> np.ndarray:
    """Causal neighbour offsets (di, dj) of the forward sweep; the backward sweep negates them."""
    return np.asarray(_OFFS[mode], np.int64)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def metric(dx, dy, mode):
    if mode == 1:
        return abs(dx) + abs(dy)
    return np.sqrt(dx * dx + dy * dy)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def seg_dist(px, py, sx, sy, tx, ty, mode):
    """Distance from (px, py) to the source segment centred at (sx, sy) along (tx, ty)."""
    dx = px - sx
    dy = py - sy
    along = dx * tx + dy * ty
    if along > HALF:
        along -= HALF
    elif along < -HALF:
        along += HALF
    else:
        along = 0.0
    perp = dx * ty - dy * tx
    # back to x/y components of the residual vector for the L1 metric
    rx = along * tx + perp * ty
    ry = along * ty - perp * tx
    return metric(rx, ry, mode)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _offer_crossing(F, band, levels, i, j, sx, sy, tx, ty, going_up, mode):
    b = band[i, j]
    nl = levels.shape[0]
    if b < 0 or b > nl:
        return
    if going_up:
        if b >= nl:
            return
        s, v = 1, levels[b]
    else:
        if b < 1:
            return
        s, v = 0, levels[b - 1]
    _offer(F, s, v, i, j, sx, sy, tx, ty, mode)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _offer(F, s, v, i, j, sx, sy, tx, ty, mode):
    """Node (i, j) takes the source (sx, sy) along (tx, ty) of value v as its side s's where
    it is nearer than the one it holds."""
    d = seg_dist(j + 0.5, i + 0.5, sx, sy, tx, ty, mode)
    if d < F[s, D, i, j]:
        F[s, SX, i, j] = sx
        F[s, SY, i, j] = sy
        F[s, TX, i, j] = tx
        F[s, TY, i, j] = ty
        F[s, D, i, j] = d
        F[s, V, i, j] = v


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _unit(a, b):
    n = np.sqrt(a * a + b * b)
    return a / n, b / n


@njit(cache=True, nogil=True, error_model="numpy")
def seed(band, H, Vc, levels, mode):
    """Initial fields from the crossings: H = rasterise(...) crossing arrays of the rows,
    Vc = those of the columns (from the transposed geometry), each (fx, fd, lx, ld, fs, ls)."""
    hfx, hfd, hlx, hld, hfs, hls = H
    vfx, vfd, vlx, vld, vfs, vls = Vc
    nr, nc = band.shape
    # stored node-major, so that one node's 12 numbers share a cache line; indexed as
    # F[side, field, i, j] through a transposed view
    F = np.zeros((nr, nc, 2, NF), np.float32).transpose((2, 3, 0, 1))
    F[:, D] = np.inf
    # every offer writes only its own node, so the visiting order does not matter: tiles keep
    # the column arrays (stored transposed) in cache
    for ti in range(0, nr, SEED_TILE):
        for tj in range(0, nc, SEED_TILE):
            for i in range(ti, min(ti + SEED_TILE, nr)):
                yc = i + 0.5
                for j in range(tj, min(tj + SEED_TILE, nc)):
                    xc = j + 0.5
                    if hfd[i, j + 1] != 0:  # right, moving right
                        tx, ty = _unit(hfs[i, j + 1], 1.0)
                        _offer_crossing(F, band, levels, i, j, hfx[i, j + 1], yc, tx, ty, hfd[i, j + 1] > 0, mode)
                    if hld[i, j] != 0:  # left, moving left
                        tx, ty = _unit(hls[i, j], 1.0)
                        _offer_crossing(F, band, levels, i, j, hlx[i, j], yc, tx, ty, hld[i, j] < 0, mode)
                    # the column crossings come from the transposed (mirrored) geometry, whose
                    # winding is the negated band: moving down, the band rises where theirs falls
                    if vfd[j, i + 1] != 0:  # below, moving down
                        tx, ty = _unit(1.0, vfs[j, i + 1])
                        _offer_crossing(F, band, levels, i, j, xc, vfx[j, i + 1], tx, ty, vfd[j, i + 1] < 0, mode)
                    if vld[j, i] != 0:  # above, moving up
                        tx, ty = _unit(1.0, vls[j, i])
                        _offer_crossing(F, band, levels, i, j, xc, vlx[j, i], tx, ty, vld[j, i] > 0, mode)
    return F


@njit(cache=True, nogil=True, error_model="numpy")
def offer_coarse(F, band, levels, Fc, k, i0, j0, cuts, mode):
    """Offer each node on the window's cut edges (cuts: top, bottom, left, right, 1 where the
    window's edge lies inside the level) the sources a coarse field of the whole level found
    for the coarse node it lies in (those of the 8 round it as well gain nothing measurable on
    Kite): Fc (2, NF, nrc, ncc) at 1/k of the window's nodes a side,
    the window's first node at level node (i0, j0). A side's coarse source is offered where
    its level is that side's of the node's band; it replaces the node's own where nearer.
    The propagation then carries the sources from beyond the window inwards."""
    nr, nc = band.shape
    nrc, ncc = Fc.shape[2], Fc.shape[3]
    nl = levels.shape[0]
    for e in range(4):
        if cuts[e] == 0:
            continue
        count = nc if e < 2 else nr
        for t in range(count):
            if e == 0:
                i, j = 0, t
            elif e == 1:
                i, j = nr - 1, t
            elif e == 2:
                i, j = t, 0
            else:
                i, j = t, nc - 1
            b = band[i, j]
            ci = min(int((i0 + i + 0.5) / k), nrc - 1)
            cj = min(int((j0 + j + 0.5) / k), ncc - 1)
            for s in range(2):
                lv = b - 1 if s == 0 else b
                if lv < 0 or lv >= nl or Fc[s, D, ci, cj] == np.inf or Fc[s, V, ci, cj] != np.float32(levels[lv]):
                    continue
                _offer(F, s, levels[lv], i, j, Fc[s, SX, ci, cj] * k - j0, Fc[s, SY, ci, cj] * k - i0,
                       Fc[s, TX, ci, cj], Fc[s, TY, ci, cj], mode)


@njit(cache=True, nogil=True, error_model="numpy")
def _sweep(F, band, offs, mode, forward):
    nr, nc = band.shape
    changed = False
    no = offs.shape[0]
    so = offs.copy() if forward else -offs
    for a in range(nr):
        i = a if forward else nr - 1 - a
        for bj in range(nc):
            j = bj if forward else nc - 1 - bj
            b = band[i, j]
            for o in range(no):
                di = so[o, 0]
                dj = so[o, 1]
                ii = i + di
                jj = j + dj
                if ii < 0 or ii >= nr or jj < 0 or jj >= nc or band[ii, jj] != b:
                    continue
                for s in range(2):
                    dn = F[s, D, ii, jj]
                    if dn == np.inf:
                        continue
                    if mode == 0:
                        cand = seg_dist(j + 0.5, i + 0.5, F[s, SX, ii, jj], F[s, SY, ii, jj],
                                        F[s, TX, ii, jj], F[s, TY, ii, jj], 0)
                    else:
                        cand = dn + metric(float(dj), float(di), mode)
                    if cand < F[s, D, i, j] * (1.0 - 1e-6):
                        for f in range(NF):
                            F[s, f, i, j] = F[s, f, ii, jj]
                        F[s, D, i, j] = cand
                        changed = True
    return changed


@njit(cache=True, nogil=True, error_model="numpy")
def propagate(F, band, offs, mode, max_iter):
    """Sweep until nothing changes (at most max_iter forward/backward pairs); returns sweeps done."""
    for it in range(max_iter):
        c1 = _sweep(F, band, offs, mode, True)
        c2 = _sweep(F, band, offs, mode, False)
        if not (c1 or c2):
            return it + 1
    return max_iter


@njit(cache=True, nogil=True, error_model="numpy")
def label_nodes(band):
    """8-connected regions of equal band: (labels (nr, nc) int32, count)."""
    nr, nc = band.shape
    parent = np.empty(nr * nc, np.int32)  # int32 (a level's nodes are far below 2**31): the labels
    for k in range(nr * nc):
        parent[k] = k
    for i in range(nr):
        for j in range(nc):
            b = band[i, j]
            k = i * nc + j
            for di, dj in ((0, 1), (1, -1), (1, 0), (1, 1)):
                ii = i + di
                jj = j + dj
                if 0 <= ii < nr and 0 <= jj < nc and band[ii, jj] == b:
                    union(parent, k, ii * nc + jj)
    m = label_in_place(parent)  # numbered in scan order of each region's first node
    return parent.reshape(nr, nc), m


@njit(cache=True, nogil=True, error_model="numpy")
def region_caps(F, band, labels, m, cap_x, cap_y, cap_band, cap_value):
    """Per region: d_max of each side (0 where the side has no source) and the cap value
    (NaN where no cap annotation falls in it)."""
    nr, nc = band.shape
    dmax = np.zeros((m, 2), np.float64)
    for i in range(nr):
        for j in range(nc):
            k = labels[i, j]
            for s in range(2):
                d = F[s, D, i, j]
                if d != np.inf and d > dmax[k, s]:
                    dmax[k, s] = d
    return dmax, cap_values(band, labels, m, cap_x, cap_y, cap_band, cap_value)


@njit(cache=True, nogil=True, error_model="numpy")
def band_widths(F, band, labels, dmax, capv, ramp):
    """(nr, nc, 2) float32: per node, the width of its band through it and the band's step
    (d0 + d1 and v1 - v0), or for a cap node its ramp length and rise (signed so that the
    step runs upwards); (0, 0) where unknown. _across reads it."""
    nr, nc = band.shape
    bw = np.zeros((nr, nc, 2), np.float32)
    for i in range(nr):
        for j in range(nc):
            d0 = F[0, D, i, j]
            d1 = F[1, D, i, j]
            if d0 != np.inf and d1 != np.inf:
                bw[i, j, 0] = d0 + d1
                bw[i, j, 1] = F[1, V, i, j] - F[0, V, i, j]
            elif d0 != np.inf or d1 != np.inf:
                k = labels[i, j]
                cv = capv[k]
                if np.isnan(cv):
                    continue
                if d1 == np.inf:  # a peak above its isoline
                    bw[i, j, 0] = min(dmax[k, 0], ramp)
                    bw[i, j, 1] = cv - F[0, V, i, j]
                else:  # a pit below it
                    bw[i, j, 0] = min(dmax[k, 1], ramp)
                    bw[i, j, 1] = F[1, V, i, j] - cv
    return bw


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _across(bw, nband, want, x, y, sx, sy, d):
    """(width, step) of band `want` just beyond the source (sx, sy) seen from (x, y) at
    distance d: read in bw at the first node of that band PROBE, then 2 PROBE, past the
    isoline; (0, 0) where unknown."""
    if d <= 1e-6:
        return 0.0, 0.0
    ux = (sx - x) / d
    uy = (sy - y) / d
    nr, nc = nband.shape
    for k in range(1, 3):
        i = int(np.floor(sy + uy * PROBE * k))
        j = int(np.floor(sx + ux * PROBE * k))
        if i < 0 or i >= nr or j < 0 or j >= nc:
            return 0.0, 0.0
        if nband[i, j] == want:
            return bw[i, j, 0], bw[i, j, 1]
    return 0.0, 0.0


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _pchip_slope(s_here, w_here, s_next, w_next):
    """Slope at the isoline between two bands (values per node unit), the PCHIP weighted
    harmonic mean: monotone, and the slope of a straight ramp where both agree."""
    if w_next <= 0.0 or s_next * s_here <= 0.0:
        return s_here
    a = 2.0 * w_here + w_next
    c = w_here + 2.0 * w_next
    return (a + c) / (a / s_here + c / s_next)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _cubic(v0, v1, m0, m1, w, t):
    """The cubic Hermite curve over a stretch of length w, from v0 (slope m0) to v1 (slope
    m1), at t in [0, 1]."""
    t2 = t * t
    t3 = t2 * t
    h00 = 2.0 * t3 - 3.0 * t2 + 1.0
    h10 = t3 - 2.0 * t2 + t
    h01 = -2.0 * t3 + 3.0 * t2
    h11 = t3 - t2
    return v0 * h00 + w * m0 * h10 + v1 * h01 + w * m1 * h11


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _hermite(bw, nband, b, x, y, sx0, sy0, d0, v0, sx1, sy1, d1, v1):
    """G1 fill between the lower isoline (distance d0, value v0) and the upper one (d1, v1):
    the cubic Hermite profile whose slopes at the isolines blend this band's slope with the
    neighbouring bands' (read across each isoline), instead of the straight line whose slope
    jumps at every isoline."""
    w = d0 + d1
    sl = (v1 - v0) / w
    wl, dl = _across(bw, nband, b - 1, x, y, sx0, sy0, d0)
    wh, dh = _across(bw, nband, b + 1, x, y, sx1, sy1, d1)
    m0 = _pchip_slope(sl, w, dl / wl if wl > 0.0 else 0.0, wl)
    m1 = _pchip_slope(sl, w, dh / wh if wh > 0.0 else 0.0, wh)
    return _cubic(v0, v1, m0, m1, w, d0 / w)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _cap_hermite(bw, nband, b, x, y, s_other, sx0, sy0, sx1, sy1, d, lvl, cv, dm):
    """A cap's ramp as a cubic from its isoline (value lvl, at distance d = 0) to the plateau
    (cv at d = dm, flat): the slope at the isoline blends the ramp's with that of the band
    across the isoline, as in _hermite."""
    s_cap = (cv - lvl) / dm
    if s_other == 0:  # a peak: the band below continues the rise inwards
        wn, dn = _across(bw, nband, b - 1, x, y, sx0, sy0, d)
        sn = dn / wn if wn > 0.0 else 0.0
    else:  # a pit: the band above falls inwards
        wn, dn = _across(bw, nband, b + 1, x, y, sx1, sy1, d)
        sn = -dn / wn if wn > 0.0 else 0.0
    m0 = _pchip_slope(s_cap, dm, sn, wn)
    return _cubic(lvl, cv, m0, 0.0, dm, d / dm)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _mid(levels, b):
    """The middle of band b's two levels (the flat fill); a band beyond the extreme levels
    extends the nearest step, and a channel without levels (a hostile or degenerate file)
    spans 0..255."""
    nl = levels.shape[0]
    if nl == 0:
        return 127.5
    lo_b = levels[b - 1] if b >= 1 else levels[0] - (levels[1] - levels[0] if nl > 1 else 10.0)
    hi_b = levels[b] if b < nl else levels[nl - 1] + (levels[nl - 1] - levels[nl - 2] if nl > 1 else 10.0)
    return 0.5 * (lo_b + hi_b)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _from_nodes(nv, nband, b, x, y, i0, j0):
    """The sample (x, y) of band b read from the node fill nv, where it can be: a node itself
    (renders at 1x), or in a cell whose four nodes share its band (no isoline crosses it;
    module docstring). Returns (True, value), or (False, 0) for exact evaluation."""
    nr, nc = nband.shape
    if 0 <= i0 < nr and 0 <= j0 < nc and x == j0 + 0.5 and y == i0 + 0.5 and nband[i0, j0] == b:
        # the sample is a node: nv holds this very evaluation
        return True, np.float64(nv[i0, j0])
    if nr > 1 and nc > 1 and -1 <= i0 < nr and -1 <= j0 < nc:
        # within half a node of the frame, outside the outermost nodes, the edge
        # cell extends linearly (as the cell next to it would), so the frame gets
        # no step where exact evaluation would meet interpolation
        ic = min(max(i0, 0), nr - 2)
        jc = min(max(j0, 0), nc - 2)
        if (nband[ic, jc] == b and nband[ic, jc + 1] == b
                and nband[ic + 1, jc] == b and nband[ic + 1, jc + 1] == b):
            fx = x - (jc + 0.5)
            fy = y - (ic + 0.5)
            return True, ((1.0 - fy) * ((1.0 - fx) * nv[ic, jc] + fx * nv[ic, jc + 1])
                          + fy * ((1.0 - fx) * nv[ic + 1, jc] + fx * nv[ic + 1, jc + 1]))
    return False, 0.0


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _nearest_sources(F, nband, labels, b, x, y, i0, j0, mode):
    """The exact evaluation's search around the sample (x, y) of band b: the 2 x 2 nodes of its
    cell, then (unless they hold a node of band b, or sources of both sides) the 4 x 4 around.
    Returns the region of the nearest node of band b (-1: none) and per side (0 = lower, 1 =
    upper) the distance (inf: none), value and position of the nearest source."""
    nr, nc = nband.shape
    reg = -1
    reg_d = np.inf
    best_d0 = np.inf
    best_d1 = np.inf
    v0 = 0.0
    v1 = 0.0
    sx0 = sy0 = sx1 = sy1 = 0.0
    found = False
    for ring in range(2):
        lo_i = i0 - ring
        hi_i = i0 + 1 + ring
        lo_j = j0 - ring
        hi_j = j0 + 1 + ring
        for i in range(lo_i, hi_i + 1):
            if i < 0 or i >= nr:
                continue
            inner = ring == 1 and i0 <= i <= i0 + 1
            for j in range(lo_j, hi_j + 1):
                if j < 0 or j >= nc or (inner and j0 <= j <= j0 + 1):
                    continue  # (the cell's own nodes, seen in ring 0, would change nothing)
                bn = nband[i, j]
                if bn == b:
                    found = True
                    dn2 = (j + 0.5 - x) ** 2 + (i + 0.5 - y) ** 2
                    if dn2 < reg_d:
                        reg_d = dn2
                        reg = labels[i, j]
                    s_lo, s_hi = 0, 2
                elif bn == b - 1:
                    # a node just below: its upper isoline is this sample's lower one
                    s_lo, s_hi = 1, 2
                elif bn == b + 1:
                    # a node just above: its lower isoline is this sample's upper one
                    s_lo, s_hi = 0, 1
                else:
                    continue
                for s in range(s_lo, s_hi):
                    dn = F[s, D, i, j]
                    if dn == np.inf:
                        continue
                    sx = F[s, SX, i, j]
                    sy = F[s, SY, i, j]
                    tx = F[s, TX, i, j]
                    ty = F[s, TY, i, j]
                    cand = seg_dist(x, y, sx, sy, tx, ty, mode)
                    if mode != 0 and bn == b:
                        # the path to the node, with its last leg re-aimed at the sample
                        cand += dn - seg_dist(j + 0.5, i + 0.5, sx, sy, tx, ty, mode)
                    side = s if bn == b else 1 - s
                    if side == 0:
                        if cand < best_d0:
                            best_d0 = cand
                            v0 = F[s, V, i, j]
                            sx0, sy0 = sx, sy
                    else:
                        if cand < best_d1:
                            best_d1 = cand
                            v1 = F[s, V, i, j]
                            sx1, sy1 = sx, sy
        if found or (best_d0 < np.inf and best_d1 < np.inf):
            break
    return reg, best_d0, v0, sx0, sy0, best_d1, v1, sx1, sy1


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _one_sided(bw, nband, dmax, capv, ramp, levels, b, x, y, reg, d0, v0, sx0, sy0, d1, v1, sx1, sy1, smooth):
    """The fill where a side has no source: the region's cap profile (peak: only the lower
    level is a source; pit: only the upper), the band's middle without a cap."""
    mid = _mid(levels, b)
    cv = capv[reg] if reg >= 0 else np.nan
    if d0 == np.inf and d1 == np.inf:
        return mid if np.isnan(cv) else cv
    if d0 == np.inf:  # a pit: only the level above is a source
        lvl, d, s_other = v1, d1, 1
    else:  # a peak
        lvl, d, s_other = v0, d0, 0
    if np.isnan(cv):
        return 0.5 * (lvl + mid)
    dm = min(dmax[reg, s_other], ramp)
    if dm <= 0.0 or d >= dm:
        return cv
    if not smooth:
        return lvl + (cv - lvl) * d / dm
    return _cap_hermite(bw, nband, b, x, y, s_other, sx0, sy0, sx1, sy1, d, lvl, cv, dm)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _between(bw, nband, b, x, y, d0, v0, sx0, sy0, d1, v1, sx1, sy1, smooth):
    """The fill between a lower and an upper source: the straight line (fill "linear") or
    the G1 Hermite profile."""
    tot = d0 + d1
    if tot <= 0.0:
        return 0.5 * (v0 + v1)
    if not smooth:
        return (v0 * d1 + v1 * d0) / tot
    return _hermite(bw, nband, b, x, y, sx0, sy0, d0, v0, sx1, sy1, d1, v1)


@njit(cache=True, nogil=True, error_model="numpy")
def evaluate(F, nband, labels, dmax, capv, ramp, tband, xs, ys, levels, mode, flat, nv, out, smooth, bw,
             corr):
    """Fill values at target samples.

    tband (n, m): band of each target sample; xs (m,), ys (n,): their positions in node units.
    labels, dmax, capv: node regions and their cap data (label_nodes, region_caps); ramp: the
    cap ramp in node units. nv: the fill at the nodes themselves (this function applied to
    the node grid), or an empty array: a sample whose four surrounding nodes all share its
    band interpolates them bilinearly (no isoline crosses that cell; module docstring), the
    others are evaluated exactly.
    out (n, m) float32 receives the values.
    smooth: G1 profiles (fill "diffusion") with bw = band_widths(...), else straight lines
    (fill "linear"; bw unused).
    corr: the enlargement sharpening at the nodes (render/sharpen.py), or an empty array.
    When given, nv must hold the node fill plus corr: the samples read from nv get the
    sharpening with it, the exactly evaluated ones add its bilinear interpolation.
    """
    use_corr = corr.shape[0] > 0
    exact = np.zeros(tband.shape[1] if use_corr else 0, np.bool_)
    use_nv = nv.shape[0] == nband.shape[0]
    nl = levels.shape[0]
    n, m = tband.shape
    for a in range(n):
        y = ys[a]
        i0 = int(np.floor(y - 0.5))
        for bcol in range(m):
            x = xs[bcol]
            b = tband[a, bcol]
            # a chain that loops on itself (or a hostile file) can push the winding sum out
            # of range; clamp so that every sample stays between the channel's extremes
            if b < 0:
                b = 0
            elif b > nl:
                b = nl
            if flat:
                out[a, bcol] = _mid(levels, b)
                continue
            j0 = int(np.floor(x - 0.5))
            if use_nv:
                hit, value = _from_nodes(nv, nband, b, x, y, i0, j0)
                if hit:
                    out[a, bcol] = value
                    continue
            if use_corr:
                exact[bcol] = True  # evaluated exactly: corr is added below
            reg, d0, v0, sx0, sy0, d1, v1, sx1, sy1 = _nearest_sources(F, nband, labels, b, x, y, i0, j0, mode)
            if d0 == np.inf or d1 == np.inf:
                out[a, bcol] = _one_sided(bw, nband, dmax, capv, ramp, levels, b, x, y, reg, d0, v0, sx0, sy0,
                                          d1, v1, sx1, sy1, smooth)
            else:
                out[a, bcol] = _between(bw, nband, b, x, y, d0, v0, sx0, sy0, d1, v1, sx1, sy1, smooth)
        if use_corr:
            for bcol in range(m):
                if exact[bcol]:
                    out[a, bcol] += bilinear_at(corr, xs[bcol], y)
                    exact[bcol] = False
