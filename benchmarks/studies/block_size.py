"""Block and margin sizes of the blocked levels (issue 22): quality and processor time.

Every level is cut into blocks (blocks.SINGLE_NODES = 0, as a canvas over 2.5 MP is), so
the wide corpus's 1280 x 800 photos and the five corpus photos show what blocks do to a
big master's render. Candidates "YB/YM/CB/CM[/R]": the luma's block and margin and the
chroma's (nodes at the level; 0: the default), and blocks.REACH_STEPS (default: the module's). For each photo (encoded once, kept in --cache) and
candidate: 1x PSNR against the original, PSNR of the U and V planes, SSIMULACRA2, the
reductions' PSNR against the box reduction of the original, and the render's processor time;
--single adds the one-window render (the whole canvas's fields: what blocks approach).

    python benchmarks/studies/block_size.py [--candidates 256/32/256/32,512/32/512/32]
        [--images A,B] [--cache /tmp/chroma_masters] [--single]

Prints a markdown table per measure (each candidate and its delta to the first, the mean).
"""

from __future__ import annotations

import argparse
import os
import sys
import threading

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

from chroma_nodes import cpu, master, uv_psnr  # noqa: E402
from corpus import load_corpus  # noqa: E402
from peers import downscale  # noqa: E402
from quality_wide import wide_photos  # noqa: E402

import isophote.render as R  # noqa: E402
from isophote import metrics  # noqa: E402
from isophote.render import blocks  # noqa: E402

MAKE_LEVEL = blocks.make_level
CHANNEL_STATE = R.channel_state
_CHANNEL = threading.local()  # the channel whose level is being made


def channel_state(vi, ch, *a, **k):
    _CHANNEL.name = ch.name
    return CHANNEL_STATE(vi, ch, *a, **k)


R.channel_state = channel_state
REACH_STEPS = blocks.REACH_STEPS


def use(spec: str) -> None:
    """Render with the candidate spec ("single": one window over every level)."""
    if spec == "single":
        blocks.SINGLE_NODES, blocks.SINGLE_SEGMENTS = 10 ** 12, 10 ** 12
        R.make_level = MAKE_LEVEL
        return
    blocks.SINGLE_NODES, blocks.SINGLE_SEGMENTS = 0, 600_000
    yb, ym, cb, cm, *reach = (int(v) for v in spec.split("/"))
    blocks.REACH_STEPS = reach[0] if reach else REACH_STEPS

    def make_level(vi, r, zoom, n_segments=0, fraction=1.0):
        chroma = getattr(_CHANNEL, "name", "Y") in ("U", "V")
        lv = MAKE_LEVEL(vi, r, zoom, n_segments, fraction)
        b, m = (cb, cm) if chroma else (yb, ym)
        if not lv.block or not (b or m):
            return lv
        scale = lv.block / blocks.BLOCK  # block_size's cut above 1x, kept in proportion
        return blocks.Level(lv.r, lv.nr, lv.nc, max(1, int((b or blocks.BLOCK) * scale)), m or lv.margin)

    R.make_level = make_level


def measure(vi, img, reductions) -> dict:
    row = {}
    t = cpu()
    one = vi.render()
    row["1x s"] = cpu() - t
    row["1x PSNR"] = metrics.psnr(img, one)
    if img.ndim == 3:
        row["1x UV PSNR"] = uv_psnr(img, one)
    row["1x S2"] = metrics.ssimulacra2(img, one)
    for f in reductions:
        ref = downscale(img, f)
        hh, ww = ref.shape[:2]
        out = vi.render(crop=(0, 0, ww * f, hh * f), width=ww, height=hh)
        row[f"1/{f} PSNR"] = metrics.psnr(ref, out)
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--wide", default=os.environ.get("ISOPHOTE_WIDE", "corpus-wide"))
    ap.add_argument("--candidates", default="256/32/256/32,512/32/512/32")
    ap.add_argument("--images")
    ap.add_argument("--cache", default="/tmp/chroma_masters")
    ap.add_argument("--reductions", default="2,8")
    ap.add_argument("--single", action="store_true")
    a = ap.parse_args(argv)
    photos = wide_photos(a.wide)
    photos.update(load_corpus())
    if a.images:
        photos = {k: v for k, v in photos.items() if k in a.images.split(",")}
    specs = a.candidates.split(",") + (["single"] if a.single else [])
    reductions = [int(f) for f in a.reductions.split(",") if f]
    rows = {}
    for name, img in photos.items():
        vi = master(name, img, a.cache)
        vi.render(crop=(0, 0, 32, 32))  # compile / load the kernels
        for spec in specs:
            use(spec)
            rows[name, spec] = measure(vi, img, reductions)
            print(name, spec, {k: round(float(v), 3) for k, v in rows[name, spec].items()}, file=sys.stderr, flush=True)
    for k in rows[next(iter(rows))]:
        print(f"\n### {k}\n")
        print("| photo | " + " | ".join(specs) + " | " + " | ".join(f"{s} - first" for s in specs[1:]) + " |")
        print("|---" * (2 * len(specs)) + "|")
        vals = []
        for name in photos:
            if k not in rows[name, specs[0]]:
                continue
            v = [rows[name, s][k] for s in specs]
            vals.append(v + [x - v[0] for x in v[1:]])
            print(f"| {name} | " + " | ".join(f"{x:.3f}" for x in vals[-1]) + " |")
        print("| **mean** | " + " | ".join(f"{x:.3f}" for x in np.nanmean(np.array(vals), axis=0)) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
