"""Chroma node resolution (issue 22): the U and V fields at a fraction of the luma's nodes.

For each photograph (the wide corpus's 1280 x 800 photos and the five corpus photos, encoded
once with the default preset and kept in --cache) and each candidate fraction, the render at
1x (PSNR and SSIMULACRA2 against the original, PSNR of the U and V planes) and the
reductions 1/2, 1/4, 1/8 (PSNR and SSIMULACRA2 against the box reduction of the original),
with the render's processor time; and a zoomed crop (--crop NAME:x,y,w,h, nearest
neighbour 4x) of each candidate's 1x render written to PNG beside the original's, to look
for chroma bleeding at colourful edges.

    python benchmarks/studies/chroma_nodes.py [--wide corpus-wide] [--fractions 1,0.5,0.25]
        [--images A,B] [--cache /tmp/chroma_masters] [--crop ColorfulCups:600,300,160,120]
        [--out-dir /tmp/chroma_crops]

Prints a markdown table per measure (per photo, each candidate's value and its delta to the
first candidate, and the mean).
"""

from __future__ import annotations

import argparse
import os
import resource
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from corpus import load_corpus  # noqa: E402
from peers import downscale  # noqa: E402
from quality_wide import wide_photos  # noqa: E402

import isophote  # noqa: E402
from isophote import metrics  # noqa: E402
from isophote.colour import rgb_to_yuv  # noqa: E402
from isophote.render import levels  # noqa: E402


def cpu() -> float:
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime


def master(name, img, cache):
    p = os.path.join(cache, f"{name}.isoph")
    if not os.path.exists(p):
        os.makedirs(cache, exist_ok=True)
        isophote.encode(img, preset="balanced").save(p)
    return isophote.load(p)


def uv_psnr(ref, out) -> float:
    a, b = rgb_to_yuv(ref.astype(np.float64)), rgb_to_yuv(out.astype(np.float64))
    mse = float(np.mean((a[..., 1:] - b[..., 1:]) ** 2))
    return 10 * np.log10(255.0 ** 2 / mse) if mse > 0 else np.nan


def measure(vi, img, want, reductions=(2, 4, 8), reduction_s2=True):
    """(row, the 1x render): the 1x render's time, PSNR (and of U, V) and, with "s2" in want,
    SSIMULACRA2; with "reduce" in want each reduction's time and PSNR against the box
    reduction of the original, and its SSIMULACRA2 where "s2" is wanted and reduction_s2."""
    row = {}
    t = cpu()
    one = vi.render()
    row["1x s"] = cpu() - t
    row["1x PSNR"] = metrics.psnr(img, one)
    if img.ndim == 3:
        row["1x UV PSNR"] = uv_psnr(img, one)
    if "s2" in want:
        row["1x S2"] = metrics.ssimulacra2(img, one)
    if "reduce" in want:
        for f in reductions:
            ref = downscale(img, f)
            hh, ww = ref.shape[:2]
            t = cpu()
            out = vi.render(crop=(0, 0, ww * f, hh * f), width=ww, height=hh)
            row[f"1/{f} s"] = cpu() - t
            row[f"1/{f} PSNR"] = metrics.psnr(ref, out)
            if "s2" in want and reduction_s2:
                row[f"1/{f} S2"] = metrics.ssimulacra2(ref, out)
    return row, one


def print_tables(rows, photos, candidates, labels) -> None:
    """A markdown table per measure of rows[(photo, candidate)]: per photo each candidate's
    value (headed by its label) and its delta to the first candidate, and the mean."""
    for k in rows[next(iter(rows))]:
        print(f"\n### {k}\n")
        print("| photo | " + " | ".join(labels) + " | " + " | ".join(f"{x} - {labels[0]}" for x in labels[1:]) + " |")
        print("|---" * (2 * len(candidates)) + "|")
        vals = []
        for name in photos:
            if k not in rows[name, candidates[0]]:
                continue
            v = [rows[name, c][k] for c in candidates]
            vals.append(v + [x - v[0] for x in v[1:]])
            print(f"| {name} | " + " | ".join(f"{x:.3f}" for x in vals[-1]) + " |")
        print("| **mean** | " + " | ".join(f"{x:.3f}" for x in np.nanmean(np.array(vals), axis=0)) + " |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wide", default=os.environ.get("ISOPHOTE_WIDE", "corpus-wide"))
    ap.add_argument("--fractions", default="1,0.5,0.25")
    ap.add_argument("--images")
    ap.add_argument("--cache", default="/tmp/chroma_masters")
    ap.add_argument("--want", default="reduce,s2")
    ap.add_argument("--crop", action="append", default=[], help="NAME:x,y,w,h (source pixels) written 4x as PNG")
    ap.add_argument("--out-dir", default="/tmp/chroma_crops")
    ap.add_argument("--blocks", action="store_true",
                    help="every level cut into blocks (as a canvas over blocks.SINGLE_NODES is)")
    a = ap.parse_args(argv)
    if a.blocks:
        from isophote.render import blocks

        blocks.SINGLE_NODES = 0
    photos = wide_photos(a.wide)
    photos.update(load_corpus())
    if a.images:
        photos = {k: v for k, v in photos.items() if k in a.images.split(",")}
    fractions = [float(f) for f in a.fractions.split(",")]
    want = set(a.want.split(","))
    crops = {}
    for c in a.crop:
        n, box = c.split(":")
        crops[n] = tuple(int(v) for v in box.split(","))
    rows = {}
    for name, img in photos.items():
        vi = master(name, img, a.cache)
        vi.render(crop=(0, 0, 32, 32))  # compile / load the kernels
        for f in fractions:
            levels.CHROMA_NODES = f
            rows[name, f], one = measure(vi, img, want)
            print(name, f, {k: round(v, 3) for k, v in rows[name, f].items()}, file=sys.stderr, flush=True)
            if name in crops:
                save_crop(one, crops[name], os.path.join(a.out_dir, f"{name}-{f:g}.png"))
        if name in crops:
            save_crop(img, crops[name], os.path.join(a.out_dir, f"{name}-original.png"))
    print_tables(rows, photos, fractions, [f"{f:g}" for f in fractions])
    return 0


def save_crop(img, box, path):
    from PIL import Image

    x, y, w, h = box
    os.makedirs(os.path.dirname(path), exist_ok=True)
    part = img[y:y + h, x:x + w]
    Image.fromarray(np.ascontiguousarray(part)).resize((4 * w, 4 * h), Image.Resampling.NEAREST).save(path)


if __name__ == "__main__":
    sys.exit(main())
