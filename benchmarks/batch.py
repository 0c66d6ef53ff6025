"""Batch throughput: a camera pan over a wide-corpus photograph, delivered to every size.

    .venv/bin/python benchmarks/batch.py [--image PATH] [--frames 48] [--window 1280x720]
        [--deliver sd,hd,uhd,phone] [--configs pool1,pool2,dask2] [--repeat 1] [--ceiling]

A FRAMES-frame sequence is cut from the photograph by panning a WINDOW across it (left to
right, vertically centred), written as PNG (lossless: each frame is exactly its crop), then
the same batch runs once per configuration and repeat, in one run, each into a fresh folder
and in a fresh process (each pays its own start-up: the pool's fork server loading the
compiled kernels, or the Dask workers loading them on their first item):

    pool1          our process pool, 1 worker (its items use the machine's processors)
    pool1-1thread  1 worker, its items on one thread (exactly one processor: the unit
                   the 2-worker configurations multiply)
    pool2          our process pool, 2 workers (items on one thread each on 2 processors)
    pool2-pinned   2 workers, each pinned to a processor of its own (--single-thread)
    dask2          a distributed.LocalCluster of 2 worker processes, 1 thread each (the
                   cluster's own start is not counted: a real cluster is already up)

--ceiling adds the machine's own ceiling for this work: one item (the middle frame, one
thread) run alone, then two copies of it side by side in two processes; their slow-down
together is what memory bandwidth and shared caches cost, with no batch involved.

It reports, per run: input megapixels a second; the scaling against pool1 and
pool1-1thread; the workers' processor seconds on their items (each item's cpu_seconds) and
the processors that kept busy; the parent's own processor seconds; the start-up (the batch's
start to the first item's); the workers' idle gaps between items and the tail (the end of
the batch after the first worker ran out of items); the time one-thread items waited for a
processor that other work on the machine held (run_queue_seconds), and the throughput with
those waits taken out; the load average. It checks that every run wrote the same bytes.
Results: benchmarks/results/batch.md.
"""

from __future__ import annotations

import argparse
import glob
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.path.join(HERE, "..", "src")
sys.path.insert(0, SRC)


def make_frames(image, folder, frames, win_w, win_h):
    from isophote.imageio import read_image, write_image

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


# =============================================================================================
# One configuration, in a process of its own (--one NAME FRAMES OUTDIR DELIVER PRESET)
# =============================================================================================


def run_one(name, frames_dir, outdir, deliver, preset):
    import resource

    import isophote

    kw = dict(deliver=deliver, preset=None if preset == "-" else preset, progress=False)
    load0 = os.getloadavg()[0]
    cluster = client = None
    if name.startswith("dask"):
        from distributed import Client, LocalCluster

        cluster = LocalCluster(n_workers=int(name[4:]), threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
        kw["executor"] = client.get_executor()
    else:
        kw["workers"] = int(name[4:].split("-")[0])
        kw["pin"] = name.endswith("-pinned")
        kw["item_threads"] = 1 if name.endswith("-1thread") else None
    r0, t0, w0 = resource.getrusage(resource.RUSAGE_SELF), time.time(), time.perf_counter()
    s = isophote.batch([frames_dir], outdir, **kw)
    wall, t1, r1 = time.perf_counter() - w0, time.time(), resource.getrusage(resource.RUSAGE_SELF)
    if client is not None:
        client.close()
        cluster.close()
    if s.failed:
        raise SystemExit(f"{name}: {len(s.failed)} items failed: {s.failed}")
    items = json.load(open(os.path.join(outdir, "manifest.json")))["items"]
    parent = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    out = dict(name=name, wall=wall, mp=s.megapixels, digest=digest(outdir), parent_cpu=parent,
               load=(load0, os.getloadavg()[0]), **timeline(items.values(), t0, t1))
    print(json.dumps(out))


def timeline(items, t0, t1):
    """Per worker: its items in order; the start-up, gaps, tail and waits of the run."""
    lanes = {}
    for r in items:
        lanes.setdefault(r.get("worker", "?"), []).append(r)
    firsts, gaps, lasts, waits = [], 0.0, [], {}
    for w, rs in lanes.items():
        rs.sort(key=lambda r: r["started"])
        firsts.append(rs[0]["started"] - t0)
        gaps += sum(b["started"] - a["finished"] for a, b in zip(rs, rs[1:]))
        lasts.append(rs[-1]["finished"])
        waits[w] = sum(r.get("run_queue_seconds") or 0.0 for r in rs)
    items = list(items)
    one_thread = all(r.get("run_queue_seconds") is not None for r in items)
    # with the waits taken out: each worker's lane ends sooner by its own waits
    ends = [r[-1]["finished"] - waits[w] for w, r in lanes.items()]
    phases = {"encode": sum(r["master"]["seconds"] for r in items)}
    for r in items:
        for name, o in r["outputs"].items():
            phases[name] = phases.get(name, 0.0) + o["seconds"]
    return dict(
        items=len(items), workers=len(lanes), cpu=sum(r.get("cpu_seconds", 0.0) for r in items),
        item_wall=sum(r["seconds"] for r in items), startup=(min(firsts), max(firsts)), gaps=gaps,
        tail=t1 - min(lasts), run_queue=sum(waits.values()) if one_thread else None,
        wall_unloaded=(max(ends) - t0 + (t1 - max(lasts))) if one_thread else None,
        threads=sorted({r.get("threads") for r in items}), phases=phases)


# =============================================================================================
# The machine's ceiling: one item alone, then two copies side by side (--item FRAME OUTDIR)
# =============================================================================================


def run_item(frame, outdir, deliver, preset):
    import isophote.batch._warm  # noqa: F401 - the kernels load before the clock starts
    from isophote.batch import run as R
    from isophote.batch.item import process

    jobs, _, _ = R.plan([frame], outdir, deliver, preset=None if preset == "-" else preset, encode=None,
                        format="png", depth=8, fit="pad", pad=(0, 0, 0), metrics=False)
    job = dict(jobs[0], threads=1)
    t = time.perf_counter()
    r = process(job)
    print(json.dumps(dict(wall=time.perf_counter() - t, cpu=r["cpu_seconds"], run_queue=r["run_queue_seconds"])))


def ceiling(frame, tmp, deliver, preset, env):
    def start(k):
        d = os.path.join(tmp, f"ceiling-{k}")
        os.makedirs(d, exist_ok=True)
        return subprocess.Popen([sys.executable, __file__, "--item", frame, d, deliver, preset],
                                stdout=subprocess.PIPE, text=True, env=env)

    load0 = os.getloadavg()[0]
    alone = json.loads(start("alone").communicate()[0])
    pair = [p.communicate()[0] for p in [start("a"), start("b")]]
    pair = [json.loads(p) for p in pair]
    return dict(alone=alone, pair=pair, load=(load0, os.getloadavg()[0]))


# =============================================================================================
# The report
# =============================================================================================


def _f(v, fmt):
    return "-" if v is None else format(v, fmt)


def report(args, runs, ceil, win_w, win_h, started):
    def mps(r):
        return r["mp"] / r["wall"]

    def mean(name, key=mps):
        vals = [key(r) for r in runs if r["name"] == name]
        return statistics.mean(vals) if vals else None

    names = list(dict.fromkeys(r["name"] for r in runs))
    base1, base1t = mean("pool1"), mean("pool1-1thread")
    same = len({r["digest"] for r in runs}) == 1
    lines = [
        "# Batch throughput",
        "",
        f"`benchmarks/batch.py --frames {args.frames} --window {args.window} --deliver {args.deliver} "
        f"--configs {args.configs} --repeat {args.repeat}{' --ceiling' if args.ceiling else ''}`: "
        f"{args.frames} frames of {win_w}x{win_h} panned across `{os.path.basename(args.image)}`, preset "
        f"{args.preset or 'balanced'}; {os.cpu_count()} processors; started {started} UTC, "
        f"{(time.time() - args.t_start) / 60:.0f} min in all.",
        "",
        "Every run, in the order run (MP/s of input; `x pool1` against the mean of the pool1 runs; "
        "`unloaded` = with the time one-thread items waited for a processor taken out):",
        "",
        "| run | MP/s | x pool1 | x pool1-1thread | wall s | item CPU s | CPU s / item | processors busy "
        "| parent CPU s | start-up s | gaps s | tail s | run-queue s | MP/s unloaded | load avg |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        un = r["mp"] / r["wall_unloaded"] if r.get("wall_unloaded") else None
        lines.append(
            f"| {r['name']} | {mps(r):.4f} | {_f(base1 and mps(r) / base1, '.2f')} | "
            f"{_f(base1t and mps(r) / base1t, '.2f')} | {r['wall']:.1f} | {r['cpu']:.1f} | "
            f"{r['cpu'] / r['items']:.1f} | {r['cpu'] / r['wall']:.2f} | {r['parent_cpu']:.2f} | "
            f"{r['startup'][0]:.1f}-{r['startup'][1]:.1f} | {r['gaps']:.2f} | {r['tail']:.1f} | {_f(r['run_queue'], '.1f')} | "
            f"{_f(un, '.4f')} | {r['load'][0]:.1f}-{r['load'][1]:.1f} |")
    lines += ["", "Per configuration (mean, and the spread min-max of MP/s over its runs):", "",
              "| configuration | runs | MP/s | spread | x pool1 | x pool1-1thread | CPU s / item |",
              "|---|---|---|---|---|---|---|"]
    for n in names:
        vals = [mps(r) for r in runs if r["name"] == n]
        m = statistics.mean(vals)
        cpi = mean(n, lambda r: r["cpu"] / r["items"])
        lines.append(f"| {n} | {len(vals)} | {m:.4f} | {min(vals):.4f}-{max(vals):.4f} | "
                     f"{_f(base1 and m / base1, '.2f')} | {_f(base1t and m / base1t, '.2f')} | {cpi:.1f} |")
    r0 = runs[0]
    lines += ["", "Where an item's time goes (the first run; seconds of its worker's wall-clock, all items): "
              + ", ".join(f"{k} {v:.0f}" for k, v in r0["phases"].items())
              + " (each delivery: render, write, hash)."]
    if ceil:
        a, p = ceil["alone"], ceil["pair"]

        def unl(x):
            return x["wall"] - x["run_queue"]

        ratio = 2 * unl(a) / max(unl(x) for x in p)
        lines += ["", "The machine's ceiling (one item, one thread: the middle frame to every delivery):", "",
                  "| run | wall s | CPU s | run-queue s | wall s unloaded |", "|---|---|---|---|---|",
                  f"| alone | {a['wall']:.1f} | {a['cpu']:.1f} | {a['run_queue']:.1f} | {unl(a):.1f} |"]
        lines += [f"| side by side {k + 1} | {x['wall']:.1f} | {x['cpu']:.1f} | {x['run_queue']:.1f} | "
                  f"{unl(x):.1f} |" for k, x in enumerate(p)]
        lines += ["", f"Two copies side by side do {ratio:.2f}x the work of one alone in the same time "
                  f"(unloaded walls; by processor seconds {2 * a['cpu'] / max(x['cpu'] for x in p):.2f}x); "
                  f"load average {ceil['load'][0]:.1f}-{ceil['load'][1]:.1f}."]
    lines += ["", f"Same bytes in every run: {'yes' if same else 'NO'} "
                  f"({', '.join(sorted({r['digest'] for r in runs}))})."]
    return lines, same


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--one"]:
        return run_one(*argv[1:6])
    if argv[:1] == ["--item"]:
        return run_item(*argv[1:5])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--image", default="corpus-wide/photo-4mp/Path.jpg")
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--window", default="1280x720")
    ap.add_argument("--deliver", default="sd,hd,uhd,phone")
    ap.add_argument("--preset", default=None)
    ap.add_argument("--configs", default="pool1,pool2,dask2")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each configuration (interleaved)")
    ap.add_argument("--ceiling", action="store_true", help="also one item alone and two side by side")
    ap.add_argument("--out", default=os.path.join(HERE, "results", "batch.md"))
    args = ap.parse_args(argv)
    args.t_start = time.time()
    started = time.strftime("%Y-%m-%d %H:%M", time.gmtime())
    win_w, win_h = (int(v) for v in args.window.lower().split("x"))
    runs, ceil = [], None
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([SRC] + os.environ.get("PYTHONPATH", "").split(os.pathsep)))
    with tempfile.TemporaryDirectory(prefix="isophote-batch-bench-") as tmp:
        frames_dir = os.path.join(tmp, "frames")
        os.makedirs(frames_dir)
        make_frames(args.image, frames_dir, args.frames, win_w, win_h)
        for k in range(args.repeat):
            for name in args.configs.split(","):
                outdir = os.path.join(tmp, f"{name}-{k}")
                res = subprocess.run([sys.executable, __file__, "--one", name, frames_dir, outdir, args.deliver,
                                      args.preset or "-"], env=env, stdout=subprocess.PIPE, text=True, check=True)
                row = json.loads(res.stdout.strip().splitlines()[-1])
                runs.append(row)
                print(f"{name}: {row['mp'] / row['wall']:.4f} MP/s, {row['wall']:.1f} s, {row['cpu']:.1f} CPU s, "
                      f"load {row['load'][1]:.1f}", flush=True)
        if args.ceiling:
            middle = os.path.join(frames_dir, f"frame_{(args.frames + 1) // 2}.png")
            ceil = ceiling(middle, tmp, args.deliver, args.preset or "-", env)
    lines, same = report(args, runs, ceil, win_w, win_h, started)
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    with open(args.out, "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
