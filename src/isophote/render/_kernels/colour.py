"""YUV planes to quantised RGB(A) in one pass (kernel; the NumPy twin is render._colour then
render.quantise, which the tests hold it to; _fit's twin is colour.fit_gamut).

The render's last step at large sizes: three float32 planes in, one uint8 or uint16 image
out, without the float64 (H, W, 3) intermediates of the NumPy path (at 3840 x 3840 each
is 350 MB; the time saved: benchmarks/results/design_choices.md#fused-colour).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _fit(r, g, b, y):
    """colour.fit_gamut of one colour outside the cube: towards the grey of its luma y."""
    yc = min(max(y, 0.0), 255.0)
    dr, dg, db = r - y, g - y, b - y
    hi, lo = max(dr, dg, db), min(dr, dg, db)
    t = 1.0
    if yc + hi > 255.0:
        t = min(t, (255.0 - yc) / hi)
    if yc + lo < 0.0:
        t = min(t, yc / -lo)
    return yc + t * dr, yc + t * dg, yc + t * db


@njit(cache=True, nogil=True)
def yuv_quantise(y, u, v, alpha, m, mul, fit, out):
    """out[i, j, :3] = rint(clip(m @ (y, u - 128, v - 128), 0, 255) * mul), and out[..., 3] from
    alpha likewise where alpha is not empty; with ``fit`` a colour outside the cube is first
    moved towards the grey of its luma y until it fits (_fit). y, u, v, alpha: (n, w) float32;
    m: the 3 x 3 YUV-to-RGB matrix; mul: 1 for 8 bits, 257 for 16; fit: bool; out: (n, w, 3 or
    4) uint8 or uint16."""
    n, w = y.shape
    has_alpha = alpha.shape[0] == n
    for i in range(n):
        for j in range(w):
            yy = np.float64(y[i, j])
            uu = np.float64(u[i, j]) - 128.0
            vv = np.float64(v[i, j]) - 128.0
            r = m[0, 0] * yy + m[0, 1] * uu + m[0, 2] * vv
            g = m[1, 0] * yy + m[1, 1] * uu + m[1, 2] * vv
            b = m[2, 0] * yy + m[2, 1] * uu + m[2, 2] * vv
            if fit and (min(r, g, b) < 0.0 or max(r, g, b) > 255.0):
                r, g, b = _fit(r, g, b, yy)
            out[i, j, 0] = np.rint(min(max(r, 0.0), 255.0) * mul)
            out[i, j, 1] = np.rint(min(max(g, 0.0), 255.0) * mul)
            out[i, j, 2] = np.rint(min(max(b, 0.0), 255.0) * mul)
            if has_alpha:
                x = min(max(np.float64(alpha[i, j]), 0.0), 255.0)
                out[i, j, 3] = np.rint(x * mul)
