"""Plain NumPy twins of diffuse.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np

from .diffuse import D, MODE_MANHATTAN, SX, SY, V


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
