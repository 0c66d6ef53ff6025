"""How many threads one encode or render may use.

By default: the processors this process may use (its affinity). :func:`limited` lowers that
for the process while it runs, so that a caller that already runs several operations at
once (a batch worker among others, isophote.batch.item) keeps each one on one processor
instead of letting them contend. Every threaded stage gives the same bytes whatever the
count (the encoder's channels, the fitter's groups of polylines, the renderer's channels,
the range coder's channels are independent and gathered in order).

The limit is process-wide, not per thread: the stages' worker threads must see it, and
they are not the caller's thread.
"""

from __future__ import annotations

import contextvars
import os
import threading
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from contextlib import contextmanager

_active: list = []  # the limits of the blocks running now (any thread's)
_limit: int | None = None  # the smallest of them
_lock = threading.Lock()


def processors() -> int:
    """The processors this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def available(cap: int | None = None) -> int:
    """Threads a stage may use: the processors, at most the current limit and ``cap``."""
    n = processors()
    if _limit is not None:
        n = min(n, _limit)
    if cap is not None:
        n = min(n, int(cap))
    return max(1, n)


@contextmanager
def limited(n: int | None):
    """Within the block, every stage of this process uses at most ``n`` threads (None: no
    change). Nested or concurrent limits keep the smallest."""
    global _limit
    if n is None:
        yield
        return
    n = max(1, int(n))
    with _lock:
        _active.append(n)
        _limit = min(_active)
    try:
        yield
    finally:
        with _lock:
            _active.remove(n)
            _limit = min(_active) if _active else None


class _InCaller(Executor):
    """An executor that runs each call at once in the caller's thread: what a stage uses
    when it may have one thread, so that its work stays on that thread (no thread to
    start, and the caller's processor time and waits are the item's)."""

    def submit(self, fn, /, *args, **kwargs):
        f = Future()
        try:
            f.set_result(fn(*args, **kwargs))
        except BaseException as e:  # noqa: BLE001 - delivered by result(), as a pool would
            f.set_exception(e)
        return f


class _InContext(ThreadPoolExecutor):
    """A ThreadPoolExecutor whose calls run in a copy of the submitting thread's context
    (contextvars), as they would in the caller's thread: a setting made for the duration of
    an operation (render/blocks.one_window) reaches the stages' worker threads."""

    def submit(self, fn, /, *args, **kwargs):
        return super().submit(contextvars.copy_context().run, fn, *args, **kwargs)


def pool(n: int):
    """An executor of ``n`` threads: a ThreadPoolExecutor (calls in the caller's context);
    where the process may use one thread (a limit, or one processor), the caller's own
    (calls run at once, in submission order; same results). A stage that merely chose one
    thread keeps its pool thread: memory peaks differ between glibc's main heap and a
    thread's arena, and the encoder's budget (tests/encoder/test_encode_budget.py) was
    measured on the latter."""
    return _InContext(max_workers=n) if n > 1 or available() > 1 else _InCaller()
