"""Distance fields on the node grid (§4.1-4.2): for every node, the nearest lower and upper
source (isoline or cap) within its band, by the chosen metric (see _kernels/diffuse.py).

Border stretches are rasterised for the bands but are never sources.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._kernels.diffuse import (
    MODE_EUCLIDEAN, MODE_GEODESIC, MODE_MANHATTAN, band_widths, evaluate, label_nodes, offsets, propagate,
    region_caps, seed,
)
from ._kernels.raster import rasterise
from ._kernels.sharpen import correction

MODES = {"euclidean": MODE_EUCLIDEAN, "manhattan": MODE_MANHATTAN, "geodesic": MODE_GEODESIC}
# one forward+backward pair: more barely change the corpus renders
# (measured: benchmarks/results/design_choices.md#distance-sweeps)
MAX_SWEEPS = 1


@dataclass
class NodeField:
    F: np.ndarray  # (2, 4, nr, nc) fields, see _kernels/diffuse.py
    band: np.ndarray  # (nr, nc) int16
    levels: np.ndarray
    r: int  # nodes per source pixel
    mode: int
    edges: tuple  # (x0, y0, x1, y1, is_source) in source pixels
    base_band: int
    labels: np.ndarray  # (nr, nc) int32 node regions
    dmax: np.ndarray  # (R, 2) largest distance of each side per region
    capv: np.ndarray  # (R,) cap value per region, NaN where none
    nv: np.ndarray  # (nr, nc) float32 fill value at each node, plus corr where sharpened
    smooth: bool  # G1 profiles across isolines (fill "diffusion") or straight lines ("linear")
    bw: np.ndarray  # (nr, nc, 2) float32 band width and step per node (band_widths), for G1
    ramp: float  # the caps' longest ramp in node units (Channel.cap_ramp * r)
    corr: np.ndarray  # (nr, nc) float32 enlargement sharpening at the nodes (sharpen.py), or (0, 0)


def node_field(vi, ch, edges, r: int, distance: str, smooth: bool = True, sharpen=(0.0, 0.0)) -> NodeField:
    """The distance fields of one channel on its node grid; ``sharpen``: the per-axis gains
    of the enlargement sharpening (sharpen.gains), (0, 0) for none."""
    x0, y0, x1, y1, src = edges
    nr, nc = vi.height * r, vi.width * r
    band, *h = rasterise(x0 * r, y0 * r, x1 * r, y1 * r, src, 0, 0, nr, nc, True)
    band += np.int16(ch.base_band)
    # columns: the same kernel on the transposed geometry
    _, *v = rasterise(y0 * r, x0 * r, y1 * r, x1 * r, src, 0, 0, nc, nr, True, True)
    mode = MODES[distance]
    F = seed(band, tuple(h), tuple(v), ch.levels, mode)
    propagate(F, band, offsets(mode), mode, MAX_SWEEPS)
    labels, m = label_nodes(band)
    dmax, capv = region_caps(
        F, band, labels, m, ch.cap_xy[:, 0] * r, ch.cap_xy[:, 1] * r, ch.cap_band.astype(np.int64), ch.cap_value
    )
    # the fill at the nodes: samples surrounded by nodes of their own band interpolate it
    nr, nc = band.shape
    nv = np.empty((nr, nc), np.float32)
    ramp = float(ch.cap_ramp) * r  # inf (domes) stays inf
    bw = band_widths(F, band, labels, dmax, capv, ramp) if smooth else np.zeros((0, 0, 2), np.float32)
    evaluate(
        F, band, labels, dmax, capv, ramp, band, np.arange(nc) + 0.5, np.arange(nr) + 0.5,
        ch.levels, mode, False, np.empty((0, 0), np.float32), nv, smooth, bw, np.empty((0, 0), np.float32),
    )
    if max(sharpen) > 0.0:
        corr, nv = correction(nv, r, float(sharpen[0]), float(sharpen[1]))
    else:
        corr = np.zeros((0, 0), np.float32)
    return NodeField(F, band, ch.levels, r, mode, edges, ch.base_band, labels, dmax, capv, nv, smooth, bw, ramp, corr)
