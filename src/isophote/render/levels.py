"""Which node grid (level) a render uses, and what it costs in memory before it starts.

The level depends on the canvas and the output scale only, never on the crop, so that every
crop of a render at one scale reads the same fields (blocks.py).

Reductions (output scale z < 1) build their nodes at the output's resolution, not the
source's: r = the smallest power of two >= z nodes a source pixel (so 1x and 1/2 .. 1/2^k
exactly), and their samples are 2 x 2 a pixel, box filtered, at least as dense as the nodes:
an output pixel is an area average, not a point sample of the fill. At and above 1x the
level is node_resolution's (render/__init__.py), as before.
"""

from __future__ import annotations

import math

REDUCTION_SUPERSAMPLE = 2


def reduction_r(z: float) -> float:
    """Nodes per source pixel below 1x: the smallest power of two at least z."""
    return 2.0 ** math.ceil(math.log2(z) - 1e-9)


def auto_supersample(requested: int, z: float) -> int:
    """Samples a side per output pixel: REDUCTION_SUPERSAMPLE below 1x unless more were asked."""
    return max(int(requested), REDUCTION_SUPERSAMPLE) if z < 1.0 - 1e-9 else int(requested)
