"""Plain NumPy twin of prune.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np


def prune(plane, levels, area, contrast) -> np.ndarray:
    """Reference twin: every component labelled over the whole plane (scipy), level by
    level. Returns a new array."""
    from scipy import ndimage

    f = np.array(plane, np.float64, copy=True)
    thr = np.broadcast_to(np.asarray(contrast, np.float64), f.shape)
    if area <= 1 or f.size == 0:
        return f
    for level in np.asarray(levels, np.float64):
        if not (f.min() < level <= f.max()):
            continue  # nothing crosses this level
        for bright in (True, False):
            mask = f >= level if bright else f < level
            lab, n = ndimage.label(mask)  # 4-connected
            if n == 0:
                continue
            flat = lab.ravel()
            count = np.bincount(flat, minlength=n + 1)
            small = count < area
            small[0] = False
            if not small.any():
                continue
            # measure only the samples of small components
            sel = small[flat]
            ls = flat[sel]
            beyond = (f.ravel()[sel] - level) if bright else (level - f.ravel()[sel])
            ext = np.zeros(n + 1)
            order = np.argsort(ls, kind="stable")
            ls_sorted = ls[order]
            starts = np.flatnonzero(np.r_[True, ls_sorted[1:] != ls_sorted[:-1]])
            ext[ls_sorted[starts]] = np.maximum.reduceat(beyond[order], starts)
            mean_thr = np.bincount(ls, thr.ravel()[sel], minlength=n + 1) / np.maximum(count, 1)
            drop = small & (ext < mean_thr)
            if not drop.any():
                continue
            where = drop[lab]
            f[where] = np.nextafter(level, -np.inf) if bright else level
    return f
