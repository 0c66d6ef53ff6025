"""What §6's local level splitting could save, estimated before building it (issue 4).

§6: "start by encoding contour 127, then split the intervals" where a test render falls
outside the error bound. Splitting is local at the granularity of loops: an intermediate
level's loop is either coded or not. This script asks, per preset, how many segments of the
intermediate levels could go: it encodes each photograph twice, with the preset's steps
(fine) and with doubled steps (coarse: every other level of the fine set), renders both at
1x, and marks the pixels where the coarse render's channel (Y, U or V) is farther than BOUND
grey levels from the original's (dilated by one pixel). A loop of an intermediate level that
touches no marked pixel is not needed: the coarse render is within the bound all along it.
Its segments are the saving local splitting could make at that bound, before the cost of
coding which loops are kept.

"hybrid" approximates the render of such a split file: the fine render within two pixels of
a marked pixel, the coarse one elsewhere (luma PSNR against the original).

    .venv/bin/python benchmarks/studies/split_potential.py [--images astronaut,coffee] [--out DIR]
"""

from __future__ import annotations

import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))  # benchmarks/: corpus, peers, speed, apply

from corpus import corpus_of, corpus_parser, write_report  # noqa: E402

BOUNDS = (3.0, 5.0)
PRESETS = ("paper", "balanced")


def _psnr(a, b):
    return float(10 * np.log10(255.0**2 / np.mean((a - b) ** 2)))


def _segment_points(ch, samples=16):
    """Every segment of a channel sampled at samples + 1 parameters: (samples + 1, S, 2)."""
    from isophote.geometry import segments

    segs, _ = segments(ch)
    t = np.linspace(0.0, 1.0, samples + 1)[:, None, None]
    s = 1.0 - t
    return s**3 * segs[:, 0] + 3 * s * s * t * segs[:, 1] + 3 * s * t * t * segs[:, 2] + t**3 * segs[:, 3]


def measure(img, preset):
    import isophote
    from scipy import ndimage

    from isophote.colour import rgb_to_yuv
    from isophote.options import PRESETS as P
    from isophote.render import render_float

    fine = isophote.encode(img, preset=preset)
    coarse = isophote.encode(img, preset=preset, y_step=2 * P[preset]["y_step"], uv_step=2 * P[preset]["uv_step"])
    def planes(a):  # Y, U, V (or grey) planes, (H, W, C)
        a = np.asarray(a, np.float64)
        a = a[..., None] if a.ndim == 2 else a
        return a[..., :1] if a.shape[-1] < 3 else rgb_to_yuv(a[..., :3])

    yo, yf, yc = planes(img), planes(render_float(fine)), planes(render_float(coarse))
    h, w = img.shape[:2]
    row = {"fine": sum(c.n_segments for c in fine.channels), "coarse": sum(c.n_segments for c in coarse.channels),
           "y_fine": _psnr(yf[..., 0], yo[..., 0]), "y_coarse": _psnr(yc[..., 0], yo[..., 0])}
    row["inter"] = 0
    for bound in BOUNDS:
        drop = 0
        hybrid = yc[..., 0].copy()
        for i, ch in enumerate(fine.channels):
            bad = ndimage.binary_dilation(np.abs(yc[..., i] - yo[..., i]) > bound)
            coarse_levels = set(np.round(coarse.channels[i].levels, 6))
            inter = np.array([round(v, 6) not in coarse_levels for v in ch.levels], bool)
            nseg = (np.diff(ch.offsets) - 1) // 3
            contour = np.repeat(np.arange(nseg.shape[0]), nseg)
            p = _segment_points(ch)
            xi = np.clip(np.floor(p[..., 0]).astype(np.int64), 0, w - 1)
            yi = np.clip(np.floor(p[..., 1]).astype(np.int64), 0, h - 1)
            touched = np.bincount(contour, weights=bad[yi, xi].any(axis=0), minlength=nseg.shape[0]) > 0
            is_inter = inter[ch.contour_level] if inter.size else np.zeros(nseg.shape[0], bool)
            drop += int(nseg[is_inter & ~touched].sum())
            if bound == BOUNDS[0]:
                row["inter"] += int(nseg[is_inter].sum())
            if i == 0:
                keep = ndimage.binary_dilation(bad, iterations=2)
                hybrid = np.where(keep, yf[..., 0], yc[..., 0])
        row[f"drop_{bound:g}"] = drop
        row[f"y_hybrid_{bound:g}"] = _psnr(hybrid, yo[..., 0])
    return row


def main(argv=None):
    args = corpus_parser(__doc__).parse_args(argv)
    corpus = corpus_of(args)
    lines = ["# Local level splitting (§6): what it could save", "",
             "Segments of the intermediate levels' loops that lie wholly where the coarse render "
             "(doubled steps) is within the bound of the original, in every channel "
             "(`benchmarks/studies/split_potential.py`; its docstring has the method). Luma PSNR dB.", ""]
    head = ("| preset | image | segments fine | coarse | intermediate | "
            + " | ".join(f"droppable at {b:g}" for b in BOUNDS)
            + " | Y fine | Y coarse | " + " | ".join(f"Y hybrid {b:g}" for b in BOUNDS) + " |")
    lines += [head, "|" + "---|" * (head.count("|") - 1)]
    for preset in PRESETS:
        tot = {}
        for name, img in corpus.items():
            r = measure(img, preset)
            for k, v in r.items():
                tot[k] = tot.get(k, 0.0) + v
            lines.append(f"| {preset} | {name} | {r['fine']} | {r['coarse']} | {r['inter']} | "
                         + " | ".join(f"{r[f'drop_{b:g}']} ({r[f'drop_{b:g}'] / r['fine']:.1%})" for b in BOUNDS)
                         + f" | {r['y_fine']:.2f} | {r['y_coarse']:.2f} | "
                         + " | ".join(f"{r[f'y_hybrid_{b:g}']:.2f}" for b in BOUNDS) + " |")
            print(lines[-1], flush=True)
        k = len(corpus)
        lines.append(f"| {preset} | **all** | {tot['fine']:.0f} | {tot['coarse']:.0f} | {tot['inter']:.0f} | "
                     + " | ".join(f"**{tot[f'drop_{b:g}'] / tot['fine']:.1%}**" for b in BOUNDS)
                     + f" | {tot['y_fine'] / k:.2f} | {tot['y_coarse'] / k:.2f} | "
                     + " | ".join(f"{tot[f'y_hybrid_{b:g}'] / k:.2f}" for b in BOUNDS) + " |")
    write_report(args.out, "split_potential.md", lines)
    print("\n".join(lines))


if __name__ == "__main__":
    main()
