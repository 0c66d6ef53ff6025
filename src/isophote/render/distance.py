"""Distance fields on the node grid (§4.1-4.2): for every node, the nearest lower and upper
source (isoline or cap) within its band, by the chosen metric (see _kernels/diffuse.py).

Border stretches are rasterised for the bands but are never sources. This module holds the
metrics and a window's fields (NodeField); render/blocks.py computes them, per level window.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._kernels.diffuse import MODE_EUCLIDEAN, MODE_GEODESIC, MODE_MANHATTAN

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
