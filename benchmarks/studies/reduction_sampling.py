"""Choose the nodes and samples of a reduction (render/levels.py) by quality and time.

For each photograph (the wide corpus's 1280 x 800 PNGs and the five corpus photos), default
preset, at 1/2, 1/4 and 1/8 against the box reduction of the original: PSNR and
SSIMULACRA2 of each candidate, with its wall and CPU seconds (measured back to back in one
process), beside the bound (the box reduction of the master's own 1x render: what a perfect
area average of this master gives) and Pillow's Lanczos of the original. A candidate
``sS_nN``: S x S samples a pixel (box filtered), nodes at N times the smallest power of two
>= the scale a source pixel (N nodes a side per output pixel, at most one a source pixel);
``rule``: what levels.py chooses. s2_n1 was the rule before issue 26's change.

    PYTHONPATH=src .venv/bin/python benchmarks/studies/reduction_sampling.py [--wide corpus-wide]
        [--images NAME,...] [--candidates s2_n1,s4_n1,s4_n2,rule] [--cache /tmp]
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))  # benchmarks/

from corpus import load_corpus  # noqa: E402
from peers import downscale  # noqa: E402
from quality_wide import lanczos, wide_photos  # noqa: E402

import isophote  # noqa: E402
import isophote.render as R  # noqa: E402
from isophote import metrics  # noqa: E402
from isophote.render import levels  # noqa: E402


def candidate(spec: str):
    """(reduction_r, auto_supersample) of a candidate spec (see the module docstring)."""
    if spec == "rule":
        return levels.reduction_r, levels.auto_supersample
    s, n = (int(p[1:]) for p in spec.split("_"))
    return (lambda z: min(1.0, n * levels._pow2_at_least(z))), (lambda req, z: max(int(req), s))


def measure(vi, img, f: int, spec: str, one) -> tuple:
    """(PSNR, SSIMULACRA2, wall s, CPU s) of one candidate at 1/f."""
    ref = downscale(img, f)
    hh, ww = ref.shape[:2]
    t, c = time.perf_counter(), time.process_time()
    if spec == "bound":
        out = downscale(one, f)
    elif spec == "lanczos":
        out = lanczos(img[: hh * f, : ww * f], (ww, hh))
    else:
        R.reduction_r, R.auto_supersample = candidate(spec)
        try:
            out = vi.render(crop=(0, 0, ww * f, hh * f), width=ww, height=hh)
        finally:
            R.reduction_r, R.auto_supersample = levels.reduction_r, levels.auto_supersample
    dt, dc = time.perf_counter() - t, time.process_time() - c
    return metrics.psnr(ref, out), metrics.ssimulacra2(ref, out), dt, dc


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wide", default=os.environ.get("ISOPHOTE_WIDE", "corpus-wide"))
    ap.add_argument("--images", default=None)
    ap.add_argument("--candidates", default="s2_n1,s4_n1,s4_n2,rule")
    ap.add_argument("--cache", default="/tmp")
    a = ap.parse_args(argv)
    photos = wide_photos(a.wide)
    photos.update(load_corpus())
    if a.images:
        photos = {k: v for k, v in photos.items() if k in a.images.split(",")}
    specs = ["bound", "lanczos"] + a.candidates.split(",")
    sums = {}
    for name, img in photos.items():
        path = os.path.join(a.cache, f"reduction_sampling_{name}.isoph")
        if not os.path.exists(path):
            isophote.encode(img).save(path)
        vi = isophote.load(path)
        one = vi.render()
        for f in (2, 4, 8):
            for spec in specs:
                v = measure(vi, img, f, spec, one)
                sums.setdefault((f, spec), []).append(v)
                print(f"{name:14s} 1/{f} {spec:8s} PSNR {v[0]:6.2f} S2 {v[1]:6.1f} wall {v[2]:6.2f} cpu {v[3]:6.2f}",
                      flush=True)
    print(f"\nmean of {len(photos)} | PSNR | SSIMULACRA2 | wall s (sum) | CPU s (sum)")
    for (f, spec), vals in sums.items():
        v = np.array(vals)
        print(f"1/{f} {spec:8s} | {v[:, 0].mean():.2f} | {v[:, 1].mean():.1f} | {v[:, 2].sum():.1f} | {v[:, 3].sum():.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
