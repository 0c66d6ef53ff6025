"""Encoder memory by stage (issue 22): peak and held RSS of each stage of one channel, in
bytes a pixel, on a crop of a photograph (default: the wide corpus's 16 MP mosaic).

Peaks come from the kernel's high-water mark (VmHWM, reset before each stage by writing 5
to /proc/self/clear_refs; Linux only), so they include what the numba kernels allocate,
which tracemalloc does not see. Stages run one after another (the encoder runs the fit
beside the hierarchy when the budget allows; their peaks then add).

    PYTHONPATH=src .venv/bin/python benchmarks/encode_stages.py --rows 1280 --cols 1600
"""

from __future__ import annotations

import argparse
import gc
import resource
import time

import numpy as np

from isophote import encoder as E
from isophote.colour import rgb_to_yuv
from isophote.encoder import budget, hierarchy, levels as L, noise
from isophote.encoder.strips import strip_isolines
from isophote.imageio import read_image
from isophote.options import EncodeOptions


def rss():
    with open("/proc/self/status") as f:
        d = dict(line.split(":", 1) for line in f)
    return int(d["VmRSS"].split()[0]) * 1024, int(d["VmHWM"].split()[0]) * 1024


def reset_peak():
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


def stages(plane, name, opts, memory, report):
    npx = plane.size
    lev = L.channel_levels(name, opts)

    def stage(label, f):
        gc.collect()
        r0 = rss()[0]
        reset_peak()
        t = time.perf_counter()
        u0 = resource.getrusage(resource.RUSAGE_SELF)
        res = f()
        dt = time.perf_counter() - t
        u1 = resource.getrusage(resource.RUSAGE_SELF)
        r1, hwm = rss()
        if report:
            print(f"| {label} | {(hwm - r0) / npx:.0f} | {(r1 - r0) / npx:.0f} | {dt:.2f} "
                  f"| {u1.ru_utime - u0.ru_utime:.2f} | {u1.ru_stime - u0.ru_stime:.2f} "
                  f"| {(u1.ru_minflt - u0.ru_minflt) / 1e6:.2f} |")
        return res

    p2, eps = stage("prepare (noise, pruning)", lambda: noise.prepare_plane(name, plane, 0.5, lev, opts))
    iso = stage("map + isolines (strips)",
                lambda: strip_isolines(p2, eps, lev, opts, budget.strip_rows(memory, plane.shape[1]), E.STRIP_WORKERS))
    del p2, eps
    if report:
        held = sum(getattr(iso, f).nbytes for f in ("points", "border", "tol", "level", "step", "below",
                                                    "band", "offsets"))
        print(f"| (isolines held: {held / npx:.0f} B/px, {iso.points.shape[0] / npx:.2f} points/px) | | | | | | |")
    held = [iso]  # as encode_channel: each part goes after the stage that reads it last
    del iso
    grid = float(E.QUANT)  # as encode_channel: the chains on the file's grid, as float32
    stage("fit (reaches, then batches)",
          lambda: E.fit_first(held, opts.snap, budget.fit_batch_points(memory), grid, np.float32))
    stage("hierarchy", lambda: hierarchy.build_hierarchy_held(held, lev))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--image", default="corpus-wide/mosaic-16mp.png")
    ap.add_argument("--rows", type=int, default=1280)
    ap.add_argument("--cols", type=int, default=1600)
    ap.add_argument("--preset", default="balanced")
    ap.add_argument("--channel", default="Y", choices=("Y", "U", "V"))
    ap.add_argument("--memory", default=budget.DEFAULT_MEMORY)
    args = ap.parse_args(argv)
    img = read_image(args.image)
    a = np.asarray(img.pixels if hasattr(img, "pixels") else img)[: args.rows, : args.cols, :3]
    yuv = rgb_to_yuv(a.astype(np.float64))
    plane = np.ascontiguousarray(yuv[..., "YUV".index(args.channel)])
    del a, yuv, img
    opts = EncodeOptions(preset=args.preset).resolved()
    budget.return_freed_memory()  # as encode does
    memory = budget.parse_memory(args.memory)
    stages(plane[:128, :128].copy(), args.channel, opts, memory, False)  # kernels loaded
    print(f"{args.channel} of {plane.shape[1]}x{plane.shape[0]}, {args.preset}, memory {args.memory}\n")
    print("| stage | peak B/px | held after B/px | seconds | user s | system s | minor faults M |\n"
          "|---|---|---|---|---|---|---|")
    stages(plane, args.channel, opts, memory, True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
