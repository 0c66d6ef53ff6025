"""Fill (§4.2) and reconstruction filter: one strip of output rows of one channel.

Double diffusion: at a sample in band b with distance t1 to the nearest lower source (value
C_lo, the level below or a pit's minimum) and t2 to the nearest upper one (C_up),
C = C_lo * t2 / (t1 + t2) + C_up * t1 / (t1 + t2) (fill "linear"; the default "diffusion"
bends that line into a G1 curve across the isolines, see _kernels/diffuse.py). Flat fill gives every band the middle of
its two levels (Fig. 1b). Above 1x the fill gets the enlargement sharpening (sharpen.py), a
field on the node grid interpolated at each sample. Supersamples are averaged over each output
pixel (a box filter, as in the paper's 4 x 4 supersampling).
"""

from __future__ import annotations

import numpy as np

from ..model import apply_tone_curve
from ._kernels.diffuse import evaluate
from ._kernels.raster import rasterise


class StripEdges:
    """A channel's flattened edges in target-sample units, indexed by the strips of ``rows``
    output rows they reach (built once per channel; each strip then rasterises only its own
    edges, in their original order, instead of scanning all of them)."""

    def __init__(self, nf, vp, rows: int):
        x0, y0, x1, y1, self.src = nf.edges
        self.X0, self.X1 = x0 * vp.kx - vp.offx, x1 * vp.kx - vp.offx
        self.Y0, self.Y1 = y0 * vp.ky - vp.offy, y1 * vp.ky - vp.offy
        lo, hi = np.minimum(self.Y0, self.Y1), np.maximum(self.Y0, self.Y1)
        # strip k covers sample rows [R_k, R_k + S), R_k = row0 + k S, and needs the edges with
        # hi > R_k and lo < R_k + S: k from floor((lo - row0) / S) to ceil((hi - row0) / S) - 1
        self.rows = rows
        S = rows * vp.s
        n_strips = -(-vp.out_h // rows)
        first = np.clip(np.floor((lo - vp.row0) / S), 0, n_strips).astype(np.int64)
        last = np.clip(np.ceil((hi - vp.row0) / S) - 1, -1, n_strips - 1).astype(np.int64)
        count = np.maximum(last - first + 1, 0)
        edge = np.repeat(np.arange(len(lo)), count)
        strip = np.repeat(first - np.cumsum(count) + count, count) + np.arange(len(edge))
        order = np.argsort(strip, kind="stable")
        self.index = edge[order]
        self.starts = np.searchsorted(strip[order], np.arange(n_strips + 1))

    def of(self, out_r0: int) -> np.ndarray:
        """Indices of the edges that reach the strip starting at output row out_r0."""
        k = out_r0 // self.rows
        return self.index[self.starts[k]:self.starts[k + 1]]


def fill_strip(nf, vp, edges: StripEdges, out_r0: int, out_r1: int, flat: bool, tone=None) -> np.ndarray:
    """Output rows [out_r0, out_r1) of one channel: (out_r1 - out_r0, out_w) float32.
    edges: the channel's StripEdges, with a strip starting at out_r0 (out_r1 - out_r0 at most
    its rows). tone: the channel's tone curve knots (model.py), applied per sample, or None."""
    s = vp.s
    n, m = (out_r1 - out_r0) * s, vp.out_w * s
    row0 = vp.row0 + out_r0 * s
    sel = edges.of(out_r0)
    tband, *_ = rasterise(edges.X0[sel], edges.Y0[sel], edges.X1[sel], edges.Y1[sel], edges.src[sel], row0, vp.col0, n, m, False)
    tband += np.int16(nf.base_band)
    xs = (vp.col0 + np.arange(m) + 0.5 + vp.offx) / vp.kx * nf.r
    ys = (row0 + np.arange(n) + 0.5 + vp.offy) / vp.ky * nf.r
    out = np.empty((n, m), np.float32)
    # with the enlargement sharpening (sharpen.py) in nf.nv and nf.corr
    evaluate(nf.F, nf.band, nf.labels, nf.dmax, nf.capv, nf.ramp, tband, xs, ys, nf.levels, nf.mode, flat,
             nf.nv, out, nf.smooth, nf.bw, nf.corr)
    out = apply_tone_curve(out, tone)
    if s > 1:
        out = out.reshape(n // s, s, m // s, s).mean(axis=(1, 3), dtype=np.float64).astype(np.float32)
    return out
