"""Enlargement sharpening: the reconstruction filter for renders above the source size.

A photograph's pixel is the average of the light over its area (a box), but the vector
image interpolates the pixel values as if they were samples at the pixel centres: the
smooth surface it renders is the scene already blurred by the source pixel's box. At 1x
that is exactly right (each output pixel is one source pixel's box). An output pixel 1/s
the size of a source pixel should average the scene over a box s times smaller, i.e. it
should be sharper than the interpolated surface by the difference of the two boxes. To
second order a box of width h blurs by h^2/24 times the Laplacian, so the output is

    out = f - K (1 - 1/s^2) h^2 Lap f        (per axis, with that axis's scale s)

where f is the rendered surface; K = 1/24 for a surface that is the exact interpolant.
Ours is smoother than the ideal interpolant between the samples, so the best K measured
is larger (below). Nothing changes at or below 1x: s <= 1 gives no correction.

The correction is computed (_kernels/sharpen.py) on the distance-node grid (r nodes a
source pixel; the nodes' fill values are the surface there) with the second differences one
source pixel (r nodes) apart, and interpolated bilinearly to the target samples. It is a field over the whole
canvas, like the distances, so crops and tiles of a render stay exactly the corresponding
part of the full render. Where a neighbour one pixel away lies off the canvas, that
axis's second difference is 0 (linear extrapolation: a ramp stays a ramp to the border).

Measured on the corpus enlargements of benchmarks/apply.py against no correction, the same
correction applied per pixel, and Pillow's bicubic and Lanczos: on the node grid it does as
well as per pixel and beats Lanczos at 2x, 4x and 8x; K = 0.1 favours PSNR, 0.15
SSIMULACRA2, and the default K, 0.125 (RenderOptions.sharpen), lies between the two
(measured: benchmarks/results/design_choices.md#sharpen-k).

Like any sharpening it rings at hard edges, less than Pillow's Lanczos does. Clamping the
corrected nodes to their neighbourhood's range (no ringing at all) costs SSIMULACRA2 at 2x
and 4x on the corpus, so it is not done (measured:
benchmarks/results/design_choices.md#sharpen-no-clamp).
"""

from __future__ import annotations


def gains(k: float, sx: float, sy: float) -> tuple[float, float]:
    """The per-axis weights K (1 - 1/s^2) of the second differences, for output scales sx and
    sy (output pixels per source pixel); 0 at or below 1x."""
    gx = k * (1.0 - 1.0 / (sx * sx)) if sx > 1.0 else 0.0
    gy = k * (1.0 - 1.0 / (sy * sy)) if sy > 1.0 else 0.0
    return gx, gy
