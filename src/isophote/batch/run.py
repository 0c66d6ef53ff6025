"""The batch: plan what is missing or stale, run the items on an executor, record them.

    batch(inputs, outdir, deliver=..., executor=None)

Any ``concurrent.futures.Executor`` runs the items (:func:`isophote.batch.item.process`):
by default a process pool of this machine's processors, or the one given (Dask's
``Client.get_executor()`` for a cluster). The outputs are the same bytes whichever runs
them: an item is a pure function of its input file and options.

Faults. A worker that dies (SIGKILL, the kernel's out-of-memory killer) breaks a process
pool: the pool is replaced and the unfinished items are submitted again, each alone (so the
next break names the culprit), at most ``retries`` more times; then the item is recorded as
failed. Dask reschedules a dead worker's tasks itself, and reports ``KilledWorker`` when it
gives up; that counts as one attempt here. Ctrl-C ends the workers of our own pool (every
output is written to a temporary name and renamed, so nothing partial is left) and
re-raises KeyboardInterrupt; the manifest holds every item finished so far, so a rerun
resumes.

Memory. On our own pool, items start only while the sum of their budgets
(memory.item_budget) fits in the machine's allowance (memory.memory_allowance), so a
16-megapixel frame does not multiply by the worker count; one item always runs. On another
executor the items' machines are not ours to measure: there at most ``max_in_flight``
items are submitted at once, and Dask's own worker memory limits apply.
"""

from __future__ import annotations

import glob
import os
import signal
import sys
import time
from collections import deque
from concurrent.futures import FIRST_COMPLETED, CancelledError, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import asdict, dataclass, field

from ..errors import OptionError
from . import manifest as M
from .deliveries import DEFAULT_FIT, FITS, parse_deliveries
from .inputs import expand, stem as stem_of
from .item import KILL_HOOK, process, sha256_file
from . import memory

FORMATS = {"png": "png", "tif": "tif", "tiff": "tif", "jpg": "jpg", "jpeg": "jpg", "webp": "webp"}
DEFAULT_DELIVERIES = "sd,hd,uhd,phone"
RETRIES = 2


@dataclass
class Summary:
    """What a batch did: ``items`` in all, ``made`` (some output written), ``up_to_date``
    (nothing to do), ``failed`` ({stem: reason}); ``megapixels`` of the inputs made,
    ``seconds`` of wall-clock."""

    items: int = 0
    made: int = 0
    up_to_date: int = 0
    failed: dict = field(default_factory=dict)
    megapixels: float = 0.0
    seconds: float = 0.0
    manifest: str = ""

    @property
    def mp_per_s(self) -> float:
        return self.megapixels / self.seconds if self.seconds > 0 else 0.0

    def line(self) -> str:
        fails = f", {len(self.failed)} failed" if self.failed else ""
        return (f"{self.items} items: {self.made} made, {self.up_to_date} up to date{fails}; "
                f"{self.megapixels:.2f} MP in {self.seconds:.1f} s, {self.mp_per_s:.2f} MP/s")


def batch(inputs, outdir, deliver=DEFAULT_DELIVERIES, *, executor=None, workers=None, preset=None,
          encode=None, format="png", depth=8, fit=DEFAULT_FIT, pad=(0, 0, 0), metrics=False,
          retries=RETRIES, max_in_flight=64, pin=False, item_threads=None, progress=None) -> Summary:
    """Encode every input into ``outdir/{stem}.isoph`` and render every delivery into
    ``outdir/{delivery}/{stem}.{format}``; record it all in ``outdir/manifest.json``.

    inputs : files, folders or glob patterns (see isophote.batch.inputs).
    deliver : "sd,hd,uhd,phone,WxH" or a list of such names.
    executor : any concurrent.futures.Executor; None = a process pool of ``workers``
        processes (default: the processors this process may use).
    preset, encode : the preset name and other EncodeOptions fields (a dict).
    format, depth, fit, pad : the deliveries' file format (png, tif, jpg, webp), bits (8,
        16), aspect fit (pad, crop, stretch) and pad colour (R, G, B on 0..255).
    metrics : also measure PSNR and SSIMULACRA2 of each master's 1x render.
    pin : give each of our pool's workers a processor of its own (an item then runs on one
        processor: its threads share it); for many workers on few processors.
    item_threads : threads each item may use; None = its worker's share of its machine's
        processors (one thread when a machine runs as many items at once as it has
        processors; all of them when it runs one): see :func:`slots`. The bytes are the
        same whatever the count.
    progress : a tqdm bar on stderr; None = only when stderr is a terminal.

    Bad inputs do not stop the batch: they are in ``Summary.failed`` and the manifest.
    """
    t0 = time.perf_counter()
    jobs, items, summary = plan(inputs, outdir, deliver, preset=preset, encode=encode, format=format,
                                depth=depth, fit=fit, pad=pad, metrics=metrics)
    outdir = os.fspath(outdir)
    save = lambda: M.save(outdir, items)  # noqa: E731
    save()
    bar = _bar(summary.items, summary.items - len(jobs), progress)

    def finished(job, result):
        s = job["stem"]
        items[s] = merge(items.get(s), job, result)
        if result.get("status") == "ok":
            summary.made += 1
            summary.megapixels += items[s].get("width", 0) * items[s].get("height", 0) / 1e6
        else:
            summary.failed[s] = result.get("reason", "failed")
        save()
        bar.update(1)

    at_once = slots(executor, workers)
    for job in jobs:
        job["slots"], job["threads"] = at_once, item_threads
    try:
        if executor is None:
            folders = sorted({sp["name"] for j in jobs for sp in j["outputs"]})
            _run_pool(jobs, finished, workers, retries, pin, lambda: _remove_temporaries(outdir, folders))
        else:
            _run_executor(executor, jobs, finished, retries, max_in_flight)
    finally:
        bar.close()
    summary.seconds = time.perf_counter() - t0
    return summary


def slots(executor, workers=None) -> int | None:
    """Items one machine runs at once on ``executor`` (None: our own pool of ``workers``):
    our pool's workers; a thread or process pool's ``_max_workers``; on Dask, the most
    worker threads on one host; None where the executor does not say."""
    if executor is None:
        return max(1, int(workers or len(_processors())))
    n = getattr(executor, "_max_workers", None)
    if isinstance(n, int):
        return max(1, n)
    client = getattr(executor, "_client", None)  # distributed's ClientExecutor
    try:
        per_host = {}
        for w in client.scheduler_info()["workers"].values():
            per_host[w.get("host")] = per_host.get(w.get("host"), 0) + int(w.get("nthreads", 1))
        return max(per_host.values()) if per_host else None
    except Exception:  # noqa: BLE001 - not Dask, or it cannot tell: no limit
        return None


def _bar(total, done, progress):
    from tqdm import tqdm

    show = sys.stderr.isatty() if progress is None else bool(progress)
    return tqdm(total=total, initial=done, unit="item", file=sys.stderr, disable=not show, leave=False,
                desc="isophote batch")


# =============================================================================================
# Planning: what is missing or stale
# =============================================================================================


def plan(inputs, outdir, deliver, *, preset, encode, format, depth, fit, pad, metrics):
    """(jobs, manifest items, Summary): one job for each item with something to make."""
    from ..imageio import check_format, image_size
    from ..options import EncodeOptions, make

    paths = expand(inputs)
    deliveries = parse_deliveries(deliver)
    fmt = FORMATS.get(str(format).lower().lstrip("."))
    if fmt is None:
        raise OptionError(f"format must be one of png, tif, jpg, webp, got {format!r}")
    check_format(f"x.{fmt}", int(depth))
    if fit not in FITS:
        raise OptionError(f"fit must be one of {', '.join(FITS)}, got {fit!r}")
    pad = _pad(pad)
    options = dict(encode or {})
    if preset is not None:
        options["preset"] = preset
    enc = M.normalised(asdict(make(EncodeOptions, options).resolved()))
    specs = [M.normalised(dict(name=d.name, width=d.width, height=d.height, fit=fit, pad=pad, depth=int(depth),
                               format=fmt)) for d in deliveries]
    outdir = os.fspath(outdir)
    if os.path.exists(outdir) and not os.path.isdir(outdir):
        raise OptionError(f"{outdir}: exists and is not a folder")
    os.makedirs(outdir, exist_ok=True)
    _remove_temporaries(outdir, [s["name"] for s in specs])
    prior = {s: r for s, r in M.load(outdir).items() if isinstance(r, dict)}
    # this run's items in input order (pending until done), then an earlier run's others
    items = {stem_of(p): prior.get(stem_of(p)) or dict(input=p, status="pending") for p in paths}
    items.update({s: r for s, r in prior.items() if s not in items})
    summary = Summary(items=len(paths), manifest=M.path_of(outdir))
    largest = max(s["width"] * s["height"] for s in specs)
    jobs = []
    for path, sha in zip(paths, _hashes(paths)):
        s = stem_of(path)
        if isinstance(sha, Exception):
            items[s] = dict(input=path, status="failed", reason=f"{path}: {getattr(sha, 'strerror', None) or sha}")
            summary.failed[s] = items[s]["reason"]
            continue
        rec = items.get(s) if (items.get(s) or {}).get("input") == path else None
        need_master = not M.master_fresh(outdir, rec, sha, enc)
        todo = [sp for sp in specs if need_master or not M.output_fresh(outdir, rec, sp)]
        need_metrics = bool(metrics) and (need_master or not (rec or {}).get("metrics"))
        if not (need_master or todo or need_metrics):
            summary.up_to_date += 1
            continue
        size = image_size(path)
        jobs.append(dict(input=path, stem=s, outdir=outdir, sha256=sha, encode=enc, need_master=need_master,
                         outputs=todo, metrics=bool(metrics), kill=os.environ.get(KILL_HOOK),
                         budget=memory.item_budget(size[0] * size[1] if size else 0, largest),
                         cost=_cost(path, size, need_master, todo)))
    # largest first, so that the run does not end on one worker finishing a big item while
    # the others are idle (stable: equal items keep the input order)
    jobs.sort(key=lambda j: j["cost"], reverse=True)
    return jobs, items, summary


def _cost(path, size, need_master, todo) -> tuple:
    """The order in which jobs start (largest first): the pixels to encode and render, then
    the input's bytes (among frames of one size, the more detailed compress less and take
    longer to encode)."""
    pixels = (size[0] * size[1] if size and need_master else 0) + sum(sp["width"] * sp["height"] for sp in todo)
    try:
        nbytes = os.path.getsize(path)
    except OSError:
        nbytes = 0
    return (pixels, nbytes if need_master else 0)


def _pad(pad) -> list:
    vals = [float(v) for v in (pad if not isinstance(pad, (int, float)) else (pad,))]
    if len(vals) == 1:
        vals *= 3
    if len(vals) != 3 or not all(0.0 <= v <= 255.0 for v in vals):
        raise OptionError(f"pad colour must be R,G,B on 0..255 (or one grey value), got {pad!r}")
    return vals


def _hashes(paths):
    """sha256 of every input (a few threads: hashing is I/O and hashlib releases the GIL);
    an OSError in place of a hash for a file that cannot be read."""
    from concurrent.futures import ThreadPoolExecutor

    def one(p):
        try:
            return sha256_file(p)
        except OSError as e:
            return e

    with ThreadPoolExecutor(max_workers=4) as pool:
        return list(pool.map(one, paths))


def _remove_temporaries(outdir, folders) -> None:
    """Temporary files a killed run left (isophote.imageio's ``.isophote-*.tmp``): the
    batch owns OUTDIR, so no other writer's file can be among them."""
    for folder in [outdir] + [os.path.join(outdir, f) for f in folders]:
        for tmp in glob.glob(os.path.join(glob.escape(folder), ".isophote-*.tmp")):
            try:
                os.unlink(tmp)
            except OSError:
                pass


def merge(old, job, result) -> dict:
    """The item's new manifest record from its old one and the worker's result."""
    base = dict(input=job["input"], input_sha256=job["sha256"], options={"encode": job["encode"]})
    attempts = job.get("attempts", 0) + (0 if result.get("lost") else 1)
    if result.get("status") != "ok":
        return dict(base, status="failed", reason=result.get("reason", "failed"), attempts=attempts)
    rec = dict(old or {}) if not job["need_master"] else {}
    rec.update(base, status="ok", attempts=attempts, seconds=result.get("seconds"))
    rec.pop("reason", None)
    if "input_sha256" in result:
        rec["input_sha256"] = result["input_sha256"]
    for key in ("width", "height", "master", "metrics", "started", "finished", "cpu_seconds", "worker",
                "threads", "run_queue_seconds"):
        if key in result:
            rec[key] = result[key]
    if "run_queue_seconds" not in result:
        rec.pop("run_queue_seconds", None)  # an earlier run's, not this one's
    rec["outputs"] = dict(rec.get("outputs") or {}, **result["outputs"])
    return M.normalised(rec)


# =============================================================================================
# Running: our own process pool
# =============================================================================================


def _worker_init(counter=None, cpus=None) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the batch's to handle
    if counter is not None and cpus:
        with counter.get_lock():
            k = counter.value
            counter.value += 1
        os.sched_setaffinity(0, {cpus[k % len(cpus)]})


def _processors() -> list:
    try:
        return sorted(os.sched_getaffinity(0))
    except AttributeError:
        return list(range(os.cpu_count() or 1))


def _new_pool(workers, pin):
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    ctx = mp.get_context("forkserver")
    ctx.set_forkserver_preload(["isophote.batch.item", "isophote.batch._warm"])
    pinning = (ctx.Value("i", 0), _processors()) if pin and hasattr(os, "sched_setaffinity") else (None, None)
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init, initargs=pinning)


def _run_pool(jobs, finished, workers, retries, pin, cleanup) -> None:
    """Run ``jobs`` on our own pool. ``cleanup()`` removes the temporary files of writes the
    pool's end cut short: a broken pool's survivors are terminated mid-item too."""
    workers = max(1, int(workers or len(_processors())))
    allowance = memory.memory_allowance()
    pending, running = deque(jobs), {}
    pool = _new_pool(workers, pin) if jobs else None

    def admissible(job):
        if not running:
            return True
        if job.get("attempts", 0) > 0 or any(j.get("attempts", 0) > 0 for j in running.values()):
            return False  # a suspect of an earlier break runs alone
        if len(running) >= workers:
            return False
        used = sum(j["budget"] for j in running.values())
        return allowance is None or used + job["budget"] <= allowance

    lost = "its worker process died (killed, or out of memory)"
    try:
        while pending or running:
            broken = False
            while pending and admissible(pending[0]):
                try:
                    fut = pool.submit(process, pending[0])
                except BrokenProcessPool:  # it broke since the last wait: nothing was submitted
                    broken = True
                    break
                running[fut] = pending.popleft()
            if not broken:
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for fut in done:
                    job = running.pop(fut)
                    try:
                        finished(job, fut.result())
                    except BrokenProcessPool:
                        broken = True
                        _retry(job, pending, finished, retries, lost)
                    except Exception as e:  # noqa: BLE001 - a bug in one item must not stop the batch
                        finished(job, _internal(e))
            if broken:  # every item still running was lost with the pool (but those just done)
                for fut, job in running.items():
                    if fut.done() and not fut.cancelled() and fut.exception() is None:
                        finished(job, fut.result())
                    else:
                        _retry(job, pending, finished, retries, lost)
                running.clear()
                # Not pool.shutdown(wait=True): on Python 3.11 a worker that submit() started
                # while the pool's manager was terminating the others is never terminated, and
                # the manager then waits for it for ever (seen: the killed-worker test hung CI).
                _terminate(pool)
                cleanup()  # no worker is running now
                pool = _new_pool(workers, pin)
    except BaseException:
        if pool is not None:
            _terminate(pool)
            pool = None
            cleanup()
        raise
    finally:
        if pool is not None:
            pool.shutdown(wait=True)


def _retry(job, pending, finished, retries, why) -> None:
    """Submit ``job`` again (first in line), or record it as failed after ``retries``."""
    job["attempts"] = job.get("attempts", 0) + 1
    if job["attempts"] > retries:
        times = "once" if job["attempts"] == 1 else f"{job['attempts']} times"
        finished(job, dict(status="failed", reason=f"{why}, {times}", lost=True))
    else:
        pending.appendleft(job)


def _internal(e) -> dict:
    return dict(status="failed", reason=f"internal error: {type(e).__name__}: {e}".splitlines()[0])


def _terminate(pool) -> None:
    """Stop our pool now: drop what is queued and end the worker processes (SIGTERM, then
    SIGKILL for one still there after 5 s), then wait for the pool's own thread."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for stop in ("terminate", "kill"):
        for p in processes:
            try:
                if p.is_alive():
                    getattr(p, stop)()
            except (OSError, AttributeError, ValueError):
                pass
        for p in processes:
            try:
                p.join(5)
            except (OSError, AssertionError, AttributeError, ValueError):
                pass
    manager = getattr(pool, "_executor_manager_thread", None)
    if manager is not None:
        manager.join(30)


# =============================================================================================
# Running: someone else's executor (Dask's Client.get_executor(), a thread pool, ...)
# =============================================================================================


def _worker_lost(e) -> bool:
    return isinstance(e, (BrokenProcessPool, CancelledError)) or type(e).__name__ == "KilledWorker"


def _run_executor(executor, jobs, finished, retries, max_in_flight) -> None:
    pending, running = deque(jobs), {}
    try:
        while pending or running:
            while pending and len(running) < max(1, int(max_in_flight)):
                job = pending.popleft()
                running[executor.submit(process, job)] = job
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for fut in done:
                job = running.pop(fut)
                try:
                    finished(job, fut.result())
                except Exception as e:  # noqa: BLE001
                    if _worker_lost(e):
                        _retry(job, pending, finished, retries, f"its worker was lost ({type(e).__name__})")
                    else:
                        finished(job, _internal(e))
    except BaseException:
        for fut in running:
            fut.cancel()
        raise
