"""Block sizes above 1x (issue 22): a deep-zoom tile's cost against closeness to one window.

Above one output pixel a node, blocks.block_size gives the largest power of two of nodes
within BLOCK output pixels, so that a 256 x 256 tile on its zoom's grid lies in one block.
The rule before (halve while zoom_per_node x b > 2 x BLOCK, at least 64) gave blocks twice
as wide, and a 2x tile of a big master read a 288^2-node window a channel instead of 160^2.
For each photograph (encoded with the default preset, kept in --cache) and each zoom (2, 4,
8; r = 1, as for any master over 1.5 MP), this renders random 512 x 512 crops on the zoom's
tile grid with both rules and with the whole level as one window (what blocks approach), and
prints each rule's PSNR against the one-window crop, its largest difference, the share of
values more than 2 off, and the processor time.

    python benchmarks/studies/tile_blocks.py [--photos Kite,ColdRipple,Path]
        [--wide corpus-wide] [--crops 6] [--cache /tmp/tile_blocks]
"""

from __future__ import annotations

import argparse
import os
import random
import time

import numpy as np

import isophote
from isophote.render import blocks

NEW = blocks.block_size


def before(zoom_per_node: float) -> int:
    b = blocks.BLOCK
    while b > 64 and zoom_per_node * b > 2 * blocks.BLOCK:
        b //= 2
    return b


def psnr(a, b) -> float:
    m = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if m == 0 else float(10 * np.log10(255.0 ** 2 / m))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--photos", default="Kite,ColdRipple,Path")
    ap.add_argument("--wide", default="corpus-wide")
    ap.add_argument("--crops", type=int, default=6)
    ap.add_argument("--cache", default="/tmp/tile_blocks")
    args = ap.parse_args(argv)
    os.makedirs(args.cache, exist_ok=True)
    print("| photo | zoom | rule | block | PSNR vs one window, mean | min | largest difference | > 2 off | CPU s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in args.photos.split(","):
        path = os.path.join(args.cache, name + ".isoph")
        if not os.path.exists(path):
            from PIL import Image

            with Image.open(os.path.join(args.wide, "photo-4mp", name + ".jpg")) as im:
                isophote.encode(np.asarray(im.convert("RGB"))).save(path)
        vi = isophote.load(path, compact=True)
        rng = random.Random(1)
        for z in (2, 4, 8):
            span, step = 512 / z, 256 / z
            got = {"before": [], "now": []}
            cpu = {"before": 0.0, "now": 0.0}
            for _ in range(args.crops):
                x = rng.randrange(int((vi.width - span) // step)) * step
                y = rng.randrange(int((vi.height - span) // step)) * step
                kw = dict(crop=(x, y, span, span), width=512, height=512)
                with blocks.one_window(10**9):
                    ref = np.asarray(vi.render(**kw))
                for rule, f in (("before", before), ("now", NEW)):
                    blocks.block_size = f
                    try:
                        t = time.process_time()
                        a = np.asarray(vi.render(**kw))
                        cpu[rule] += time.process_time() - t
                    finally:
                        blocks.block_size = NEW
                    d = np.abs(a.astype(np.int32) - ref.astype(np.int32))
                    got[rule].append((psnr(a, ref), int(d.max()), float((d > 2).mean())))
            for rule, f in (("before", before), ("now", NEW)):
                r = np.array(got[rule])
                print(f"| {name} | {z}x | {rule} | {f(z)} | {r[:, 0].mean():.2f} | {r[:, 0].min():.2f} | "
                      f"{r[:, 1].max():.0f} | {100 * r[:, 2].mean():.3f} % | {cpu[rule]:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
