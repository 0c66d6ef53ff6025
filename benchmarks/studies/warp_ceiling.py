"""How well could a vector warp do at best? The encoder's interpolant alone (issue 5).

A vector warp renders the contours traced on the encoder's 2x grid (encoder/mapping.py:
the pixels, Carrato midpoints between them, marching squares linear within each half-pixel
cell). However faithfully the contours follow that grid, the warped render can be no better
than the grid itself read at the warped positions. This script takes the contours out:
it samples the grid bilinearly (its own interpolant) at the warp's inverse positions and
scores it as benchmarks/apply.py scores the warps (same input, reference, mask and warps),
beside scikit-image's bicubic and order-5 spline warps of the input and two finer grids:
a cubic spline's values on the 2x grid and on a 4x grid, each read bilinearly.

    .venv/bin/python benchmarks/studies/warp_ceiling.py [--images astronaut,coffee] [--out DIR]
"""

from __future__ import annotations

import os
import sys

import numpy as np
from scipy import ndimage

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))  # benchmarks/: corpus, peers, speed, apply

from apply import psnr_masked, raster_warp, warp_cases, warp_reference  # noqa: E402
from corpus import corpus_of, corpus_parser, write_report  # noqa: E402
from peers import downscale  # noqa: E402

from isophote.encoder.mapping import map_pixels  # noqa: E402

WARPS = ("rotate 15", "perspective", "swirl")


def spline_grid(v, factor):
    """A cubic spline's values on the grid of `factor` samples a pixel (grid sample k at
    k / factor, in pixel-corner coordinates, as the encoder's grid for factor 2)."""
    h, w = v.shape
    rr = np.arange(factor * h + 1) / factor - 0.5
    cc = np.arange(factor * w + 1) / factor - 0.5
    return ndimage.map_coordinates(v, np.meshgrid(rr, cc, indexing="ij"), order=3, mode="mirror")


def read_grid(grids, factor, inv, h, w):
    """The grids read bilinearly at the inverse map of each output pixel centre."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    p = inv(np.stack([xx.ravel() + 0.5, yy.ravel() + 0.5], axis=1))
    out = [ndimage.map_coordinates(g, [p[:, 1] * factor, p[:, 0] * factor], order=1, mode="nearest").reshape(h, w)
           for g in grids]
    return out[0] if len(out) == 1 else np.stack(out, axis=-1)


def measure(img):
    lo = downscale(img, 2).astype(np.float64)
    h, w = lo.shape[:2]
    hi = img[: 2 * h, : 2 * w].astype(np.float64)
    chans = [lo] if lo.ndim == 2 else [lo[..., k] for k in range(lo.shape[2])]
    models = {
        "encoder grid": ([map_pixels(c, 0.0)[0] for c in chans], 2),
        "spline on 2x grid": ([spline_grid(c, 2) for c in chans], 2),
        "spline on 4x grid": ([spline_grid(c, 4) for c in chans], 4),
    }
    rows = {}
    for case, (_, inv, _, inv2) in warp_cases(w, h).items():
        ref, mask = warp_reference(hi, inv, inv2)
        r = {"bicubic": psnr_masked(ref, raster_warp(lo, inv, 3), mask),
             "spline order 5": psnr_masked(ref, raster_warp(lo, inv, 5), mask)}
        for name, (grids, factor) in models.items():
            r[name] = psnr_masked(ref, read_grid(grids, factor, inv, h, w), mask)
        rows[case] = r
    return rows


def main(argv=None):
    args = corpus_parser(__doc__).parse_args(argv)
    corpus = corpus_of(args)
    results = {name: measure(img) for name, img in corpus.items()}
    cols = list(next(iter(next(iter(results.values())).values())))
    lines = ["# Warps: the encoder's interpolant alone (issue 5)", "",
             "PSNR dB against the warp of the full-resolution photograph, as in apply.md "
             "(`benchmarks/studies/warp_ceiling.py`; its docstring has the method). The first two columns "
             "warp the input raster with scikit-image; the others read a grid bilinearly, "
             "\"encoder grid\" being the one the contours are traced on.", "",
             "| image | warp | " + " | ".join(cols) + " |", "|---|---|" + "---|" * len(cols)]
    for name, rows in results.items():
        for case, r in rows.items():
            lines.append(f"| {name} | {case} | " + " | ".join(f"{r[c]:.2f}" for c in cols) + " |")
    for case in WARPS:
        lines.append(f"| **mean** | {case} | " + " | ".join(
            f"**{np.mean([results[n][case][c] for n in results]):.2f}**" for c in cols) + " |")
    path = write_report(args.out, "warp_ceiling.md", lines)
    print("\n".join(lines[-3:]))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
