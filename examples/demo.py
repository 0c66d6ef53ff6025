"""isophote in one page: encode a photograph, render it back, draw its contours, measure.

    python examples/demo.py examples/data/chelsea.png out/demo        (or: make demo)

Writes into OUTDIR:
    <name>.isoph         the vectorised photograph
    render.png           rendered back at the original size, double-diffusion fill
    render_2x.png        rendered at twice the size: the same contours, no resampling
    contours.png         the Y contours over the Y plane around the left eye, 6x (paper Fig. 2):
                         red joint-to-joint polylines, green fitted Bezier chains
    side_by_side.png     original | render (diffusion) | flat fill (paper Fig. 1b)
and prints the size of the file and PSNR / SSIMULACRA2 of both fills against the original.

The sample photograph, chelsea.png, is from scikit-image (CC0, by Stefan van der Walt).
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np

import isophote
from isophote import metrics
from isophote.imageio import read_image, write_image
from isophote.overlay import draw_contours

CONTOUR_CROP = (120, 70, 110, 80)  # x, y, w, h in source pixels: chelsea's left eye
CONTOUR_SCALE = 6
GAP = 6  # white pixels between the panels of the side-by-side


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    src, outdir = argv
    os.makedirs(outdir, exist_ok=True)
    name = os.path.splitext(os.path.basename(src))[0]

    raster = read_image(src)  # (H, W, C) float on 0..255 and its bit depth
    original = _as_integers(raster.pixels, raster.depth)
    h, w = original.shape[:2]

    t = time.perf_counter()
    vi = isophote.encode(original)  # the public API: an array in, a VectorImage out
    t_encode = time.perf_counter() - t
    isoph = os.path.join(outdir, f"{name}.isoph")
    vi.save(isoph)

    t = time.perf_counter()
    render = vi.render()  # same size as the original, uint8
    t_render = time.perf_counter() - t
    flat = vi.render(fill="flat")
    render_2x = vi.render(scale=2)
    write_image(os.path.join(outdir, "render.png"), render)
    write_image(os.path.join(outdir, "render_2x.png"), render_2x)

    crop = CONTOUR_CROP if _fits(CONTOUR_CROP, w, h) else None
    figure = draw_contours(isophote.load(isoph), "Y", scale=CONTOUR_SCALE if crop else 2, crop=crop)
    write_image(os.path.join(outdir, "contours.png"), figure)
    write_image(os.path.join(outdir, "side_by_side.png"), side_by_side([original, render, flat]))

    size = os.path.getsize(isoph)
    segments = sum(ch.n_segments for ch in vi.channels)
    print(f"{src}: {w}x{h}, encoded in {t_encode:.1f} s, rendered in {t_render:.1f} s")
    print(f"{isoph}: {size:,} bytes ({os.path.getsize(src):,} for the input), "
          f"{segments:,} Bezier segments in {', '.join(ch.name for ch in vi.channels)}")
    for label, img in (("diffusion", render), ("flat", flat)):
        scores = []
        for metric in ("psnr", "ssimulacra2"):
            try:
                scores.append(f"{metric} {metrics.METRICS[metric](original, img):.2f}")
            except isophote.OptionError as e:  # the optional metric package is missing
                scores.append(f"{metric} n/a ({e})")
        print(f"  {label:<10} " + "  ".join(scores))
    print(f"outputs in {outdir}/: {name}.isoph render.png render_2x.png contours.png side_by_side.png")
    return 0


def _as_integers(pixels: np.ndarray, depth: int) -> np.ndarray:
    """The raster as the integers it was stored as, so that encode() knows the bit depth."""
    if depth == 16:
        return np.rint(pixels * 257.0).astype(np.uint16)
    return np.rint(pixels).astype(np.uint8)


def _fits(crop, w, h) -> bool:
    x, y, cw, ch = crop
    return x + cw <= w and y + ch <= h


def side_by_side(images, gap: int = GAP) -> np.ndarray:
    """Panels left to right on white, as (H, W, C) float on 0..255 (grey or colour panels)."""
    panels = []
    for img in images:
        a = np.asarray(img)
        a = a / 257.0 if a.dtype == np.uint16 else a.astype(np.float64)
        panels.append(a if a.ndim == 3 else a[..., None])
    c = max(p.shape[2] for p in panels)
    h = max(p.shape[0] for p in panels)
    w = sum(p.shape[1] for p in panels) + gap * (len(panels) - 1)
    out = np.full((h, w, c), 255.0)
    x = 0
    for p in panels:
        if p.shape[2] != c:
            p = np.repeat(p, c, axis=2)
        out[: p.shape[0], x : x + p.shape[1]] = p
        x += p.shape[1] + gap
    return out


if __name__ == "__main__":
    raise SystemExit(main())
