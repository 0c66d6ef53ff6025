"""Load on `isophote serve`: a bounded loopback client against a real uvicorn server.

For each master: start `isophote serve MASTER --port P` as its own process, then ask for N
distinct IIIF tiles (256 px, the viewer's pyramid, zoom 1:8 to 8:1, levels equally often,
shuffled with a fixed seed), C at a time, from a cold cache; then the same N again (warm).
The server prepares the pyramid at start (render/prepare.py; --no-prepare: each level's
first tile does) and the cold pass starts once its /stats says it is done. Reports
p50/p95/p99 latency, 503s, the server's cache hit rate, its processor time in the cold pass
and its peak RSS; and, in
process, the time of one tile at each zoom against a peer measured in the same run (Pillow:
crop the original raster's region and resize it with Lanczos to the tile, as a raster tile
server would), which shows what bounds the latency zoom by zoom (benchmarks/results/render_scale.md
has where a render's time goes).

    python benchmarks/serve_load.py MASTER.isoph[=ORIGINAL] ... [--tiles 500] [--concurrency 4]

Results: benchmarks/results/serve_load.md.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import random
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "src"))

from isophote.serve import dzi  # noqa: E402
from isophote.serve.page import ZOOM  # noqa: E402
from isophote.serve.tiles import load_master, render_tile  # noqa: E402

ZOOMS = (1 / 8, 1 / 4, 1 / 2, 1, 2, 4, 8)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def level_of(m, zoom: float) -> int:
    """The viewer pyramid's level showing zoom output pixels per source pixel."""
    return dzi.top_level(m.width, m.height, ZOOM) - int(round(np.log2(ZOOM / zoom)))


def tile_url(m, level, col, row) -> str:
    (x, y, w, h), (ow, oh) = dzi.tile_region(m.width, m.height, ZOOM, level, col, row)
    up = "^" if ow > w else ""
    return f"/iiif/{m.id}/{x},{y},{w},{h}/{up}{ow},{oh}/0/default.png"


def sample_tiles(m, n: int, seed: int = 0) -> list:
    """n distinct tile URLs, levels 1:8 .. 8:1 about equally often."""
    rng = random.Random(seed)
    per_level = {}
    for z in ZOOMS:
        level = level_of(m, z)
        lw, lh = dzi.level_size(m.width, m.height, ZOOM, level)
        cells = [(level, c, r) for r in range(-(-lh // dzi.TILE)) for c in range(-(-lw // dzi.TILE))]
        rng.shuffle(cells)
        per_level[z] = cells
    chosen = []
    while len(chosen) < n and any(per_level.values()):
        for z in ZOOMS:
            if per_level[z] and len(chosen) < n:
                chosen.append(per_level[z].pop())
    rng.shuffle(chosen)
    return [(lev, tile_url(m, lev, c, r)) for lev, c, r in chosen]


async def run_client(base: str, urls: list, concurrency: int):
    import httpx

    queue = list(enumerate(urls))
    lat = [None] * len(urls)
    busy = 0

    async def worker(client):
        nonlocal busy
        while queue:
            i, url = queue.pop(0)
            t0 = time.perf_counter()
            while True:
                r = await client.get(url)
                if r.status_code != 503:
                    break
                busy += 1
                await asyncio.sleep(float(r.headers.get("retry-after", "1")))
            if r.status_code != 200:
                raise RuntimeError(f"{url}: {r.status_code} {r.text.strip()}")
            lat[i] = time.perf_counter() - t0

    async with httpx.AsyncClient(base_url=base, timeout=600) as client:
        t0 = time.perf_counter()
        await asyncio.gather(*(worker(client) for _ in range(concurrency)))
        wall = time.perf_counter() - t0
        stats = (await client.get("/stats")).json()
    return np.array(lat), busy, wall, stats


def peak_rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def serve(master: str, port: int, cache_mb: int, prepare: bool = True):
    """Start the server; with ``prepare`` wait until it has prepared the pyramid (its /stats
    says so). Returns (process, seconds from start to ready, the server's preparation
    seconds or None)."""
    env = dict(os.environ, PYTHONPATH=str(HERE.parent / "src"))
    t0 = time.perf_counter()
    p = subprocess.Popen([sys.executable, "-m", "isophote", "serve", master, "--port", str(port), "--quiet",
                          "--cache-mb", str(cache_mb)] + ([] if prepare else ["--no-prepare"]), env=env)
    import httpx

    for _ in range(3000):
        try:
            st = httpx.get(f"http://127.0.0.1:{port}/stats", timeout=1).json()
            if st.get("prepare_error"):
                raise RuntimeError(st["prepare_error"])
            if not prepare or st.get("prepared") == st.get("masters"):
                return p, time.perf_counter() - t0, st.get("prepare_s")
        except httpx.HTTPError:
            pass
        time.sleep(0.2)
    p.kill()
    raise RuntimeError("the server did not start")


def cpu_seconds(pid: int) -> float:
    """User + system processor seconds of a process so far."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def one_tile_each_zoom(m, original, zooms=ZOOMS, warm=True):
    """Seconds for one tile at each zoom, in process (numba warmed first), and the peer's."""
    from PIL import Image

    im = Image.open(original).convert("RGB") if original else None
    if warm:  # numba's kernels load (on a large master this costs a full grid: skip it there)
        render_tile(m, (0, 0, 8, 8), (8, 8))
    rows = []
    for z in zooms:
        level = level_of(m, z)
        lw, lh = dzi.level_size(m.width, m.height, ZOOM, level)
        col, row = (lw // dzi.TILE) // 2, (lh // dzi.TILE) // 2
        region, size = dzi.tile_region(m.width, m.height, ZOOM, level, col, row)
        t0 = time.perf_counter()
        render_tile(m, region, size)
        t_tile = time.perf_counter() - t0
        t_peer = float("nan")
        if im is not None:
            x, y, w, h = region
            t0 = time.perf_counter()
            im.crop((x, y, x + w, y + h)).resize(size, Image.LANCZOS)
            t_peer = time.perf_counter() - t0
        rows.append((z, region, size, t_tile, t_peer))
    return rows


def pct(a, q) -> float:
    return float(np.percentile(a, q)) * 1000


def single_tiles(rows, title: str) -> list:
    """The table of one_tile_each_zoom's rows, headed by ``title``."""
    lines = [f"{title}, against the peer in the same run (Pillow crop + Lanczos of the original raster):", "",
             "| zoom | region | tile px | render s | peer s | ratio |", "|---:|---|---|---:|---:|---:|"]
    for z, region, size, t, tp in rows:
        lines.append(f"| {z:g} | {region[2]}x{region[3]} | {size[0]}x{size[1]} | {t:.3f} | {tp:.4f} | {t / tp:.0f} |")
    return lines + [""]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("masters", nargs="+", metavar="MASTER.isoph[=ORIGINAL]")
    ap.add_argument("--tiles", type=int, default=500)
    ap.add_argument("--concurrency", type=int, default=4)
    ap.add_argument("--cache-mb", type=int, default=256)
    ap.add_argument("--warm-ups", type=int, default=3, choices=(1, 2, 3),
                    help="requests outside the sample before the cold pass (numba's kernels load)")
    ap.add_argument("--single-zooms", default=",".join(f"{z:g}" for z in ZOOMS),
                    help="zooms of the in-process one-tile timings")
    ap.add_argument("--out", default=str(HERE / "results" / "serve_load.md"))
    ap.add_argument("--append", action="store_true", help="add the masters' sections to --out")
    ap.add_argument("--single-only", action="store_true",
                    help="only the in-process one-tile timings (for a master whose load pass cannot fit)")
    ap.add_argument("--no-prepare", dest="prepare", action="store_false",
                    help="start the server with --no-prepare (each level's first tile prepares it)")
    args = ap.parse_args()
    singles = tuple(float(v) for v in args.single_zooms.split(","))

    lines = ["# serve_load: tile latency of `isophote serve` under a bounded loopback client", "",
             f"{args.tiles} distinct 256-px IIIF tiles a master (zoom 1:8 to 8:1, levels equally often), "
             f"{args.concurrency} requests at a time, against `isophote serve` in its own process "
             f"({len(os.sched_getaffinity(0))} cores, render pool = cores, queue 4 x cores, "
             f"cache {args.cache_mb} MiB, {'pyramid prepared at start' if args.prepare else '--no-prepare'}); "
             f"cold = first pass (tile cache empty), warm = the same tiles again. {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, "
             f"machine load average at start: {os.getloadavg()[0]:.1f} (shared machine: timings are noisy).", ""]
    for spec in args.masters:
        path, _, original = spec.partition("=")
        m = load_master(path)
        print(f"{m.id}: {m.width}x{m.height}", flush=True)
        if args.single_only:
            import resource

            rows = one_tile_each_zoom(m, original or None, singles, warm=False)
            rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
            lines += [f"## {m.id}: {m.width} x {m.height} ({m.width * m.height / 1e6:.1f} MP), one tile at a time", ""]
            lines += single_tiles(rows, f"One tile at each zoom, in process, one render at a time (peak RSS {rss:.0f} MB)")
            print("\n".join(lines[-12:]), flush=True)
            continue
        urls = sample_tiles(m, args.tiles)
        port = free_port()
        server, ready_s, prep_s = serve(path, port, args.cache_mb, args.prepare)
        try:
            import httpx

            for warm_up in (f"/iiif/{m.id}/0,0,8,8/8,8/0/default.png", f"/iiif/{m.id}/0,0,8,8/^32,32/0/default.png",
                            f"/iiif/{m.id}/0,0,16,16/8,8/0/default.png")[:args.warm_ups]:  # outside the sample
                httpx.get(f"http://127.0.0.1:{port}{warm_up}", timeout=600).raise_for_status()
            cpu0, load0 = cpu_seconds(server.pid), os.getloadavg()[0]
            cold, busy_c, wall_c, s1 = asyncio.run(run_client(f"http://127.0.0.1:{port}", [u for _, u in urls],
                                                              args.concurrency))
            cpu1, load1 = cpu_seconds(server.pid), os.getloadavg()[0]
            warm, busy_w, wall_w, s2 = asyncio.run(run_client(f"http://127.0.0.1:{port}", [u for _, u in urls],
                                                              args.concurrency))
            rss = peak_rss_mb(server.pid)
        finally:
            server.terminate()
            server.wait(30)
        levels = np.array([lev for lev, _ in urls])
        lines += [f"## {m.id}: {m.width} x {m.height} ({m.width * m.height / 1e6:.1f} MP)", "",
                  "| pass | tiles | p50 ms | p95 ms | p99 ms | max ms | 503s | wall s | cache hits so far |",
                  "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for name, lat, busy, wall, st in (("cold", cold, busy_c, wall_c, s1), ("warm", warm, busy_w, wall_w, s2)):
            lines.append(f"| {name} | {len(lat)} | {pct(lat, 50):.0f} | {pct(lat, 95):.0f} | {pct(lat, 99):.0f} | "
                         f"{lat.max() * 1000:.0f} | {busy} | {wall:.1f} | {st['hits']}/{st['hits'] + st['misses'] - args.warm_ups} |")
        total = s2["hits"] + s2["misses"] - args.warm_ups
        prep = f"preparation {prep_s:.1f} s (ready {ready_s:.1f} s after start)" if prep_s is not None else \
            f"ready {ready_s:.1f} s after start"
        lines += ["", f"Cache hit rate over both passes: {s2['hits'] / total:.1%} "
                  f"(cache holds {s2['bytes'] / 2**20:.1f} MiB in {s2['entries']} tiles); server peak RSS {rss:.0f} MB; "
                  f"{prep}; {s1['workers']} render workers. Cold pass: the server's processor time "
                  f"{cpu1 - cpu0:.1f} s ({(cpu1 - cpu0) / len(cold) * 1000:.0f} ms a tile), load average "
                  f"{load0:.1f} -> {load1:.1f}.", "",
                  "Cold latency by zoom (ms, p50 / p95):", ""]
        for z in ZOOMS:
            sel = cold[levels == level_of(m, z)]
            if len(sel):
                lines.append(f"- {z:g}x: {pct(sel, 50):.0f} / {pct(sel, 95):.0f} ({len(sel)} tiles)")
        title = "One tile at each zoom, in process (s)"
        if args.prepare:
            from isophote.serve.tiles import prepare_master

            title += f", after the pyramid's preparation ({prepare_master(m, ZOOM):.1f} s in process)"
        rows = one_tile_each_zoom(m, original or None, singles, warm=args.warm_ups > 1)
        lines += [""] + single_tiles(rows, title)
        print("\n".join(lines[-30:]), flush=True)
    if args.append:
        lines = lines[lines.index("") + 1:]  # the sections only
        lines = lines[lines.index("") + 1:]
        with open(args.out, "a") as f:
            f.write("\n".join(lines) + "\n")
    else:
        Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
