"""Batch throughput: a camera pan over a wide-corpus photograph, delivered to every size.

    .venv/bin/python benchmarks/batch.py [--image PATH] [--frames 48] [--window 1280x720]
        [--deliver sd,hd,uhd,phone] [--configs pool1,pool2,pool2-pinned,dask2]

A FRAMES-frame sequence is cut from the photograph by panning a WINDOW across it (left to
right, vertically centred), written as PNG (lossless: each frame is exactly its crop), then
the same batch runs once per configuration, in one run, each into a fresh folder:

    pool1         our process pool, 1 worker
    pool2         our process pool, 2 workers
    pool2-pinned  2 workers, each on a processor of its own (--single-thread)
    dask2         a distributed.LocalCluster of 2 worker processes, 1 thread each

It reports input megapixels a second, the scaling against pool1, the processor seconds
the workers spent on the items (each item's cpu_seconds in the manifest) and their ratio
to the wall-clock (the processors in use), and
checks that every configuration wrote the same bytes. Results: benchmarks/results/batch.md.
"""

from __future__ import annotations

import argparse
import glob
import hashlib
import os
import json
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "src"))

import isophote  # noqa: E402
from isophote.imageio import read_image, write_image  # noqa: E402


def make_frames(image, folder, frames, win_w, win_h):
    px = read_image(image).pixels
    h, w = px.shape[:2]
    if win_w > w or win_h > h:
        raise SystemExit(f"{image} is {w}x{h}, smaller than the {win_w}x{win_h} window")
    y = (h - win_h) // 2
    for i in range(frames):
        x = round(i * (w - win_w) / max(1, frames - 1))
        write_image(os.path.join(folder, f"frame_{i + 1}.png"), px[y : y + win_h, x : x + win_w])


def digest(outdir):
    h = hashlib.sha256()
    for p in sorted(glob.glob(os.path.join(outdir, "**", "*.*"), recursive=True)):
        if not p.endswith("manifest.json"):
            h.update(os.path.relpath(p, outdir).encode())
            h.update(open(p, "rb").read())
    return h.hexdigest()[:16]


def items_cpu(outdir):
    """The workers' processor seconds over their items (each item's cpu_seconds)."""
    items = json.load(open(os.path.join(outdir, "manifest.json")))["items"]
    return sum(r.get("cpu_seconds", 0.0) for r in items.values())


def run_config(name, frames_dir, outdir, deliver, preset):
    kw = dict(deliver=deliver, preset=preset, progress=False)
    t0 = time.perf_counter()
    if name.startswith("dask"):
        from distributed import Client, LocalCluster

        with LocalCluster(n_workers=int(name[4:]), threads_per_worker=1, processes=True,
                          dashboard_address=None) as cluster, Client(cluster) as client:
            t0 = time.perf_counter()  # the cluster's start is not the batch's
            s = isophote.batch([frames_dir], outdir, executor=client.get_executor(), **kw)
            wall = time.perf_counter() - t0
    else:
        workers = int(name[4:].split("-")[0])
        s = isophote.batch([frames_dir], outdir, workers=workers, pin=name.endswith("pinned"), **kw)
        wall = time.perf_counter() - t0
    cpu = items_cpu(outdir)
    if s.failed:
        raise SystemExit(f"{name}: {len(s.failed)} items failed: {s.failed}")
    return dict(name=name, wall=wall, cpu=cpu, mp=s.megapixels, digest=digest(outdir))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--image", default="corpus-wide/photo-4mp/Path.jpg")
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--window", default="1280x720")
    ap.add_argument("--deliver", default="sd,hd,uhd,phone")
    ap.add_argument("--preset", default=None)
    ap.add_argument("--configs", default="pool1,pool2,pool2-pinned,dask2")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "batch.md"))
    args = ap.parse_args(argv)
    win_w, win_h = (int(v) for v in args.window.lower().split("x"))
    rows = []
    with tempfile.TemporaryDirectory(prefix="isophote-batch-bench-") as tmp:
        frames_dir = os.path.join(tmp, "frames")
        os.makedirs(frames_dir)
        make_frames(args.image, frames_dir, args.frames, win_w, win_h)
        for name in args.configs.split(","):
            row = run_config(name, frames_dir, os.path.join(tmp, name), args.deliver, args.preset)
            rows.append(row)
            print(f"{name}: {row['mp'] / row['wall']:.3f} MP/s, {row['wall']:.1f} s, {row['cpu']:.1f} CPU s",
                  flush=True)
    base = rows[0]["mp"] / rows[0]["wall"]
    same = len({r["digest"] for r in rows}) == 1
    lines = [
        "# Batch throughput",
        "",
        f"`benchmarks/batch.py --frames {args.frames} --window {args.window} --deliver {args.deliver}`: "
        f"{args.frames} frames of {win_w}x{win_h} panned across `{os.path.basename(args.image)}`, "
        f"preset {args.preset or 'balanced'}; {os.cpu_count()} processors; load average at the end "
        f"{os.getloadavg()[0]:.1f}.",
        "",
        "| configuration | MP/s (input) | x pool1 | wall s | worker CPU s | CPU s / item | processors busy |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        mps = r["mp"] / r["wall"]
        lines.append(f"| {r['name']} | {mps:.3f} | {mps / base:.2f} | {r['wall']:.1f} | {r['cpu']:.1f} | "
                     f"{r['cpu'] / args.frames:.1f} | {r['cpu'] / r['wall']:.2f} |")
    lines += ["", f"Same bytes in every configuration: {'yes' if same else 'NO'} "
                  f"({', '.join(sorted({r['digest'] for r in rows}))})."]
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
