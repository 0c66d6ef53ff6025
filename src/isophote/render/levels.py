"""Which node grid (level) a render uses, and what it costs in memory before it starts.

The level depends on the canvas and the output scale only, never on the crop, so that every
crop of a render at one scale reads the same fields (blocks.py).

Reductions (output scale z < 1) are area averages of the fill, as the box reduction of the
1x render is. With p the smallest power of two >= z: above 1/2 the nodes are the source's
(r = 1); at 1/2 and below half a source pixel apart (r = REDUCTION_FINEST), but at most
REDUCTION_NODES times p (r = 4p from 1/8 down): 1, 2 and 4 a side per output pixel at 1/2,
1/4 and 1/8, and 4 at every smaller power of two. The samples are s x s a pixel, box
filtered, s the smallest power of two >= 1/z between 2 and REDUCTION_SAMPLES: 2 at 1/2, 4
at 1/4 and below (one a source pixel at 1/4, one every 2 at 1/8). Both are bounded per
output pixel, so a reduction costs what its output does. Nodes at the output's resolution
with 2 x 2 samples (the rule before, still the one at 1/2) point-sample the contours at 1/4
and 1/8: on the wide corpus and the five corpus photos 1/8 rendered 0.5-18.5 dB under the
box reduction of the 1x render, this rule -0.4-3.9 dB (benchmarks/results/
reduction_sampling.md, with the candidates measured). At 1/2 the 1x grid would be 0.7 dB
closer to that bound (up to 1.8) for about twice the time, but at 1/2 of the encoder's
largest canvas its kept blocks leave the default memory budget (limits_render.py). At and
above 1x the level is node_resolution's (render/__init__.py).
"""

from __future__ import annotations

import math

REDUCTION_NODES = 4  # most nodes a side per output pixel at powers of two 1/2 and below
REDUCTION_FINEST = 0.5  # nodes a source pixel at 1/2 and below, at most (see the module docstring)
REDUCTION_SAMPLES = 4  # most samples a side per output pixel below 1x
CHROMA_NODES = 1.0  # chroma nodes a side per luma node at and below 1x; 1/2 and 1/4 lose (results/chroma_nodes.md)


def _pow2_at_least(x: float) -> float:
    return 2.0 ** math.ceil(math.log2(x) - 1e-9)


def reduction_r(z: float) -> float:
    """Nodes per source pixel below 1x: above 1/2, 1; at 1/2 and below REDUCTION_FINEST, at
    most REDUCTION_NODES times the smallest power of two p >= z (REDUCTION_NODES a side per
    output pixel)."""
    p = _pow2_at_least(z)
    return p if p >= 1.0 else min(REDUCTION_FINEST, REDUCTION_NODES * p)


def level_r(z: float, chroma: bool = False) -> tuple[float, float]:
    """(nodes per source pixel, fraction of the luma's nodes a side) at and below 1x:
    reduction_r's for the luma, CHROMA_NODES of it for the chroma."""
    f = CHROMA_NODES if chroma else 1.0
    return reduction_r(z) * f, f


def auto_supersample(requested: int, z: float) -> int:
    """Samples a side per output pixel: below 1x the smallest power of two >= 1/z, between 2
    and REDUCTION_SAMPLES, unless more were asked; at and above 1x as asked."""
    if z >= 1.0 - 1e-9:
        return int(requested)
    return max(int(requested), int(min(REDUCTION_SAMPLES, max(2.0, _pow2_at_least(1.0 / z)))))
