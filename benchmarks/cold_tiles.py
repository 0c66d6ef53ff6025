"""Processor time of cold 256-px tiles after the preparation, by zoom (issue 23).

In process, one thread (threads.limited(1)), after ``vi.prepare(zooms)`` as the server does
(serve/tiles.py): N tiles a zoom at random tile positions (fixed seed), each rendered 3
times with the block-field caches emptied before each (so every one is cold: its blocks'
fields are computed), the least processor time of the 3 kept. Also the thread time inside
ChannelLevel.field (the block fields) and inside evaluate (node fill and samples).

    python benchmarks/cold_tiles.py MASTER.isoph [--tiles 8] [--zooms 1,2,4,8]

Prints a Markdown table and a hash of the tiles' bytes (equal before and after a change
that keeps the output).
"""

from __future__ import annotations

import argparse
import collections
import hashlib
import time

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("master")
    ap.add_argument("--tiles", type=int, default=8)
    ap.add_argument("--zooms", default="1,2,4,8")
    args = ap.parse_args(argv)

    import isophote
    import isophote.render.blocks as B
    from isophote import threads
    from isophote.render import prepare as P

    took = collections.defaultdict(float)

    def timed(fn, lab):
        def run(*a, **k):
            t = time.thread_time()
            try:
                return fn(*a, **k)
            finally:
                took[lab] += time.thread_time() - t
        return run

    B.ChannelLevel.field = timed(B.ChannelLevel.field, "field")
    B.evaluate = timed(B.evaluate, "evaluate")
    vi = isophote.load(args.master)
    zooms = [float(z) for z in args.zooms.split(",")]
    vi.prepare(zooms)
    prep = P.prepared(vi)
    rng = np.random.default_rng(1)
    h = hashlib.sha256()
    n = args.tiles
    print("| zoom | tile ms median | mean | max | block fields ms | evaluate (node fill + samples) ms |")
    print("|---:|---:|---:|---:|---:|---:|")
    with threads.limited(1):
        vi.tile((0.0, 0.0, 64.0, 64.0), (64, 64))  # compile / load the kernels
        vi.tile((0.0, 0.0, 32.0, 32.0), (256, 256))
        for z in zooms:
            src = 256 / z
            ts = []
            took.clear()
            for _ in range(n):
                x = float(rng.integers(0, int(vi.width / src) - 1) * src)
                y = float(rng.integers(0, int(vi.height / src) - 1) * src)
                best = np.inf
                for _ in range(3):
                    prep.caches.clear()
                    t = time.thread_time()
                    a = vi.tile((x, y, src, src), (256, 256), max_pixels=2**40)
                    best = min(best, time.thread_time() - t)
                ts.append(best)
                h.update(a.tobytes())
            ts = np.array(ts) * 1000
            print(f"| {z:g} | {np.median(ts):.0f} | {ts.mean():.0f} | {ts.max():.0f} | "
                  f"{took['field'] * 1000 / n / 3:.0f} | {took['evaluate'] * 1000 / n / 3:.0f} |", flush=True)
    print("tiles' bytes sha256", h.hexdigest()[:16])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
