"""Render cost against output size on a big master (issue 22's renderer targets).

One run measures, each case in a fresh subprocess (peak RSS = that process's ru_maxrss):
Pillow's PNG decode + Lanczos resize of the original to 3840 x 2400 and to 960 wide, and
isophote's load (compact, as `isophote render` and the server load) + render of the master to
the same sizes and at 1x; then, in one process,
the preparation and N random 256 x 256 tiles over zooms 1:64 .. 8:1 (powers of two, tiles
on each zoom's grid), with p50/p95/p99. Ratios are against Pillow measured in the same run
(the machine is shared: absolute times are noisy).

    python benchmarks/render_scale.py [--master M.isoph] [--original O.png] [--tiles 500]

Writes benchmarks/results/render_scale.md.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
RESULTS = os.path.join(HERE, "results", "render_scale.md")

CHILD = r"""
import json, resource, sys, time
case = json.loads(sys.argv[1])
t0 = time.perf_counter()
if case["kind"] == "pillow":
    from PIL import Image
    im = Image.open(case["original"]); im.load()
    t1 = time.perf_counter()
    w = case["width"]; h = case.get("height") or round(im.height * w / im.width)
    out = im.resize((w, h), Image.LANCZOS)
    t2 = time.perf_counter()
    res = dict(load=t1 - t0, work=t2 - t1, shape=[h, w])
elif case["kind"] == "render":
    import isophote
    vi = isophote.load(case["master"], compact=True)  # as isophote render and the server load it
    t1 = time.perf_counter()
    out = vi.render(**case["options"])
    t2 = time.perf_counter()
    res = dict(load=t1 - t0, work=t2 - t1, shape=list(out.shape[:2]))
else:
    import random
    import numpy as np
    import isophote
    from isophote.render.tiles import Tiler
    vi = isophote.load(case["master"], compact=True)  # as isophote render and the server load it
    zooms = [2.0 ** k for k in range(-6, 4)]
    t1 = time.perf_counter()
    tiler = Tiler(vi, zooms=zooms)  # every zoom the tiles ask for
    t2 = time.perf_counter()
    rng = random.Random(22)
    times = {}
    for _ in range(case["tiles"]):
        z = rng.choice(zooms)
        span = 256 / z
        nx, ny = max(1, -(-vi.width // span)), max(1, -(-vi.height // span))
        i, j = rng.randrange(int(nx)), rng.randrange(int(ny))
        x, y = i * span, j * span
        w, h = min(span, vi.width - x), min(span, vi.height - y)
        ow, oh = max(1, round(w * z)), max(1, round(h * z))
        ts = time.perf_counter()
        tiler.tile(x, y, w, h, ow, oh)
        times.setdefault(z, []).append(time.perf_counter() - ts)
    alls = sorted(t for v in times.values() for t in v)
    pct = lambda a, q: a[min(len(a) - 1, int(q * len(a)))]
    res = dict(load=t1 - t0, work=t2 - t1, p50=pct(alls, 0.5), p95=pct(alls, 0.95), p99=pct(alls, 0.99),
               by_zoom={str(z): [len(v), pct(sorted(v), 0.5), pct(sorted(v), 0.95)] for z, v in sorted(times.items())})
res["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps(res))
"""


def run(case: dict, timeout: float) -> dict:
    env = dict(os.environ)
    src = os.path.join(os.path.dirname(HERE), "src")
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    try:
        p = subprocess.run([sys.executable, "-c", CHILD, json.dumps(case)], capture_output=True, text=True,
                           timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return dict(error=f"over {timeout:.0f} s")
    if p.returncode != 0:
        return dict(error=(p.stderr.strip().splitlines() or ["failed"])[-1])
    return json.loads(p.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--master", default="corpus-wide/masters/mosaic-16mp.isoph")
    ap.add_argument("--original", default="corpus-wide/mosaic-16mp.png")
    ap.add_argument("--tiles", type=int, default=500)
    ap.add_argument("--timeout", type=float, default=900)
    ap.add_argument("--skip", default="", help="comma-separated cases to skip (sizes, 1x, tiles)")
    ap.add_argument("--sizes", choices=("mosaic", "proportional"), default="mosaic",
                    help="the mosaic's output sizes, or the same scales of the master given")
    ap.add_argument("--out", default=RESULTS)
    args = ap.parse_args(argv)
    skip = set(filter(None, args.skip.split(",")))
    rows = []
    sizes = [("3840x2400", 3840, 2400), ("960 wide", 960, None)]
    if args.sizes == "proportional":  # the same reductions of a smaller master (0.75 and 0.1875 of its width)
        from PIL import Image

        w0, h0 = Image.open(args.original).size
        sizes = [(f"{round(w0 * 0.75)}x{round(h0 * 0.75)}", round(w0 * 0.75), round(h0 * 0.75)),
                 (f"{round(w0 * 0.1875)} wide", round(w0 * 0.1875), None)]
    for name, width, height in ([] if "sizes" in skip else sizes):
        opts = dict(width=width, height=height) if height else dict(width=width)
        pil = run(dict(kind="pillow", original=args.original, width=width, height=height), args.timeout)
        ren = run(dict(kind="render", master=args.master, options=opts), args.timeout)
        rows.append((name, pil, ren))
        print(name, pil, ren, flush=True)
    one = None if "1x" in skip else run(dict(kind="render", master=args.master, options={}), args.timeout)
    print("1x", one, flush=True)
    tiles = None if "tiles" in skip else run(dict(kind="tiles", master=args.master, tiles=args.tiles), args.timeout)
    print("tiles", tiles, flush=True)

    def f(d, k, fmt="{:.2f}"):
        return fmt.format(d[k]) if d and k in d else (d or {}).get("error", "-")

    lines = ["# Render cost against output size (issue 22)", "",
             f"Master `{os.path.basename(args.master)}`, original `{os.path.basename(args.original)}`; "
             f"`python benchmarks/render_scale.py`, {time.strftime('%Y-%m-%d')}. Each case a fresh process; "
             "times in seconds (load = file decode, work = resize or render), peak = the process's peak RSS.", "",
             "| output | Pillow decode | Lanczos | Pillow total | peak MB | isophote load | render | "
             "render / Pillow total | (load+render) / Pillow | peak MB |", "|---|---|---|---|---|---|---|---|---|---|"]
    for name, pil, ren in rows:
        ratio = ratio2 = "-"
        if "work" in pil and "work" in ren:
            tot = pil["load"] + pil["work"]
            ratio, ratio2 = f"{ren['work'] / tot:.1f}", f"{(ren['load'] + ren['work']) / tot:.1f}"
        lines.append(f"| {name} | {f(pil, 'load')} | {f(pil, 'work')} | "
                     f"{(pil['load'] + pil['work']) if 'work' in pil else '-':.4} | {f(pil, 'peak_mb', '{:.0f}')} | "
                     f"{f(ren, 'load')} | {f(ren, 'work')} | {ratio} | {ratio2} | {f(ren, 'peak_mb', '{:.0f}')} |")
    if one:
        mp = one["shape"][0] * one["shape"][1] / 1e6 if "shape" in one else 1.0
        lines += ["", f"1x render: load {f(one, 'load')} s, render {f(one, 'work')} s "
                  f"({one['work'] / mp:.2f} s/MP)" if "work" in one else f"1x render: {one.get('error')}",
                  f"peak {f(one, 'peak_mb', '{:.0f}')} MB."]
    if tiles:
        lines += ["", f"Tiles ({args.tiles} random 256 x 256, zooms 1:64 .. 8:1): preparation "
                  f"{f(tiles, 'work')} s, p50 {f(tiles, 'p50', '{:.3f}')} s, p95 {f(tiles, 'p95', '{:.3f}')} s, "
                  f"p99 {f(tiles, 'p99', '{:.3f}')} s, peak {f(tiles, 'peak_mb', '{:.0f}')} MB.", "",
                  "| zoom | tiles | p50 s | p95 s |", "|---|---|---|---|"]
        for z, (n, p50, p95) in (tiles.get("by_zoom") or {}).items():
            lines.append(f"| {float(z):g} | {n} | {p50:.3f} | {p95:.3f} |")
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as fh:
        fh.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
