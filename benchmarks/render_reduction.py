"""Reductions as area averages (issue 26, issue 22): PSNR of renders at 1/2, 1/4, 1/8
against the box reduction of the original, beside the 1x render's own PSNR.

    python benchmarks/render_reduction.py [--images astronaut,camera,coffee]

Encodes each image with the default preset (cached in --cache), renders at 1, 1/2, 1/4 and
1/8, and writes benchmarks/results/render_reduction.md.
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def box(img, k):
    h, w = img.shape[0] // k * k, img.shape[1] // k * k
    x = img[:h, :w].astype(float)
    return x.reshape(h // k, k, w // k, k, *img.shape[2:]).mean(axis=(1, 3))


def main(argv=None) -> int:
    import isophote
    from isophote.metrics import psnr
    from skimage import data

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", default="astronaut,camera,coffee")
    ap.add_argument("--cache", default="/tmp")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "render_reduction.md"))
    args = ap.parse_args(argv)
    lines = ["# Reductions: PSNR (dB) against the box reduction of the original", "",
             "`python benchmarks/render_reduction.py`; default preset.", "",
             "| image | 1x | 1/2 | 1/4 | 1/8 |", "|---|---|---|---|---|"]
    for name in args.images.split(","):
        img = getattr(data, name)()
        path = os.path.join(args.cache, f"render_reduction_{name}.isoph")
        if not os.path.exists(path):
            isophote.encode(img).save(path)
        vi = isophote.load(path)
        row = []
        for k in (1, 2, 4, 8):
            ref = box(img, k)
            out = vi.render(scale=1 / k).astype(float)[: ref.shape[0], : ref.shape[1]]
            row.append(f"{psnr(out, ref):.2f}")
        lines.append(f"| {name} | " + " | ".join(row) + " |")
        print(lines[-1], flush=True)
    with open(args.out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
