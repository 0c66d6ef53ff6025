"""Block and margin sizes of the blocked levels (issue 22): quality and processor time.

Every level is cut into blocks (blocks.SINGLE_NODES = 0, as a canvas over 2.5 MP is), so
the wide corpus's 1280 x 800 photos and the five corpus photos show what blocks do to a
big master's render. Candidates "YB/YM/CB/CM": the luma's block and margin and the
chroma's (nodes at the level; 0: the default). For each photo (encoded once, kept in --cache) and
candidate: 1x PSNR against the original, PSNR of the U and V planes, SSIMULACRA2, the
reductions' PSNR against the box reduction of the original, and each render's processor time;
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

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.dirname(HERE))

from chroma_nodes import master, measure, print_tables  # noqa: E402
from corpus import load_corpus  # noqa: E402
from quality_wide import wide_photos  # noqa: E402

import isophote.render as R  # noqa: E402
from isophote.render import blocks  # noqa: E402

MAKE_LEVEL = blocks.make_level
CHANNEL_STATE = R.channel_state
_CHANNEL = threading.local()  # the channel whose level is being made


def channel_state(vi, ch, *a, **k):
    _CHANNEL.name = ch.name
    return CHANNEL_STATE(vi, ch, *a, **k)


R.channel_state = channel_state


def use(spec: str) -> None:
    """Render with the candidate spec ("single": one window over every level)."""
    if spec == "single":
        blocks.SINGLE_NODES, blocks.SINGLE_SEGMENTS = 10 ** 12, 10 ** 12
        R.make_level = MAKE_LEVEL
        return
    blocks.SINGLE_NODES, blocks.SINGLE_SEGMENTS = 0, 600_000
    yb, ym, cb, cm = (int(v) for v in spec.split("/"))

    def make_level(vi, r, zoom, n_segments=0, fraction=1.0):
        chroma = getattr(_CHANNEL, "name", "Y") in ("U", "V")
        lv = MAKE_LEVEL(vi, r, zoom, n_segments, fraction)
        b, m = (cb, cm) if chroma else (yb, ym)
        if not lv.block or not (b or m):
            return lv
        scale = lv.block / blocks.BLOCK  # block_size's cut above 1x, kept in proportion
        return blocks.Level(lv.r, lv.nr, lv.nc, max(1, int((b or blocks.BLOCK) * scale)), m or lv.margin)

    R.make_level = make_level


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
            rows[name, spec], _ = measure(vi, img, {"s2", "reduce"}, reductions, reduction_s2=False)
            print(name, spec, {k: round(float(v), 3) for k, v in rows[name, spec].items()}, file=sys.stderr, flush=True)
    print_tables(rows, photos, specs, specs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
