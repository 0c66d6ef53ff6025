"""Fill (§4.2) and reconstruction filter: one strip of output rows of one channel.

Double diffusion: at a sample in band b with distance t1 to the nearest lower source (value
C_lo, the level below or a pit's minimum) and t2 to the nearest upper one (C_up),
C = C_lo * t2 / (t1 + t2) + C_up * t1 / (t1 + t2) (fill "linear"; the default "diffusion"
bends that line into a G1 curve across the isolines, see _kernels/diffuse.py). Flat fill gives every band the middle of
its two levels (Fig. 1b). Supersamples are averaged over each output pixel (a box filter, as
in the paper's 4 x 4 supersampling).
"""

from __future__ import annotations

import numpy as np

from ..model import CAP_RAMP, apply_tone_curve
from .._kernels.diffuse import evaluate
from .._kernels.raster import rasterise


def fill_strip(nf, vp, out_r0: int, out_r1: int, flat: bool, tone=None) -> np.ndarray:
    """Output rows [out_r0, out_r1) of one channel: (out_r1 - out_r0, out_w) float32.
    tone: the channel's tone curve knots (model.py), applied per sample, or None."""
    s = vp.s
    n, m = (out_r1 - out_r0) * s, vp.out_w * s
    row0 = vp.row0 + out_r0 * s
    x0, y0, x1, y1, src = nf.edges
    X0, X1 = x0 * vp.kx - vp.offx, x1 * vp.kx - vp.offx
    Y0, Y1 = y0 * vp.ky - vp.offy, y1 * vp.ky - vp.offy
    # only edges that reach the strip's rows (and everything to their left counts)
    lo, hi = np.minimum(Y0, Y1), np.maximum(Y0, Y1)
    sel = (hi > row0) & (lo < row0 + n)
    tband, *_ = rasterise(X0[sel], Y0[sel], X1[sel], Y1[sel], src[sel], row0, vp.col0, n, m, False)
    tband += np.int16(nf.base_band)
    xs = (vp.col0 + np.arange(m) + 0.5 + vp.offx) / vp.kx * nf.r
    ys = (row0 + np.arange(n) + 0.5 + vp.offy) / vp.ky * nf.r
    out = np.empty((n, m), np.float32)
    evaluate(nf.F, nf.band, nf.labels, nf.dmax, nf.capv, CAP_RAMP * nf.r, tband, xs, ys, nf.levels, nf.mode, flat, nf.nv, out, nf.smooth, nf.bw)
    out = apply_tone_curve(out, tone)
    if s > 1:
        out = out.reshape(n // s, s, m // s, s).mean(axis=(1, 3), dtype=np.float64).astype(np.float32)
    return out
