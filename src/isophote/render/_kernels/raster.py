"""Scanline winding accumulation (kernel; its NumPy twin is raster_ref.py).

Grid convention: sample (i, j) sits at (j + 0.5, i + 0.5) in grid units, and is tested at
(j + 0.5 + NUDGE_X, i + 0.5 + NUDGE_Y). Chain joints lie on a 1/64 px lattice, often exactly on
sample rows and columns: a joint touching a row from one side would give a pair of crossings
that cancel in the band but not in the crossing record (a phantom distance source), and an
isoline through a sample would be counted on one side by the rows and on the other by the
columns. The nudge, off every such lattice and far below any visible distance, settles both
the same way in both directions (the transposed raster of the columns, ``transposed``, tests
the same point). Its two components differ, in a ratio no lattice slope has: with equal ones
a straight edge at 45 degrees through a sample would pass through the tested point itself,
and the rows and the columns would settle it on opposite sides (a phantom source).
An edge crosses row i when min(y0, y1) <= yc < max(y0, y1), yc = i + 0.5 + NUDGE_Y
(half-open, so a joint a chain passes through counts once); the crossing at x changes the
winding of every sample of the row tested right of x, i.e. samples j >= k with
k = floor(x + 0.5 - NUDGE_X): the crossing lies in "gap" k, between samples k - 1 and k (gap 0
is left of the first sample, gap n_cols right of the last). With ``transposed`` (x and y
swapped by the caller) the two components swap too.
An edge going down (y1 > y0) adds +1; contours with their above side on the left then add
up to the band index (see model.py).

With ``crossings`` the kernel also records, per gap, the leftmost and rightmost crossing (x
and the winding change, 0 when the edge is a border stretch, which is no source): the exact
isoline positions next to each sample, which seed the distance fields of the diffusion fill.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...geometry.flatten import MAX_STEPS, point, steps

NUDGE_X = 2.0**-21
NUDGE_Y = 2.0**-21 * 0.6180339887498949  # (sqrt(5) - 1) / 2: no lattice slope


@njit(cache=True, nogil=True, error_model="numpy")
def rasterise(x0, y0, x1, y1, is_src, row0, col0, n_rows, n_cols, crossings, transposed=False):
    """Band (winding sum) of rows row0 .. row0 + n_rows - 1, columns col0 .. col0 + n_cols - 1.

    Returns (band (n_rows, n_cols) int16, first_x, first_dw, last_x, last_dw, first_slope,
    last_slope), the last six (n_rows, n_cols + 1) arrays (empty unless ``crossings``): per
    gap, the leftmost and rightmost crossing (dw = 0 where the gap has none, or where that
    crossing is a border edge's) and the crossing edge's dx/dy.
    """
    acc = _accumulators(n_rows, n_cols, crossings)
    nudge_row, nudge_col = (NUDGE_X, NUDGE_Y) if transposed else (NUDGE_Y, NUDGE_X)
    for e in range(x0.shape[0]):
        _edge(acc, x0[e], y0[e], x1[e], y1[e], is_src[e], row0, col0, n_rows, n_cols, crossings, nudge_row, nudge_col)
    return _finish(acc, n_rows, n_cols)


@njit(cache=True, nogil=True, error_model="numpy")
def rasterise_chains(points, first, border, ids, tol, kx, ox, ky, oy, swap, row0, col0, n_rows, n_cols, crossings,
                     transposed=False):
    """rasterise() of the edges flatten_selected(points, first, border, ids, tol) would give,
    mapped to grid units (x * kx - ox, y * ky - oy; swapped with ``swap``), in the same order,
    without building them: the same band and crossings, bit for bit."""
    acc = _accumulators(n_rows, n_cols, crossings)
    nudge_row, nudge_col = (NUDGE_X, NUDGE_Y) if transposed else (NUDGE_Y, NUDGE_X)
    for q in range(ids.shape[0]):
        k = ids[q]
        f = first[k]
        n = steps(points, f, border[k], tol, MAX_STEPS)
        src = not border[k]
        px, py = points[f, 0] * kx - ox, points[f, 1] * ky - oy
        if swap:
            px, py = py, px
        pr = _row_of(py, nudge_row)
        for i in range(1, n + 1):
            sx, sy = point(points, f, i, n)
            qx, qy = sx * kx - ox, sy * ky - oy
            if swap:
                qx, qy = qy, qx
            qr = _row_of(qy, nudge_row)
            if qr != pr:
                _edge_rows(acc, px, py, qx, qy, pr, qr, src, row0, col0, n_rows, n_cols, crossings, nudge_row,
                           nudge_col)
            px, py, pr = qx, qy, qr
    return _finish(acc, n_rows, n_cols)


@njit(cache=True, nogil=True, error_model="numpy")
def rasterise_window(points, first, border, ids, tol, r, j0, i0, n_rows, n_cols):
    """A window's rows and columns at once: (rasterise_chains(..., r, j0, r, i0, False, 0, 0,
    n_rows, n_cols, True), rasterise_chains(..., r, j0, r, i0, True, 0, 0, n_cols, n_rows, True,
    True)), flattening each segment once for both."""
    rows = _accumulators(n_rows, n_cols, True)
    cols = _accumulators(n_cols, n_rows, True)
    for q in range(ids.shape[0]):
        k = ids[q]
        f = first[k]
        n = steps(points, f, border[k], tol, MAX_STEPS)
        src = not border[k]
        px, py = points[f, 0] * r - j0, points[f, 1] * r - i0
        pr, pc = _row_of(py, NUDGE_Y), _row_of(px, NUDGE_X)
        for i in range(1, n + 1):
            sx, sy = point(points, f, i, n)
            qx, qy = sx * r - j0, sy * r - i0
            qr, qc = _row_of(qy, NUDGE_Y), _row_of(qx, NUDGE_X)
            if qr != pr:
                _edge_rows(rows, px, py, qx, qy, pr, qr, src, 0, 0, n_rows, n_cols, True, NUDGE_Y, NUDGE_X)
            if qc != pc:
                _edge_rows(cols, py, px, qy, qx, pc, qc, src, 0, 0, n_cols, n_rows, True, NUDGE_X, NUDGE_Y)
            px, py, pr, pc = qx, qy, qr, qc
    return _finish(rows, n_rows, n_cols), _finish(cols, n_cols, n_rows)


@njit(cache=True, nogil=True, error_model="numpy")
def _accumulators(n_rows, n_cols, crossings):
    delta = np.zeros((n_rows, n_cols + 1), np.int32)
    if crossings:
        fx = np.full((n_rows, n_cols + 1), np.inf, np.float64)
        lx = np.full((n_rows, n_cols + 1), -np.inf, np.float64)
        fd = np.zeros((n_rows, n_cols + 1), np.int8)
        ld = np.zeros((n_rows, n_cols + 1), np.int8)
        fs = np.zeros((n_rows, n_cols + 1), np.float32)
        ls = np.zeros((n_rows, n_cols + 1), np.float32)
    else:
        fx = np.empty((0, 0), np.float64)
        lx = np.empty((0, 0), np.float64)
        fd = np.empty((0, 0), np.int8)
        ld = np.empty((0, 0), np.int8)
        fs = np.empty((0, 0), np.float32)
        ls = np.empty((0, 0), np.float32)
    return delta, fx, fd, lx, ld, fs, ls


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _row_of(y, nudge_row):
    """The first row at or above y in the edge test: an edge from ya to yb crosses the rows
    from min to max (exclusive) of _row_of(ya) and _row_of(yb), none where the two are equal
    (ya == yb among them). A chain's point is shared by two consecutive edges, so the chains'
    kernels compute it once a point and skip the edges that cross no row."""
    return int(np.ceil(y - 0.5 - nudge_row))


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _rows_crossed(ya, yb, ra, rb, row0, n_rows):
    """(dw, i_start, i_stop): an edge's winding change (+1 going down) and the rows i with
    lo <= i + 0.5 < hi it crosses, relative to row0 and within 0 .. n_rows (stop exclusive;
    none where i_start >= i_stop), from its ends' rows ra = _row_of(ya), rb = _row_of(yb)."""
    if ya < yb:
        dw, i_start, i_stop = 1, ra - row0, rb - row0
    else:
        dw, i_start, i_stop = -1, rb - row0, ra - row0
    return dw, max(i_start, 0), min(i_stop, n_rows)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _edge(acc, xa, ya, xb, yb, is_src, row0, col0, n_rows, n_cols, crossings, nudge_row, nudge_col):
    """One edge's crossings of the rows, into the accumulators."""
    if ya == yb:
        return
    _edge_rows(acc, xa, ya, xb, yb, _row_of(ya, nudge_row), _row_of(yb, nudge_row), is_src, row0, col0, n_rows,
               n_cols, crossings, nudge_row, nudge_col)


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _edge_rows(acc, xa, ya, xb, yb, ra, rb, is_src, row0, col0, n_rows, n_cols, crossings, nudge_row, nudge_col):
    """_edge with the ends' rows ra = _row_of(ya), rb = _row_of(yb) given (ya != yb)."""
    delta, fx, fd, lx, ld, fs, ls = acc
    dw, i_start, i_stop = _rows_crossed(ya, yb, ra, rb, row0, n_rows)
    if i_start >= i_stop:
        return
    slope = (xb - xa) / (yb - ya)
    for i in range(i_start, i_stop):
        yc = i + row0 + 0.5 + nudge_row
        x = xa + (yc - ya) * slope
        k = int(np.floor(x + 0.5 - nudge_col)) - col0
        if k < 0:
            k = 0
        elif k > n_cols:
            k = n_cols
        delta[i, k] += dw
        if crossings:
            # the nearest crossing of any edge; a border edge (no source) records dw = 0,
            # so that a source beyond it is not taken for the sample's neighbour
            sdw = dw if is_src else 0
            if x < fx[i, k]:
                fx[i, k] = x
                fd[i, k] = sdw
                fs[i, k] = slope
            if x > lx[i, k]:
                lx[i, k] = x
                ld[i, k] = sdw
                ls[i, k] = slope


@njit(cache=True, nogil=True, error_model="numpy")
def _finish(acc, n_rows, n_cols):
    delta, fx, fd, lx, ld, fs, ls = acc
    band = np.empty((n_rows, n_cols), np.int16)
    for i in range(n_rows):
        a = 0
        for j in range(n_cols):
            a += delta[i, j]
            band[i, j] = a
    return band, fx, fd, lx, ld, fs, ls


@njit(cache=True, nogil=True, error_model="numpy")
def row_windings(points, first, border, ids, tol, kx, ox, ky, oy, row0, n_rows, step, n_bins):
    """(n_rows, n_bins) int32: per row (row0 + i, as rasterise's) the winding of the crossings
    of the segments' edges (mapped as in rasterise_chains) in gaps K < c * step, for c = 0 ..
    n_bins - 1; i.e. the band rasterise would give at column c * step - 1 (col0 0), less the
    base band. A crop reads it at the bin left of its first column, and rasterises only the
    edges from there on (render/strips.py)."""
    delta = np.zeros((n_rows, n_bins + 1), np.int32)
    for q in range(ids.shape[0]):
        k = ids[q]
        f = first[k]
        n = steps(points, f, border[k], tol, MAX_STEPS)
        xa, ya = points[f, 0] * kx - ox, points[f, 1] * ky - oy
        ra = _row_of(ya, NUDGE_Y)
        for e in range(1, n + 1):
            sx, sy = point(points, f, e, n)
            xb, yb = sx * kx - ox, sy * ky - oy
            rb = _row_of(yb, NUDGE_Y)
            if ra != rb:
                dw, i_start, i_stop = _rows_crossed(ya, yb, ra, rb, row0, n_rows)
                slope = (xb - xa) / (yb - ya)
                for i in range(i_start, i_stop):
                    yc = i + row0 + 0.5 + NUDGE_Y
                    x = xa + (yc - ya) * slope
                    g = int(np.floor(x + 0.5 - NUDGE_X))  # the crossing's gap
                    c = (g + step) // step if g >= 0 else 0  # first bin whose columns it reaches
                    if c < n_bins:
                        delta[i, c] += dw
            xa, ya, ra = xb, yb, rb
    out = np.empty((n_rows, n_bins), np.int32)
    for i in range(n_rows):
        a = 0
        for c in range(n_bins):
            a += delta[i, c]
            out[i, c] = a
    return out
