"""Blocked renders against the one-window render: the sources beyond a window (issue 22).

A blocked level (a canvas over 2.5 MP at 1x, every tile zoom of a big master) computes each
block's fields on a window of the block and a margin. Its nodes farther than the margin from
every source of a side found a farther one, or none; since 2026-12-02 the window's cut edges
are offered the sources of the level's coarse field (blocks.py, diffuse.offer_coarse). For
each photo this renders the one-window render (blocks.SINGLE_NODES raised: the whole level's
fields, what blocks approach), the blocked render without the offers (as before) and with
them, and reports the share of pixels more than 0.5 and more than 2 levels off the
one-window render (any of R, G, B), each render's PSNR against the original and its
processor time. ``--force``: cut every level into blocks (blocks.SINGLE_NODES = 0), as the
1280 x 800 photos' levels are not otherwise; ``--scale``: the render's scale.

    python benchmarks/studies/block_sources.py [--wide corpus-wide] [--masters A.isoph[=A.jpg],...]
        [--image PHOTO --region x,y,w,h] [--cache /tmp/block_sources] [--force] [--scale 1]
        [--margin 32]

``--image``/``--region``: that region of a photograph, encoded (a small canvas whose
one-window render at an enlargement fits in memory, as a deep-zoom tile's level does not).

Prints one markdown table (a row a photo, and the mean).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

import isophote  # noqa: E402
from isophote.render import blocks  # noqa: E402
from quality_wide import wide_photos  # noqa: E402


def psnr(a, b) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return 10 * np.log10(255.0 ** 2 / mse) if mse > 0 else float("inf")


def render(vi, scale, single, offers):
    blocks.SINGLE_NODES = 10**15 if single else (0 if FORCE else SINGLE)
    blocks.offer_coarse = OFFER if offers else (lambda *args: None)
    try:
        t = time.process_time()
        out = vi.render(scale=scale)
        return out, time.process_time() - t
    finally:
        blocks.SINGLE_NODES, blocks.offer_coarse = SINGLE, OFFER


SINGLE, OFFER, FORCE = blocks.SINGLE_NODES, blocks.offer_coarse, False


def main(argv=None) -> int:
    global FORCE
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wide", default="")
    ap.add_argument("--masters", default="")
    ap.add_argument("--image", default="")
    ap.add_argument("--region", default="")
    ap.add_argument("--cache", default="/tmp/block_sources")
    ap.add_argument("--force", action="store_true")
    ap.add_argument("--scale", type=float, default=1.0)
    ap.add_argument("--margin", type=int, default=0, help="blocks.MARGIN for the blocked renders (0: as it is)")
    args = ap.parse_args(argv)
    FORCE = args.force
    if args.margin:
        blocks.MARGIN = args.margin
    items = []
    if args.wide:
        for name, img in wide_photos(args.wide).items():
            p = os.path.join(args.cache, f"{name}.isoph")
            if not os.path.exists(p):
                os.makedirs(args.cache, exist_ok=True)
                isophote.encode(img).save(p)
            items.append((name, isophote.load(p), img))
    if args.image:
        from PIL import Image

        with Image.open(args.image) as im:
            img = np.asarray(im.convert("RGB"))
        x, y, w, h = (int(v) for v in args.region.split(",")) if args.region else (0, 0, img.shape[1], img.shape[0])
        img = np.ascontiguousarray(img[y:y + h, x:x + w])
        items.append((f"{os.path.splitext(os.path.basename(args.image))[0]} [{args.region}]", isophote.encode(img), img))
    for spec in filter(None, args.masters.split(",")):
        p, _, original = spec.partition("=")  # MASTER.isoph[=ORIGINAL]: PSNR against the original
        img = None
        if original:
            from PIL import Image

            with Image.open(original) as im:
                img = np.asarray(im.convert("RGB"))
        items.append((os.path.splitext(os.path.basename(p))[0], isophote.load(p), img))
    print(f"scale {args.scale:g}, {'every level blocked' if FORCE else 'levels blocked over 2.5 M nodes'}, "
          f"margin {blocks.MARGIN}\n")
    print("| photo | > 0.5 off without | with | > 2 off without | with | PSNR one-window | without | with "
          "| CPU s one-window | without | with |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    rows = []
    for name, vi, img in items:
        one, t1 = render(vi, args.scale, True, True)
        off, t0 = render(vi, args.scale, False, False)
        on, t2 = render(vi, args.scale, False, True)
        d0 = np.abs(off.astype(int) - one.astype(int)).max(axis=-1)
        d1 = np.abs(on.astype(int) - one.astype(int)).max(axis=-1)
        ps = [psnr(img, x) if img is not None and args.scale == 1 else np.nan for x in (one, off, on)]
        row = [100 * np.mean(d0 > 0.5), 100 * np.mean(d1 > 0.5), 100 * np.mean(d0 > 2), 100 * np.mean(d1 > 2),
               *ps, t1, t0, t2]
        rows.append(row)
        print(f"| {name} | {row[0]:.2f} % | {row[1]:.2f} % | {row[2]:.3f} % | {row[3]:.3f} % | {row[4]:.2f} | "
              f"{row[5]:.2f} | {row[6]:.2f} | {row[7]:.1f} | {row[8]:.1f} | {row[9]:.1f} |", flush=True)
    if len(rows) > 1:
        m = np.nanmean(np.array(rows, float), axis=0)
        print(f"| **mean** | {m[0]:.2f} % | {m[1]:.2f} % | {m[2]:.3f} % | {m[3]:.3f} % | {m[4]:.2f} | {m[5]:.2f} | "
              f"{m[6]:.2f} | {m[7]:.1f} | {m[8]:.1f} | {m[9]:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
