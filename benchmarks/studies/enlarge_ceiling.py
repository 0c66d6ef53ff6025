"""How well could an enlargement from a master do at best? The encode's own loss (issue 26).

Protocol of benchmarks/quality_wide.py ("enlarge"): each photograph is box-downsampled by f
(2, 4), encoded (default preset), and rendered at f; it is scored against the original
beside Pillow's bicubic and Lanczos enlargements of the small image. The oracle row is what
a renderer could do if it only had its own 1x render to interpolate: Pillow's bicubic of the
master's 1x render. Where isophote's enlargement is at or above that oracle, the distance to
bicubic of the small image is the encode's loss of the small image (its 1x PSNR is listed),
not the renderer's.

    PYTHONPATH=src .venv/bin/python benchmarks/studies/enlarge_ceiling.py [--dir corpus-wide/photo] [--preset balanced]
"""

from __future__ import annotations

import argparse
import glob
import os
import sys

import numpy as np
from PIL import Image

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))  # benchmarks/: peers

import isophote  # noqa: E402
from isophote import metrics  # noqa: E402
from peers import downscale  # noqa: E402

CASES = ("iso", "bicubic", "lanczos", "bicubic_of_iso1x")


def up(a, f, method):
    h, w = a.shape[:2]
    return np.asarray(Image.fromarray(a).resize((w * f, h * f), method))


def study(path, preset):
    img = np.asarray(Image.open(path).convert("RGB"))
    rows = []
    for f in (2, 4):
        small = downscale(img, f)
        hh, ww = small.shape[:2]
        ref = img[: hh * f, : ww * f]
        vi = isophote.encode(small, preset=preset)
        r1 = vi.render()
        made = {"iso": vi.render(scale=f), "bicubic": up(small, f, Image.Resampling.BICUBIC),
                "lanczos": up(small, f, Image.Resampling.LANCZOS),
                "bicubic_of_iso1x": up(r1, f, Image.Resampling.BICUBIC)}
        row = {"f": f, "small_1x_psnr": metrics.psnr(small, r1)}
        for k, a in made.items():
            row[k] = (metrics.psnr(ref, a), metrics.ssimulacra2(ref, a))
        rows.append(row)
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default="corpus-wide/photo")
    ap.add_argument("--preset", default="balanced")
    ap.add_argument("--out", default=os.path.join(os.path.dirname(HERE), "results", "enlarge_ceiling.md"))
    args = ap.parse_args()
    paths = sorted(glob.glob(os.path.join(args.dir, "*.png")))
    if not paths:
        sys.exit(f"no photographs in {args.dir} (../shared/corpus/fetch-wide.sh corpus-wide)")
    table = {os.path.basename(p)[:-4]: study(p, args.preset) for p in paths}
    lines = [f"# Enlargement ceiling ({args.preset}, {args.dir})", "",
             "`benchmarks/studies/enlarge_ceiling.py`: PSNR / SSIMULACRA2 against the original; oracle = "
             "bicubic of the master's own 1x render; small 1x = the master's PSNR against the small image.", ""]
    for i, f in enumerate((2, 4)):
        lines += [f"## x{f}", "", "| photo | small 1x PSNR | isophote | oracle | bicubic | Lanczos |", "|---|---|---|---|---|---|"]
        for name, rows in table.items():
            r = rows[i]
            cell = lambda k: f"{r[k][0]:.2f} / {r[k][1]:.1f}"  # noqa: E731
            lines.append(f"| {name} | {r['small_1x_psnr']:.2f} | {cell('iso')} | {cell('bicubic_of_iso1x')} | "
                         f"{cell('bicubic')} | {cell('lanczos')} |")
        rs = [rows[i] for rows in table.values()]
        mean = {k: (np.mean([r[k][0] for r in rs]), np.mean([r[k][1] for r in rs])) for k in CASES}
        lines.append(f"| **mean** | {np.mean([r['small_1x_psnr'] for r in rs]):.2f} | "
                     + " | ".join(f"{mean[k][0]:.2f} / {mean[k][1]:.1f}" for k in ("iso", "bicubic_of_iso1x", "bicubic", "lanczos"))
                     + " |")
        lines += ["", f"isophote >= oracle: PSNR {sum(r['iso'][0] >= r['bicubic_of_iso1x'][0] for r in rs)} of {len(rs)}, "
                      f"SSIMULACRA2 {sum(r['iso'][1] >= r['bicubic_of_iso1x'][1] for r in rs)}; isophote >= bicubic PSNR "
                      f"{sum(r['iso'][0] >= r['bicubic'][0] for r in rs)}; >= Lanczos SSIMULACRA2 "
                      f"{sum(r['iso'][1] >= r['lanczos'][1] for r in rs)}.", ""]
    with open(args.out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
