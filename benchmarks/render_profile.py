"""Where a render's time goes, stage by stage (issue 22): processor seconds of each kernel.

One process, one thread (threads.limited(1): the stages' own times, not the waits of a
shared machine), after a warm-up render: the renderer's kernels are wrapped by timers that
read the calling thread's processor time, so the figures hold on a loaded machine too.

    python benchmarks/render_profile.py MASTER.isoph [--scale 0.75 | --width 960] [--crop x,y,w,h]
        [--prepared]

``--prepared``: the master is prepared for the render's scale first (VectorImage.prepare,
not timed), so a crop costs what a tile there does: its windows and its samples.

Stages: the segment index; the canvas-wide region pass (its bands, then the labelling);
per block window the rasterised rows and columns with their crossings, seed, propagate,
label, region caps, band widths and the node fill (evaluate:nodes); per strip the samples'
bands (raster:sample-bands) and their fill read from the windows (evaluate:samples); the
colour conversion. Prints a table; nothing is written.
"""

from __future__ import annotations

import argparse
import collections
import threading
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("master")
    ap.add_argument("--scale", type=float)
    ap.add_argument("--width", type=int)
    ap.add_argument("--crop", help="x,y,w,h in source pixels")
    ap.add_argument("--prepared", action="store_true", help="prepare the master for this scale first")
    args = ap.parse_args(argv)

    import isophote
    import isophote.render as R
    import isophote.render.blocks as B
    import isophote.render.segment_index as SI
    import isophote.render.strips as S
    from isophote import threads

    took = collections.defaultdict(float)
    calls = collections.defaultdict(int)
    where = threading.local()

    def timed(fn, label):
        def run(*a, **k):
            lab = label(a) if callable(label) else label
            t = time.thread_time()
            try:
                return fn(*a, **k)
            finally:
                took[lab] += time.thread_time() - t
                calls[lab] += 1
        return run

    def inside(fn, flag):
        def run(*a, **k):
            setattr(where, flag, True)
            try:
                return fn(*a, **k)
            finally:
                setattr(where, flag, False)
        return run

    for name in ("seed", "propagate", "label_nodes", "region_caps", "band_widths", "rasterise_window",
                 "local_cap_values_runs"):
        setattr(B, name, timed(getattr(B, name), name))
    B.evaluate = timed(B.evaluate, lambda a: "evaluate:samples" if getattr(where, "samples", False)
                       else "evaluate:nodes")
    S.evaluate_piece = inside(S.evaluate_piece, "samples")
    B.ChannelLevel.rasterise = timed(B.ChannelLevel.rasterise, lambda a: "raster:regions"
                                     if getattr(where, "regions", False) else "raster:sample-bands")
    B.ChannelLevel._regions = inside(B.ChannelLevel._regions, "regions")
    SI.SegmentIndex.__init__ = timed(SI.SegmentIndex.__init__, "segment index")
    R._convert = timed(R._convert, "colour")

    opts = {k: v for k, v in (("scale", args.scale), ("width", args.width)) if v is not None}
    if args.crop:
        opts["crop"] = tuple(float(v) for v in args.crop.split(","))
    vi = isophote.load(args.master)
    with threads.limited(1):
        if args.prepared:
            from isophote.options import RenderOptions, make
            from isophote.render.prepare import prepare

            vp = R.viewport(vi, make(RenderOptions, opts))
            prepare(vi, (max(vp.kx, vp.ky) / vp.s,))  # the zoom channel_state gives this render
        vi.render(crop=(0, 0, 64, 64), scale=opts.get("scale", 1.0))  # compile / load the kernels
        took.clear()
        calls.clear()
        t = time.thread_time()
        out = vi.render(**opts)
        total = time.thread_time() - t
    mp = out.shape[0] * out.shape[1] / 1e6
    print(f"{args.master} {opts or '1x'}: output {out.shape[1]}x{out.shape[0]}, "
          f"{total:.2f} s processor time on one thread ({total / mp:.3f} s per output MP)")
    print("| stage | s | share | calls |\n|---|---|---|---|")
    for k in sorted(took, key=lambda k: -took[k]):
        print(f"| {k} | {took[k]:.2f} | {100 * took[k] / total:.0f}% | {calls[k]} |")
    rest = total - sum(took.values())
    print(f"| the rest (Python, copies, tone curve, box filter) | {rest:.2f} | {100 * rest / total:.0f}% | |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
