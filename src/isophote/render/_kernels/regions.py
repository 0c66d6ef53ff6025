"""Kernels of the canvas-wide region pass (render/blocks.py): the cap value of every node
region of a level, the level's labels as runs along its rows (what a blocked level keeps of
them), and the canvas region of each region of a window.

cap_values is the rule region_caps (diffuse.py) uses for the cap values too: the annotation's
nearest node of its band among the 3 x 3 around it names the region; the first annotation
to name a region gives its value.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def cap_values(band, labels, m, cap_x, cap_y, cap_band, cap_value):
    """(m,) float64 cap value of each region of the labelled grid, NaN where none."""
    nr, nc = band.shape
    capv = np.full(m, np.nan)
    for c in range(cap_x.shape[0]):
        ci = int(np.floor(cap_y[c]))
        cj = int(np.floor(cap_x[c]))
        best = np.inf
        bk = -1
        for i in range(ci - 1, ci + 2):
            for j in range(cj - 1, cj + 2):
                if 0 <= i < nr and 0 <= j < nc and band[i, j] == cap_band[c]:
                    dd = (j + 0.5 - cap_x[c]) ** 2 + (i + 0.5 - cap_y[c]) ** 2
                    if dd < best:
                        best = dd
                        bk = labels[i, j]
        if bk >= 0 and np.isnan(capv[bk]):
            capv[bk] = cap_value[c]
    return capv


@njit(cache=True, nogil=True)
def row_runs(labels):
    """The labels (nr, nc) as runs along each row: (row_start (nr + 1,) int64, col (runs,)
    int32, label (runs,) int32); row i's runs are row_start[i] .. row_start[i + 1] - 1, each
    from its col to the next run's (or the row's end) with one label."""
    nr, nc = labels.shape
    n = 0
    for i in range(nr):
        n += 1
        for j in range(1, nc):
            if labels[i, j] != labels[i, j - 1]:
                n += 1
    row_start = np.empty(nr + 1, np.int64)
    col = np.empty(n, np.int32)
    lab = np.empty(n, np.int32)
    k = 0
    for i in range(nr):
        row_start[i] = k
        for j in range(nc):
            if j == 0 or labels[i, j] != labels[i, j - 1]:
                col[k] = j
                lab[k] = labels[i, j]
                k += 1
    row_start[nr] = k
    return row_start, col, lab


@njit(cache=True, nogil=True)
def run_label(row_start, col, lab, i, j):
    """The label of node (i, j) from row_runs: the last run of row i that starts at or before j."""
    lo, hi = row_start[i], row_start[i + 1] - 1
    while lo < hi:  # the last run with col <= j (the row's first starts at 0)
        mid = (lo + hi + 1) // 2
        if col[mid] <= j:
            lo = mid
        else:
            hi = mid - 1
    return lab[lo]


@njit(cache=True, nogil=True)
def local_cap_values_runs(labels, m, i0, j0, row_start, col, lab, gcapv):
    """The value gcapv[g] of each region of a window (labels (nr, nc), m regions), g the canvas
    region of its first node in scan order, read from the canvas labels as runs (row_runs); the
    window's first node is (i0, j0) of the level."""
    out = np.full(m, np.nan)
    seen = np.zeros(m, np.bool_)
    nr, nc = labels.shape
    for i in range(nr):
        for j in range(nc):
            k = labels[i, j]
            if not seen[k]:
                seen[k] = True
                out[k] = gcapv[run_label(row_start, col, lab, i0 + i, j0 + j)]
    return out
