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

Measured (benchmarks/apply.py protocol: corpus box-downsampled, encoded with high, rendered
back, mean PSNR dB / SSIMULACRA2 against the original), the same correction applied to the
render by a per-pixel Laplacian, and on the node grid with r = 3 and 2:
    4x: none 27.05 / 23.4; per pixel K = 0.1 27.35 / 35.3; nodes r = 3 K = 0.1 27.36 / 34.8,
        K = 0.15 27.30 / 35.9; r = 2 K = 0.1 27.34 / 33.6, K = 0.15 27.31 / 34.9
        (Pillow's bicubic 26.99 / 28.8, Lanczos 27.15 / 32.3).
    2x: none 30.67 / 56.6; K = 0.1 31.08 / 62.3; K = 0.15 31.03 / 63.3 (Lanczos 30.96 / 63.0).
    8x: none 24.36 / -36.6; K = 0.1 24.64 / -28.9; K = 0.15 24.60 / -28.3 (Lanczos 24.41 / -32.7).
The default K, 0.125 (RenderOptions.sharpen), lies between the two: 4x 27.35 / 35.7, 2x
31.07 / 62.9 (balanced: 4x 27.23 / 29.5, 2x 30.80 / 58.6).

Like any sharpening it rings at hard edges: a disc of 200 on 50 rendered at 4x reaches 27 and
228 (at 8x 23 and 232), where Pillow's Lanczos reaches 18 and 232 and its bicubic 30 and 220;
across a straight step of 50 to 150, 46 and 155 (Lanczos 38 and 162). Clamping the corrected
nodes to their neighbourhood's range (no ringing at all) cost 2-3 points of SSIMULACRA2 at 2x
and 4x on the corpus (high, 4x: 33.0 against 35.7), so it is not done.
"""

from __future__ import annotations


def gains(k: float, sx: float, sy: float) -> tuple[float, float]:
    """The per-axis weights K (1 - 1/s^2) of the second differences, for output scales sx and
    sy (output pixels per source pixel); 0 at or below 1x."""
    gx = k * (1.0 - 1.0 / (sx * sx)) if sx > 1.0 else 0.0
    gy = k * (1.0 - 1.0 / (sy * sy)) if sy > 1.0 else 0.0
    return gx, gy
