"""The smooth-region criterion's floor (issue 26): what a render with no terraces scores.

banding.py passes a render when its band-pass error A in the smooth regions, after a 2x
contrast curve, is within the original's own grain level N in Y and in U, V. This scores,
on each wide-corpus photograph, the original itself blurred by a Gaussian of 1.5 px (no
terraces, no blotches, nothing added: only its finest grain smoothed, as any render from
contours smooths it) beside the default preset's render and the paper preset's (the
storm-sky case the measure flags).

    python benchmarks/studies/smooth_floor.py [--wide corpus-wide] [--cache /tmp/smooth_floor]

Prints one markdown table.
"""

from __future__ import annotations

import argparse
import glob
import os

import numpy as np

import isophote
from isophote.banding import smooth_artefacts


def main(argv=None) -> int:
    from PIL import Image
    from scipy import ndimage

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wide", default="corpus-wide")
    ap.add_argument("--cache", default="/tmp/smooth_floor")
    args = ap.parse_args(argv)
    os.makedirs(args.cache, exist_ok=True)

    def render(name, img, preset):
        path = os.path.join(args.cache, f"{name}-{preset}.npy")
        if not os.path.exists(path):
            np.save(path, np.asarray(isophote.encode(img, preset=preset).render())[..., :3])
        return np.load(path)

    cols = ("original blurred 1.5 px", "balanced", "paper")
    print("| photo | own Y | own UV | " + " | ".join(f"{c}: A Y | A UV | ok" for c in cols) + " |")
    print("|---|---|---|" + "---|---|---|" * len(cols))
    for p in sorted(glob.glob(os.path.join(args.wide, "photo", "*.png"))):
        name = os.path.splitext(os.path.basename(p))[0]
        with Image.open(p) as im:
            img = np.asarray(im.convert("RGB"))
        blur = np.clip(np.round(ndimage.gaussian_filter(img.astype(np.float64), (1.5, 1.5, 0))), 0, 255)
        rs = [smooth_artefacts(img, t) for t in (blur.astype(np.uint8), render(name, img, "balanced"),
                                                 render(name, img, "paper"))]
        if np.isnan(rs[0]["y"]):
            print(f"| {name} | - | - | " + " | ".join("- | - | (no smooth region)" for _ in rs) + " |")
            continue
        print(f"| {name} | {rs[0]['y_own']:.3f} | {rs[0]['uv_own']:.3f} | " + " | ".join(
            f"{r['y_a']:.3f} | {r['uv_a']:.3f} | {'yes' if r['ok'] else 'no'}" for r in rs) + " |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
