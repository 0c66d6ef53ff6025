"""Marching squares over all levels of a channel in one scan (kernel; its NumPy twin is marching_ref.py).

Input is a padded grid: the outer ring (row 0, last row, column 0, last column) is padding
that lies below every level (band 0), so every contour closes; segments in cells that touch
the padding run exactly along the image border and are flagged as border.

Cell corners: 0 = top-left (r, c), 1 = top-right (r, c+1), 2 = bottom-right (r+1, c+1),
3 = bottom-left (r+1, c). Edge k joins corner k and corner (k+1) % 4.
A segment from a crossing on edge ea to one on edge eb has corners ea+1 .. eb (cyclically)
on its left as seen on screen (y down); segments are oriented so that the corners at or
above the level are on the left.

Saddles: the asymptotic decider. The bilinear interpolant's value at its saddle point is
s = (a c - b d) / (a + c - b - d) for corners a, b, c, d = 0, 1, 2, 3. If s >= level the
centre is above and the below corners are cut off singly; otherwise the above corners are.

Per segment the kernel reports: start and end keys (edge id * n_levels + level; a crossing
is shared by the two cells of its edge, so keys link segments into loops), the level, the
border flag, and the start crossing as (below sample, above sample, t): the point lies at
t of the way from the below sample to the above sample (t = 1 when the below one is padding).

Crossings: :func:`march` reports the linear t, (level - below) / (above - below). The loops
of :func:`march_loops` place each crossing on the monotone cubic along its grid edge
instead: the cubic Hermite through the edge's two samples with Catmull-Rom end slopes (from
the samples one step beyond either end, or the end's own value on the padding), clipped to
0 when they point against the edge's rise and scaled into Fritsch and Carlson's circle of
radius 3 so that it rises monotonically. Crossings of several levels on one edge keep
their order, so loops still never cross; on a linear ramp the cubic is the straight line.
The grid's midpoints are cubic interpolants already (encoder/mapping.py); the cubic
crossing carries that between the samples: better enlargements and a better 1x render
for slightly more bytes (measured: benchmarks/results/design_choices.md#cubic-crossings).

Linking: the segment after s starts where s ends, on the same edge and level, in the cell
across that edge, so :func:`march_loops` finds it among that cell's few segments (no sort);
loops start at, and are ordered by, their smallest start key.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# corner offsets (dr, dc) and edge -> (corner a, corner b)
_CDR = np.array([0, 0, 1, 1], np.int64)
_CDC = np.array([0, 1, 1, 0], np.int64)
# Most Newton (or bisection) steps that place a crossing on its edge's cubic (_cubic_t), and
# the step below which it stops: Newton converges quadratically, so after a step of 1e-7
# (of the edge, half a pixel) the crossing is within about 1e-14 of the root.
CUBIC_ITERATIONS = 30
CUBIC_STEP = 1e-7


@njit(cache=True, nogil=True)
def _edge_id(r, c, k, hp, wp):
    # horizontal edges: id = r * wp + c for (r, c)-(r, c+1); vertical: hp*wp + r*wp + c for (r, c)-(r+1, c)
    if k == 0:
        return r * wp + c
    if k == 1:
        return hp * wp + r * wp + (c + 1)
    if k == 2:
        return (r + 1) * wp + c
    return hp * wp + r * wp + c


@njit(cache=True, nogil=True)
def pad_bands(grid, levels):
    """Padded values and bands: a ring of band 0 (value 0) around the grid. The band of v
    is the number of levels <= v (np.searchsorted(levels, v, "right"))."""
    hg, wg = grid.shape
    vals = np.zeros((hg + 2, wg + 2))
    band = np.zeros((hg + 2, wg + 2), np.int16)
    for r in range(hg):
        for c in range(wg):
            v = grid[r, c]
            vals[r + 1, c + 1] = v
            band[r + 1, c + 1] = _band(levels, v)
    return vals, band


@njit(cache=True, nogil=True, inline="always")
def _band(levels, v):
    """The number of levels <= v (np.searchsorted(levels, v, "right"))."""
    lo = 0
    hi = levels.shape[0]
    while lo < hi:
        mid = (lo + hi) >> 1
        if levels[mid] <= v:
            lo = mid + 1
        else:
            hi = mid
    return lo


@njit(cache=True, nogil=True)
def band_of(vals, levels, out):
    """out[r, c] = the number of levels <= vals[r, c] (np.searchsorted(levels, v, "right"),
    pad_bands' rule), for a window of values."""
    for r in range(vals.shape[0]):
        for c in range(vals.shape[1]):
            out[r, c] = _band(levels, vals[r, c])


@njit(cache=True, nogil=True)
def _march_cells(vals, band, levels):
    """The segments of every cell and level (the kernel of the module docstring), in scan
    order, with what linking needs. Per segment: its cell
    (r (wp - 1) + c), level, start and end edge; rec[s] = (free for the caller; start key;
    below sample; above sample; 2 level + border flag) and t. Segments of cell k are
    cell_start[k]:cell_start[k+1]."""
    return _march_cells_rows(vals, band, levels, 0, vals.shape[0], 0, vals.shape[0] - 1)


@njit(cache=True, nogil=True)
def _march_cells_rows(vals, band, levels, w0, hp, r0, r1):
    """:func:`_march_cells` for the cells of padded rows [r0, r1) of a grid of hp rows, of
    which vals and band hold the rows from w0 on (a strip and its margin): edge ids, sample
    indices and border flags are the whole grid's; cells are numbered (r - r0) (wp - 1) + c."""
    wp = vals.shape[1]
    nl = levels.shape[0]
    ncell = (r1 - r0) * (wp - 1)
    # count first: a cell has one segment per level between its lowest and highest corner
    # band, and a second one for each level that makes it a saddle
    cell_start = np.empty(ncell + 1, np.int64)
    cap = 0
    for r in range(r0, r1):
        for c in range(wp - 1):
            cell_start[(r - r0) * (wp - 1) + c] = cap
            b0 = band[r - w0, c]
            b1 = band[r - w0, c + 1]
            b2 = band[r - w0 + 1, c + 1]
            b3 = band[r - w0 + 1, c]
            cap += (max(max(b0, b1), max(b2, b3)) - min(min(b0, b1), min(b2, b3))
                    + max(0, min(b0, b2) - max(b1, b3)) + max(0, min(b1, b3) - max(b0, b2)))
    cell_start[ncell] = cap
    s_cell = np.empty(cap, np.int64)
    s_lev = np.empty(cap, np.int64)
    s_ea = np.empty(cap, np.int8)
    s_eb = np.empty(cap, np.int8)
    rec = np.empty((cap, 5), np.int64)
    s_t = np.empty(cap, np.float64)
    cv = np.empty(4, np.float64)
    cb = np.empty(4, np.int64)
    cidx = np.empty(4, np.int64)
    cpad = np.empty(4, np.bool_)
    above = np.empty(4, np.bool_)
    cross = np.empty(4, np.int64)
    segs_a = np.empty(2, np.int64)
    segs_b = np.empty(2, np.int64)
    n = 0
    for r in range(r0, r1):
        for c in range(wp - 1):
            b0 = band[r - w0, c]
            b1 = band[r - w0, c + 1]
            b2 = band[r - w0 + 1, c + 1]
            b3 = band[r - w0 + 1, c]
            bmin = min(min(b0, b1), min(b2, b3))
            bmax = max(max(b0, b1), max(b2, b3))
            if bmin == bmax:
                continue
            cell = (r - r0) * (wp - 1) + c
            anypad = r == 0 or c == 0 or r + 1 == hp - 1 or c + 1 == wp - 1
            for k in range(4):
                rr = r + _CDR[k]
                cc = c + _CDC[k]
                cv[k] = vals[rr - w0, cc]
                cb[k] = band[rr - w0, cc]
                cidx[k] = rr * wp + cc
                cpad[k] = rr == 0 or cc == 0 or rr == hp - 1 or cc == wp - 1
            for l in range(bmin, bmax):
                L = levels[l]
                for k in range(4):
                    above[k] = cb[k] > l
                nc = 0
                for k in range(4):
                    if above[k] != above[(k + 1) % 4]:
                        cross[nc] = k
                        nc += 1
                ns = 0
                if nc == 2:
                    ea = cross[0]
                    eb = cross[1]
                    if above[(ea + 1) % 4]:
                        segs_a[0] = ea
                        segs_b[0] = eb
                    else:
                        segs_a[0] = eb
                        segs_b[0] = ea
                    ns = 1
                else:
                    den = cv[0] + cv[2] - cv[1] - cv[3]
                    s = (cv[0] * cv[2] - cv[1] * cv[3]) / den
                    centre_above = s >= L
                    for k in range(4):
                        if above[k] != centre_above:
                            ep = (k + 3) % 4
                            if above[k]:
                                segs_a[ns] = ep
                                segs_b[ns] = k
                            else:
                                segs_a[ns] = k
                                segs_b[ns] = ep
                            ns += 1
                for q in range(ns):
                    ea = segs_a[q]
                    s_cell[n] = cell
                    s_lev[n] = l
                    s_ea[n] = ea
                    s_eb[n] = segs_b[q]
                    ka = ea
                    kb = (ea + 1) % 4
                    if above[ka]:
                        ka, kb = kb, ka
                    rec[n, 1] = _edge_id(r, c, ea, hp, wp) * nl + l
                    rec[n, 2] = cidx[ka]
                    rec[n, 3] = cidx[kb]
                    rec[n, 4] = 2 * l + (1 if anypad else 0)
                    if cpad[ka]:
                        s_t[n] = 1.0
                    else:
                        s_t[n] = (L - cv[ka]) / (cv[kb] - cv[ka])
                    n += 1
    return n, s_cell, s_lev, s_ea, s_eb, rec, s_t, cell_start


def march(vals, band, levels):
    """The segments of the marching kernel as per-segment arrays (see module docstring), in
    scan order: skey, ekey, level, border, below, above, t."""
    vals = np.ascontiguousarray(vals, np.float64)
    band = np.ascontiguousarray(band)
    levels = np.ascontiguousarray(levels, np.float64)
    hp, wp = vals.shape
    n, s_cell, s_lev, _, s_eb, rec, s_t, _ = _march_cells(vals, band, levels)
    r, c = np.divmod(s_cell[:n], wp - 1)
    eb = s_eb[:n]
    edge = np.where(eb == 0, r * wp + c, np.where(eb == 1, hp * wp + r * wp + c + 1,
                    np.where(eb == 2, (r + 1) * wp + c, hp * wp + r * wp + c)))
    return dict(
        skey=rec[:n, 1].copy(), ekey=edge * levels.shape[0] + s_lev[:n], level=s_lev[:n].astype(np.int32),
        border=(rec[:n, 4] & 1).astype(bool), below=rec[:n, 2].copy(), above=rec[:n, 3].copy(),
        t=s_t[:n].copy(),
    )


# ---------------------------------------------------------------------------------------
# Marching, linking and the per-point gathers of encoder/isolines.py in one kernel; its twin
# (marching_ref.march_loops) is marching_ref.march, a plain walk along the keys, and NumPy gathers.
# ---------------------------------------------------------------------------------------


@njit(cache=True, nogil=True)
def _grad_at(grid, r, c):
    """|grad| of the (unpadded) grid at sample (r, c): np.gradient(grid, 0.5) and hypot,
    as encoder/ribbon.py's gradient_magnitude."""
    hg, wg = grid.shape
    if r == 0:
        gy = (grid[1, c] - grid[0, c]) / 0.5
    elif r == hg - 1:
        gy = (grid[hg - 1, c] - grid[hg - 2, c]) / 0.5
    else:
        gy = (grid[r + 1, c] - grid[r - 1, c]) / (2.0 * 0.5)
    if c == 0:
        gx = (grid[r, 1] - grid[r, 0]) / 0.5
    elif c == wg - 1:
        gx = (grid[r, wg - 1] - grid[r, wg - 2]) / 0.5
    else:
        gx = (grid[r, c + 1] - grid[r, c - 1]) / (2.0 * 0.5)
    return math.hypot(gx, gy)


@njit(cache=True, nogil=True, error_model="numpy")
def _cubic_t(vm, v0, v1, v2, t):
    """Where the monotone cubic through v0 (at 0) and v1 (at 1) reaches the value that the
    straight line between them reaches at t (module docstring: "Crossings"); vm and v2 are
    the samples one step beyond either end. Needs v0 < v1 and 0 < t <= 1."""
    d = v1 - v0
    a = 0.5 * (v1 - vm) / d  # Catmull-Rom end slopes, relative to the chord
    b = 0.5 * (v2 - v0) / d
    if a < 0.0:
        a = 0.0
    if b < 0.0:
        b = 0.0
    r = a * a + b * b
    if r > 9.0:  # Fritsch-Carlson: inside the circle of radius 3 the cubic is monotone
        f = 3.0 / math.sqrt(r)
        a *= f
        b *= f
    c2 = 3.0 - 2.0 * a - b
    c3 = a + b - 2.0
    lo = 0.0
    hi = 1.0
    x = t
    for _ in range(CUBIC_ITERATIONS):
        g = ((c3 * x + c2) * x + a) * x - t
        if g == 0.0:
            return x
        if g < 0.0:
            lo = x
        else:
            hi = x
        dg = (3.0 * c3 * x + 2.0 * c2) * x + a
        xn = x - g / dg if dg > 0.0 else 0.5 * (lo + hi)
        if not (lo < xn < hi):
            xn = 0.5 * (lo + hi)
        if abs(xn - x) <= CUBIC_STEP:
            return xn
        x = xn
    return x


@njit(cache=True, nogil=True)
def _link(n, s_cell, s_lev, s_ea, s_eb, cell_start, hp, wp):
    """The segment after each segment s: the one that starts on s's end edge, in the cell
    across it, at the same level. Returns (nxt, ok); ok False where one has none."""
    # The links go to a compact array of their own: walking the loops chases them one
    # dependent load after another, in an order that jumps a row of cells at every
    # vertical step, so the fewer bytes they span the fewer cache misses.
    nxt, _, ok = link_rows(n, s_cell, s_lev, s_ea, s_eb, cell_start, hp, wp, 0, hp - 1)
    for s in range(n):
        if nxt[s] == -2:
            nxt[s] = -1
            ok = False
    return nxt, ok


@njit(cache=True, nogil=True)
def link_rows(n, s_cell, s_lev, s_ea, s_eb, cell_start, hp, wp, r0, r1):
    """:func:`_link` for the segments of the cells of padded rows [r0, r1) (cells numbered
    from r0, as _march_cells_rows does): (nxt, has_pred, ok), nxt -2 where the next cell lies
    outside those rows, has_pred where a segment leads to it."""
    nxt = np.full(n, -1, np.int64)
    has_pred = np.zeros(n, np.bool_)
    ok = True
    for s in range(n):
        cell = s_cell[s]
        r = cell // (wp - 1)
        c = cell - r * (wp - 1)
        r += r0
        eb = s_eb[s]
        if eb == 0:
            r -= 1
        elif eb == 1:
            c += 1
        elif eb == 2:
            r += 1
        else:
            c -= 1
        if r < r0 or r >= r1:
            nxt[s] = -2
            continue
        if c < 0 or c >= wp - 1:
            ok = False
            break
        other = (r - r0) * (wp - 1) + c
        want = (eb + 2) % 4
        for s2 in range(cell_start[other], cell_start[other + 1]):
            if s_lev[s2] == s_lev[s] and s_ea[s2] == want:
                nxt[s] = s2
                has_pred[s2] = True
                break
        if nxt[s] < 0:
            ok = False
            break
    return nxt, has_pred, ok


@njit(cache=True, nogil=True)
def _walk(nxt, n, ok):
    """Each loop walked once (from its first segment in scan order), following the links
    alone: (trav, lp_start, n_loops, m, ok), the segments in travel order and where each
    loop starts in them. A visited segment's link becomes -1."""
    trav = np.empty(n if ok else 0, np.int64)
    lp_start = np.empty(n + 1, np.int64)
    lp_start[0] = 0
    n_loops = 0
    m = 0
    if ok:
        for s0 in range(n):
            if nxt[s0] < 0:
                continue
            j = s0
            while nxt[j] >= 0:
                trav[m] = j
                m += 1
                jn = nxt[j]
                nxt[j] = -1
                j = jn
            if j != s0:
                ok = False
                break
            n_loops += 1
            lp_start[n_loops] = m
    if not ok:
        n_loops = 0
    return trav, lp_start, n_loops, m, ok


@njit(cache=True, nogil=True)
def _loop_keys(rec, trav, lp_start, n_loops, m, ok):
    """Per loop: its smallest start key, where that is, whether it has an isoline segment,
    and its level; the segments' t, samples and flags are copied to a buffer tb in travel
    order on the way (gathers in travel order are independent loads, unlike the walk)."""
    lp_key = np.empty(n_loops, np.int64)
    lp_at = np.empty(n_loops, np.int64)
    lp_inner = np.empty(n_loops, np.bool_)
    lp_lev = np.empty(n_loops, np.int64)
    tb = np.empty((m if ok else 0, 4), np.int64)  # t (bits), below, above, 2 level + border
    for a in range(n_loops):
        o = lp_start[a]
        bkey = rec[trav[o], 1]
        at = 0
        inner = False
        for k in range(lp_start[a + 1] - o):
            j = trav[o + k]
            key = rec[j, 1]
            if key < bkey:
                bkey = key
                at = k
            tb[o + k, 0] = rec[j, 0]
            tb[o + k, 1] = rec[j, 2]
            tb[o + k, 2] = rec[j, 3]
            tb[o + k, 3] = rec[j, 4]
            inner = inner or (rec[j, 4] & 1) == 0
        lp_key[a] = bkey
        lp_at[a] = at
        lp_inner[a] = inner
        lp_lev[a] = tb[o, 3] >> 1
    return lp_key, lp_at, lp_inner, lp_lev, tb


@njit(cache=True, nogil=True)
def _crossing_t(vals_f, b, ab, tt, rb, cb, ra, ca, hp, wp):
    """t of the crossing between the below sample b and the above one ab (flat padded
    indices at (rb, cb) and (ra, ca)): on the monotone cubic through the samples beyond both
    ends where b is off the padding (a sample beyond on the padding is replaced by the end's
    own), else the linear tt."""
    if rb > 0 and cb > 0 and rb < hp - 1 and cb < wp - 1:
        step = ab - b
        v0 = vals_f[b]
        v1 = vals_f[ab]
        r2 = 2 * rb - ra  # the sample before the below one, and after the above one
        c2 = 2 * cb - ca
        vm = vals_f[b - step] if 0 < r2 < hp - 1 and 0 < c2 < wp - 1 else v0
        r2 = 2 * ra - rb
        c2 = 2 * ca - cb
        v2 = vals_f[ab + step] if 0 < r2 < hp - 1 and 0 < c2 < wp - 1 else v1
        tt = _cubic_t(vm, v0, v1, v2, tt)
    return tt


@njit(cache=True, nogil=True)
def _gather_points(vals, grid, grid_eps, tb, lp_start, lp_key, lp_at, lp_inner, lp_lev, n_loops):
    """The kept loops in order of their smallest start key, each rotated to start there;
    per point, in travel order: (x, y), the border flag of the segment it starts, its below
    and above samples, t, and the errors and gradients at those samples (march_loops)."""
    hp, wp = vals.shape
    tb_f = tb.view(np.float64)
    order = np.argsort(lp_key)
    vals_f = vals.ravel()
    n_out = 0
    n_kept = 0
    for a in range(n_loops):
        if lp_inner[a]:
            n_out += lp_start[a + 1] - lp_start[a]
            n_kept += 1
    points = np.empty((n_out, 2))
    border = np.empty(n_out, np.bool_)
    below = np.empty(n_out, np.int32)  # sample indices: the padded grid of MAX_PIXELS has under 2**31
    above = np.empty(n_out, np.int32)
    t = np.empty(n_out)
    eps_b = np.empty(n_out)
    eps_a = np.empty(n_out)
    grad_b = np.empty(n_out)
    grad_a = np.empty(n_out)
    level = np.empty(n_kept, np.int32)
    offsets = np.empty(n_kept + 1, np.int64)
    frame_levels = np.empty(n_loops - n_kept, np.int64)
    offsets[0] = 0
    m = 0
    kl = 0
    fl = 0
    for a in range(n_loops):
        lp = order[a]
        o = lp_start[lp]
        length = lp_start[lp + 1] - o
        if not lp_inner[lp]:
            frame_levels[fl] = lp_lev[lp]
            fl += 1
            continue
        level[kl] = lp_lev[lp]
        for k in range(length):
            src = o + lp_at[lp] + k
            if src >= o + length:
                src -= length
            b = tb[src, 1]
            ab = tb[src, 2]
            rb = b // wp
            cb = b - rb * wp
            ra = ab // wp
            ca = ab - ra * wp
            tt = _crossing_t(vals_f, b, ab, tb_f[src, 0], rb, cb, ra, ca, hp, wp)
            # padded (r, c) -> image (x, y) = ((c - 1) / 2, (r - 1) / 2)
            points[m, 0] = ((cb - 1) + tt * (ca - cb)) * 0.5
            points[m, 1] = ((rb - 1) + tt * (ra - rb)) * 0.5
            t[m] = tt
            # sample errors and |grad| at both samples (0 on the padding), as
            # encoder/ribbon.py's gradient_magnitude; the above sample is never padding
            if rb > 0 and cb > 0 and rb < hp - 1 and cb < wp - 1:
                eps_b[m] = grid_eps[rb - 1, cb - 1]
                grad_b[m] = _grad_at(grid, rb - 1, cb - 1)
            else:
                eps_b[m] = 0.0
                grad_b[m] = 0.0
            eps_a[m] = grid_eps[ra - 1, ca - 1]
            grad_a[m] = _grad_at(grid, ra - 1, ca - 1)
            below[m] = b
            above[m] = ab
            border[m] = (tb[src, 3] & 1) != 0
            m += 1
        kl += 1
        offsets[kl] = m
    return points, border, below, above, t, eps_b, eps_a, grad_b, grad_a, level, offsets, frame_levels


@njit(cache=True, nogil=True)
def march_loops(vals, band, levels, grid, grid_eps):
    """All isolines of a padded grid as loops, in one call: marching, linking, and the
    per-point data of encoder/isolines.py.

    grid, grid_eps : the unpadded grid (vals without its ring) and its sample errors.
    Loops are ordered by, and start at, their segment of smallest start key (as
    link_loops); loops with no isoline segment (wholly on the frame) are left out and their
    levels returned. Per point of the kept loops, in travel order: (x, y), the border flag
    of the segment it starts, its below and above samples (flat padded indices) and t, and
    the sample errors and gradient magnitudes at the below and above samples (0 on the
    padding). Returns ok False (and empty arrays) if the segments do not close into loops.
    """
    hp, wp = vals.shape
    n, s_cell, s_lev, s_ea, s_eb, rec, s_t, cell_start = _march_cells(vals, band, levels)
    nxt, ok = _link(n, s_cell, s_lev, s_ea, s_eb, cell_start, hp, wp)
    # rec[:, 0] takes t (its bits), so that the gathers below find a segment's data on one
    # cache line
    rec_f = rec.view(np.float64)
    for s in range(n):
        rec_f[s, 0] = s_t[s]
    # what only linking needed goes (memory: about 150 bytes a segment remain at peak)
    s_t = s_t[:0].copy()
    s_cell = s_cell[:0].copy()
    s_lev = s_lev[:0].copy()
    s_ea = s_ea[:0].copy()
    s_eb = s_eb[:0].copy()
    cell_start = cell_start[:0].copy()
    trav, lp_start, n_loops, m, ok = _walk(nxt, n, ok)
    nxt = nxt[:0].copy()
    lp_key, lp_at, lp_inner, lp_lev, tb = _loop_keys(rec, trav, lp_start, n_loops, m, ok)
    rec = rec[:0].copy()
    trav = trav[:0].copy()
    return (ok,) + _gather_points(vals, grid, grid_eps, tb, lp_start, lp_key, lp_at, lp_inner, lp_lev, n_loops)
