"""YUV planes to quantised RGB(A) in one pass (kernel; the NumPy twin is render._colour then
render.quantise, which the tests hold it to).

The render's last step at large sizes: three float32 planes in, one uint8 or uint16 image
out, without the float64 (H, W, 3) intermediates of the NumPy path (at 3840 x 3840 each
is 350 MB; the time saved: benchmarks/results/design_choices.md#fused-colour).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def yuv_quantise(y, u, v, alpha, m, mul, out):
    """out[i, j, :3] = rint(clip(m @ (y, u - 128, v - 128), 0, 255) * mul), and out[..., 3] from
    alpha likewise where alpha is not empty. y, u, v, alpha: (n, w) float32; m: the 3 x 3
    YUV-to-RGB matrix; mul: 1 for 8 bits, 257 for 16; out: (n, w, 3 or 4) uint8 or uint16."""
    n, w = y.shape
    has_alpha = alpha.shape[0] == n
    for i in range(n):
        for j in range(w):
            yy = np.float64(y[i, j])
            uu = np.float64(u[i, j]) - 128.0
            vv = np.float64(v[i, j]) - 128.0
            for c in range(3):
                x = m[c, 0] * yy + m[c, 1] * uu + m[c, 2] * vv
                x = min(max(x, 0.0), 255.0)
                out[i, j, c] = np.rint(x * mul)
            if has_alpha:
                x = min(max(np.float64(alpha[i, j]), 0.0), 255.0)
                out[i, j, 3] = np.rint(x * mul)
