"""Kernel of the noise estimate's window medians (encoder/noise.py, local_noise); its plain
NumPy twin is median_ref.py. Both give the same bits (tests compare them).

The twin gathers every window (16 x 16 samples on an 8-sample lattice: each sample four
times) and takes NumPy's median along them, 32 bytes a pixel of copies and as much again
for the partition: 1 GB for a 16 MP plane. The kernel selects each window's middle
samples in one buffer of its own. The median of an even count is the mean of its two
middle samples, (a + b) / 2, as NumPy computes it, so the bits are NumPy's.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _select(buf, n, k):
    """Put the k-th smallest of buf[:n] at buf[k], the smaller ones before it and the
    larger after (Hoare's selection, the middle of three as pivot)."""
    lo, hi = 0, n - 1
    while hi > lo:
        mid = (lo + hi) // 2
        a, b, c = buf[lo], buf[mid], buf[hi]
        if a > b:
            a, b = b, a
        if b > c:
            b = c
            if a > b:
                b = a
        pivot = b
        i, j = lo, hi
        while i <= j:
            while buf[i] < pivot:
                i += 1
            while buf[j] > pivot:
                j -= 1
            if i <= j:
                t = buf[i]
                buf[i] = buf[j]
                buf[j] = t
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return


@njit(cache=True, nogil=True)
def window_medians(rp, rows, cols, win):
    """(len(rows), len(cols)) medians of the win x win windows of rp whose top left corners
    are (rows[i], cols[j])."""
    ny, nx = rows.shape[0], cols.shape[0]
    out = np.empty((ny, nx))
    n = win * win
    buf = np.empty(n)
    k = n // 2
    for i in range(ny):
        r0 = rows[i]
        for j in range(nx):
            c0 = cols[j]
            q = 0
            for r in range(r0, r0 + win):
                for c in range(c0, c0 + win):
                    buf[q] = rp[r, c]
                    q += 1
            _select(buf, n, k)
            hi = buf[k]
            if n % 2 == 1:
                out[i, j] = hi
            else:
                lo = buf[0]
                for q in range(1, k):
                    if buf[q] > lo:
                        lo = buf[q]
                out[i, j] = (lo + hi) / 2.0
    return out
