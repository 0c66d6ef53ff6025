"""Kernels of the canvas-wide region pass (render/blocks.py): the cap value of every node
region of a level, and the first node of each region of a window.

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
def local_cap_values(labels, m, glabels, gcapv):
    """(m,) cap value of each window region: that of the canvas region of its first node (a
    region connected within the window lies in one canvas region)."""
    out = np.full(m, np.nan)
    seen = np.zeros(m, np.bool_)
    nr, nc = labels.shape
    for i in range(nr):
        for j in range(nc):
            k = labels[i, j]
            if not seen[k]:
                seen[k] = True
                out[k] = gcapv[glabels[i, j]]
    return out
