"""One batch item, as a worker runs it: read, encode (or reuse the master), render every
delivery that is missing or stale, write each output atomically, hash it.

:func:`process` is a plain top-level function of a plain dict, so any
``concurrent.futures.Executor`` can run it: a process pool here, a Dask cluster's workers
elsewhere (they need isophote installed and the same paths on shared storage).

Every delivery is rendered from the master as read back from its file, whether it was
encoded just now or by an earlier run: a delivery added to a finished batch has the bytes
it would have had in the first run.
"""

from __future__ import annotations

import hashlib
import math
import os
import signal
import socket
import time

from .. import threads
from ..errors import IsophoteError

# Test hook: "STEM:MARKER" in this environment variable of the batch's process (passed to
# the workers in the job, so any executor's workers see it) makes the worker that starts item STEM kill itself with SIGKILL,
# once (it creates the file MARKER first; while MARKER exists, nothing happens), or each
# time when MARKER is "-". The tests
# use it to check that a killed worker's item is retried and the batch completes.
KILL_HOOK = "ISOPHOTE_BATCH_TEST_KILL"


def sha256_file(path, chunk: int = 1 << 20) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while True:
            block = f.read(chunk)
            if not block:
                return h.hexdigest()
            h.update(block)


def _kill_hook(stem: str, spec) -> None:
    if not spec or ":" not in spec:
        return
    target, marker = spec.split(":", 1)
    if target != stem:
        return
    if marker == "-":  # every time
        os.kill(os.getpid(), signal.SIGKILL)
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return
    os.close(fd)
    os.kill(os.getpid(), signal.SIGKILL)


def _run_queue_seconds() -> float | None:
    """Seconds this thread has spent ready to run but waiting for a processor (other work
    on the machine took it): Linux's schedstat; None where unknown."""
    try:
        with open("/proc/thread-self/schedstat") as f:
            return int(f.read().split()[1]) / 1e9
    except (OSError, ValueError, IndexError):
        return None


def _file_entry(path: str, outdir: str, seconds: float, **extra) -> dict:
    return dict(path=os.path.relpath(path, outdir), sha256=sha256_file(path), bytes=os.path.getsize(path),
                seconds=round(seconds, 4), **extra)


def item_threads(job: dict) -> int | None:
    """Threads the item may use: ``threads`` where the batch fixed it; else this worker's
    share of its machine, the processors it may use over ``slots`` (the items its machine
    runs at once: one thread each on a machine with as many slots as processors); None
    (no limit) where neither is known."""
    if job.get("threads"):
        return int(job["threads"])
    if job.get("slots"):
        return max(1, threads.processors() // int(job["slots"]))
    return None


def process(job: dict) -> dict:
    """Run one item. ``job``: input, stem, outdir, encode (resolved EncodeOptions fields),
    need_master, outputs (a list of delivery specs: name, width, height, fit, pad, depth,
    format), metrics, and threads or slots (:func:`item_threads`). Returns the item's
    results: ``status`` "ok" with the master and the outputs written, or "failed" with a
    one-line ``reason`` (bad input, bad options, a write that failed). Anything else (a
    bug) propagates, and the batch records it."""
    _kill_hook(job["stem"], job.get("kill"))
    t0, started, cpu = time.perf_counter(), time.time(), time.process_time()
    n_threads = item_threads(job)
    waited = _run_queue_seconds()
    try:
        with threads.limited(n_threads):
            out = _process(job, t0)
        if waited is not None and n_threads == 1:  # then all of the item ran on this thread
            out["run_queue_seconds"] = round(_run_queue_seconds() - waited, 3)
        out["started"], out["finished"] = round(started, 3), round(time.time(), 3)  # Unix time
        out["worker"] = f"{socket.gethostname()}:{os.getpid()}"
        out["threads"] = n_threads or threads.processors()
        # the worker process's processor time over the item (all its threads; a worker that
        # runs items in threads of one process, as Dask's threads do, counts its neighbours')
        out["cpu_seconds"] = round(time.process_time() - cpu, 3)
        return out
    except IsophoteError as e:
        return dict(status="failed", reason=" ".join(str(e).split()), seconds=round(time.perf_counter() - t0, 4))
    except MemoryError:
        return dict(status="failed", reason="out of memory", seconds=round(time.perf_counter() - t0, 4))
    except OSError as e:
        where = f"{e.filename}: " if e.filename else ""
        return dict(status="failed", reason=f"{where}{e.strerror or e}", seconds=round(time.perf_counter() - t0, 4))


def _process(job: dict, t0: float) -> dict:
    from .. import load
    from ..imageio import read_image

    outdir, stem = job["outdir"], job["stem"]
    master_path = os.path.join(outdir, stem + ".isoph")
    out = dict(status="ok", outputs={})
    raster = None
    if job["need_master"] or job["metrics"]:
        raster = read_image(job["input"])
        out["input_sha256"] = sha256_file(job["input"])
    if job["need_master"]:
        out["master"] = _encode(raster, job, master_path, outdir)
    vi = load(master_path, compact=True)  # only rendered: float32 points, the same pixels
    out["width"], out["height"] = vi.width, vi.height
    for spec in job["outputs"]:
        out["outputs"][spec["name"]] = _deliver(vi, spec, outdir, stem)
    if job["metrics"]:
        out["metrics"] = _metrics(vi, raster)
    out["seconds"] = round(time.perf_counter() - t0, 4)
    return out


def _encode(raster, job, path, outdir) -> dict:
    from dataclasses import replace

    from ..encoder import encode_pixels
    from ..options import EncodeOptions

    t = time.perf_counter()
    opts = EncodeOptions(**{k: tuple(v) if isinstance(v, list) else v for k, v in job["encode"].items()})
    if raster.noise_floor is not None and opts.noise_floor is None:
        opts = replace(opts, noise_floor=raster.noise_floor)  # a JPEG's quantisation error, as `encode`
    vi = encode_pixels(raster.pixels, raster.depth, opts)
    vi.save(path)
    h, w = raster.pixels.shape[:2]
    return _file_entry(path, outdir, time.perf_counter() - t, width=w, height=h)


def _deliver(vi, spec: dict, outdir: str, stem: str) -> dict:
    from ..imageio import write_image
    from .deliveries import placement, render_delivery

    t = time.perf_counter()
    where = placement(vi.width, vi.height, spec["width"], spec["height"], spec["fit"])
    img = render_delivery(vi, where, depth=spec["depth"], pad=spec["pad"])
    folder = os.path.join(outdir, spec["name"])
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, f"{stem}.{spec['format']}")
    samples = img / 257.0 if spec["depth"] == 16 else img
    write_image(path, samples, depth=spec["depth"])
    return _file_entry(path, outdir, time.perf_counter() - t, width=spec["width"], height=spec["height"],
                       spec=spec)


def _metrics(vi, raster) -> dict:
    """PSNR and SSIMULACRA2 of the 1x render against the input (8-bit render, as `render
    --compare`); a metric that cannot run is reported as null with its reason."""
    import numpy as np

    from ..metrics import psnr, ssimulacra2

    img = vi.render(depth=8)
    test = (img[..., None] if img.ndim == 2 else img).astype(np.float64)
    ref = raster.pixels
    scores = {}
    for name, fn in (("psnr", psnr), ("ssimulacra2", ssimulacra2)):
        try:
            v = float(fn(ref, test))
            scores[name] = None if math.isinf(v) else round(v, 4)
        except IsophoteError as e:
            scores[name] = None
            scores[f"{name}_missing"] = " ".join(str(e).split())
    return scores
