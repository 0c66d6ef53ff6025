"""Encoder scale (issue 22): peak RSS and seconds a megapixel against image size.

Crops of one photograph (default the wide corpus's 16 MP mosaic: a 1 MP and a 4 MP crop
from its centre, and the whole) are encoded, each in a fresh process whose peak RSS is read
with os.wait4; Pillow's decode of the same PNG is measured the same way in the same run, as
the peer. The encode time is measured inside the child, without import and kernel loading
(a 64x64 encode warms the kernels first); the baseline row is that warm-up alone.

    PYTHONPATH=src .venv/bin/python benchmarks/encode_scale.py \
        --image corpus-wide/mosaic-16mp.png --sizes 1,4,16 --preset balanced
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

CHILD = r"""
import json, sys, time
import numpy as np
from PIL import Image
path, mp, preset, memory = sys.argv[1], float(sys.argv[2]), sys.argv[3], sys.argv[4]
t0 = time.perf_counter()
with Image.open(path) as im:
    im = im.convert("RGB")
    w, h = im.size
    if mp > 0 and mp * 1e6 < w * h * 0.98:
        s = (mp * 1e6 / (w * h)) ** 0.5
        cw, ch = int(round(w * s)), int(round(h * s))
        x0, y0 = (w - cw) // 2, (h - ch) // 2
        im = im.crop((x0, y0, x0 + cw, y0 + ch))
    a = np.asarray(im)
del im  # the encode's peak is measured beside the decoded array alone, not Pillow's image too
t_decode = time.perf_counter() - t0
out = {"pixels": int(a.shape[0] * a.shape[1]), "shape": list(a.shape[:2]), "decode_s": t_decode}
if preset != "pillow":
    import isophote
    kw = {} if memory == "default" else {"memory": memory}
    isophote.encode(a[:64, :64], preset=preset, **kw)  # kernels loaded
    if mp != 0:
        t0 = time.perf_counter()
        vi = isophote.encode(a, preset=preset, **kw)
        out["encode_s"] = time.perf_counter() - t0
print(json.dumps(out))
"""


def run_child(image, mp, preset, memory):
    env = dict(os.environ)
    p = subprocess.Popen([sys.executable, "-c", CHILD, image, str(mp), preset, memory],
                         stdout=subprocess.PIPE, env=env, text=True)
    out = p.stdout.read()
    _, status, ru = os.wait4(p.pid, 0)
    p.stdout.close()
    if status != 0:
        raise SystemExit(f"child failed ({status}) for {mp} MP {preset}")
    res = json.loads(out.strip().splitlines()[-1])
    res["peak_mb"] = ru.ru_maxrss / 1024.0  # kilobytes on Linux
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--image", default="corpus-wide/mosaic-16mp.png")
    ap.add_argument("--sizes", default="1,4,16", help="megapixels of the centre crops (16 or more: the whole)")
    ap.add_argument("--preset", default="balanced")
    ap.add_argument("--memory", default="default")
    ap.add_argument("--out", default=None, help="append the table to this markdown file")
    args = ap.parse_args(argv)
    sizes = [float(s) for s in args.sizes.split(",")]
    rows = []
    base = run_child(args.image, 0, args.preset, args.memory)
    rows.append(("baseline (import + 64x64 warm-up)", 0, base["peak_mb"], None, None))
    for mp in sizes:
        peer = run_child(args.image, mp, "pillow", args.memory)
        enc = run_child(args.image, mp, args.preset, args.memory)
        px = enc["pixels"]
        rows.append((f"Pillow decode + crop {enc['shape'][1]}x{enc['shape'][0]}", px, peer["peak_mb"],
                     peer["decode_s"], None))
        rows.append((f"encode {args.preset} {enc['shape'][1]}x{enc['shape'][0]}", px, enc["peak_mb"],
                     enc["encode_s"], enc["encode_s"] / (px / 1e6)))
        print(rows[-2], rows[-1], file=sys.stderr, flush=True)
    lines = [f"## {os.path.basename(args.image)}, preset {args.preset}, memory {args.memory} "
             f"({time.strftime('%Y-%m-%d')})", "",
             "| run | pixels | peak RSS MB | B/px (peak) | seconds | s/MP |", "|---|---|---|---|---|---|"]
    for name, px, peak, sec, spmp in rows:
        bpp = f"{peak * 2**20 / px:,.0f}" if px else ""
        lines.append(f"| {name} | {px:,} | {peak:,.0f} | {bpp} | "
                     f"{'' if sec is None else f'{sec:.2f}'} | {'' if spmp is None else f'{spmp:.2f}'} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        with open(args.out, "a") as f:
            f.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
