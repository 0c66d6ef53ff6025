"""Kernel of the pruning of small, low-contrast level crossings (encoder/prune.py); its
plain NumPy twin is prune_ref.py.

Used by :mod:`isophote.encoder.prune`, which documents and validates; nothing here checks its
arguments. Both give the same bits (tests compare them).

The twin labels every component of {f >= L} (and of {f < L}) over the whole plane, level
after level. The kernel visits only what can change: a component is flattened only if
every sample lies less than the largest contrast threshold beyond the level, so it grows
4-connected components from the samples that lie that close, and gives one up (it stays)
as soon as it reaches ``area`` samples, a sample farther beyond, or a sample of a
component given up before in the same pass. Each sample is visited at most once per pass,
so a level costs its near samples, not the plane. A component that stays whole is judged
as the twin judges it: its largest excursion beyond the level against the mean of its
samples' thresholds, summed in the twin's order (flat index).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _beyond(v, level, bright):
    """How far v lies beyond the level on the pass's side (bright: v >= level, else
    v < level), or -1 when it is not on that side."""
    if bright:
        return v - level if v >= level else -1.0
    return level - v if v < level else -1.0


@njit(cache=True, nogil=True)
def _pass(f, thr, level, area, bright, limit, seen, first_id, next_id, stack, comp, drop):
    """One pass (bright: components of {f >= level}, else of {f < level}) over the flat
    plane f; returns (next free component id, dropped samples in drop[:k], k)."""
    h, w = f.shape
    ff = f.ravel()
    tt = thr.ravel()
    n = h * w
    nd = 0
    for p in range(n):
        beyond = _beyond(ff[p], level, bright)
        if beyond < 0.0 or beyond > limit or seen[p] >= first_id:
            continue
        cid = next_id
        next_id += 1
        seen[p] = cid
        stack[0] = p
        top = 1
        size = 0
        ok = True
        while top > 0 and ok:
            top -= 1
            a = stack[top]
            comp[size] = a
            size += 1
            if size >= area:
                ok = False
                break
            r = a // w
            c = a - r * w
            for k in range(4):
                if k == 0:
                    if r == 0:
                        continue
                    b = a - w
                elif k == 1:
                    if r == h - 1:
                        continue
                    b = a + w
                elif k == 2:
                    if c == 0:
                        continue
                    b = a - 1
                else:
                    if c == w - 1:
                        continue
                    b = a + 1
                bb = _beyond(ff[b], level, bright)
                if bb < 0.0 or seen[b] == cid:
                    continue
                if bb > limit or seen[b] >= first_id:
                    ok = False  # farther beyond, or part of a component given up
                    break
                seen[b] = cid
                stack[top] = b
                top += 1
        if not ok:
            continue
        # the whole component, fewer than area samples: in flat order, as the twin sums
        for i in range(1, size):
            x = comp[i]
            j = i - 1
            while j >= 0 and comp[j] > x:
                comp[j + 1] = comp[j]
                j -= 1
            comp[j + 1] = x
        ext = -np.inf
        tsum = 0.0
        for i in range(size):
            q = comp[i]
            e = _beyond(ff[q], level, bright)
            if e > ext:
                ext = e
            tsum += tt[q]
        if ext < tsum / size:
            for i in range(size):
                drop[nd] = comp[i]
                nd += 1
    return next_id, nd


@njit(cache=True, nogil=True)
def prune_kernel(f, thr, levels, area):
    """Flatten the small, low-contrast crossings of every level of f (H, W) in place; thr
    (H, W) the contrast thresholds, area > 1."""
    n = f.size
    ff = f.ravel()
    tmax = max(0.0, thr.max())
    # beyond this no component can be flattened (the mean of thresholds up to tmax stays
    # below it, rounding included)
    limit = tmax * (1.0 + 1e-9)
    seen = np.full(n, -1, np.int64)
    stack = np.empty(4 * area + 4, np.int64)  # each of < area samples pushes <= 4
    comp = np.empty(area, np.int64)
    drop = np.empty(n, np.int32)  # sample indices: MAX_PIXELS < 2**31 (4 bytes a sample less)
    next_id = 0
    for li in range(levels.shape[0]):
        level = levels[li]
        if not (ff.min() < level <= ff.max()):
            continue
        for bright in (True, False):
            first_id = next_id
            next_id, nd = _pass(f, thr, level, area, bright, limit, seen, first_id, next_id,
                                stack, comp, drop)
            value = np.nextafter(level, -np.inf) if bright else level
            for i in range(nd):
                ff[drop[i]] = value
