"""Plain NumPy twin of raster.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np

from .raster import NUDGE_X, NUDGE_Y


def rasterise(x0, y0, x1, y1, row0, col0, n_rows, n_cols, transposed=False):
    """NumPy twin of the band output: per row, all crossings at once."""
    nudge_row, nudge_col = (NUDGE_X, NUDGE_Y) if transposed else (NUDGE_Y, NUDGE_X)
    band = np.zeros((n_rows, n_cols), np.int64)
    for i in range(n_rows):
        yc = row0 + i + 0.5 + nudge_row
        lo, hi = np.minimum(y0, y1), np.maximum(y0, y1)
        sel = (lo <= yc) & (yc < hi) & (y0 != y1)
        if not sel.any():
            continue
        x = x0[sel] + (yc - y0[sel]) * (x1[sel] - x0[sel]) / (y1[sel] - y0[sel])
        dw = np.where(y1[sel] > y0[sel], 1, -1)
        k = np.clip(np.floor(x + 0.5 - nudge_col) - col0, 0, n_cols).astype(np.int64)
        band[i] = ((k[None, :] <= np.arange(n_cols)[:, None]) * dw[None, :]).sum(axis=1)
    return band.astype(np.int16)


def rasterise_chains(points, first, border, ids, tol, kx, ox, ky, oy, swap, row0, col0, n_rows, n_cols,
                     transposed=False):
    """NumPy twin of the band output of raster.rasterise_chains: the segments flattened by
    geometry's NumPy twin, mapped, then rasterised."""
    from ...geometry.flatten_ref import flatten

    segs = points[first[ids][:, None] + np.arange(4)]
    x0, y0, x1, y1, _ = flatten(segs, border[ids], tol)
    x0, x1, y0, y1 = x0 * kx - ox, x1 * kx - ox, y0 * ky - oy, y1 * ky - oy
    if swap:
        x0, y0, x1, y1 = y0, x0, y1, x1
    return rasterise(x0, y0, x1, y1, row0, col0, n_rows, n_cols, transposed)


def row_windings(points, first, border, ids, tol, kx, ox, ky, oy, row0, n_rows, step, n_bins):
    """NumPy twin of raster.row_windings: the band of the whole rows (one column left of the
    first) read at columns c * step - 1."""
    band = rasterise_chains(points, first, border, ids, tol, kx, ox, ky, oy, False, row0, -1, n_rows,
                            (n_bins - 1) * step + 1)
    return band[:, np.arange(n_bins) * step].astype(np.int32)
