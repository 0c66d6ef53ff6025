"""isophote.threads: the process-wide thread limit, the caller's-thread executor, and the
same bytes from an encode and a render whatever the thread count."""

import threading

import numpy as np
import pytest

from isophote import threads


def test_limited_lowers_then_restores():
    n = threads.processors()
    assert threads.available() == n and threads.available(cap=1) == 1
    with threads.limited(1):
        assert threads.available() == 1 and threads.available(cap=8) == 1
        with threads.limited(3):  # nested: the smallest holds
            assert threads.available() == 1
        assert threads.available() == 1
    assert threads.available() == n
    with threads.limited(None):
        assert threads.available() == n


def test_concurrent_limits_hold_until_the_last_ends():
    # two blocks in two threads, the first ending while the second runs: the limit stays
    entered, release, seen = threading.Event(), threading.Event(), []

    def second():
        with threads.limited(1):
            entered.set()
            release.wait(10)
            seen.append(threads.available())

    t = threading.Thread(target=second)
    with threads.limited(1):
        t.start()
        entered.wait(10)
    seen.append(threads.available())  # the first block is over, the second is not
    release.set()
    t.join(10)
    assert seen == [1, 1] and threads.available() == threads.processors()


def test_pool_of_one_runs_in_the_caller_in_order():
    me, order = threading.get_ident(), []
    with threads.limited(1), threads.pool(1) as pool:
        futures = [pool.submit(lambda k: (order.append(k), threading.get_ident())[1], k) for k in range(3)]
        assert all(f.done() for f in futures)  # run at once, not queued
        assert [f.result() for f in futures] == [me] * 3 and order == [0, 1, 2]
        assert list(pool.map(lambda x: x * x, [1, 2, 3])) == [1, 4, 9]
        failed = pool.submit(lambda: 1 / 0)
        with pytest.raises(ZeroDivisionError):
            failed.result()
    with threads.pool(2) as pool:
        assert pool.submit(threading.get_ident).result() != me
    if threads.processors() > 1:  # one thread chosen, more allowed: a pool thread still
        with threads.pool(1) as pool:
            assert pool.submit(threading.get_ident).result() != me


def test_same_bytes_with_one_thread(tmp_path, monkeypatch):
    import isophote
    from isophote.encoder import encode_pixels
    from isophote.options import EncodeOptions

    sizes, real_pool = [], threads.pool
    monkeypatch.setattr(threads, "pool", lambda n: (sizes.append(n), real_pool(n))[1])

    rng = np.random.default_rng(5)
    yy, xx = np.mgrid[0:192, 0:256]
    img = np.stack([128 + 90 * np.sin(xx / 7.0) * np.cos(yy / 11.0), 255.0 * xx / 256, 255.0 * yy / 192], -1)
    img = np.clip(img + rng.normal(0, 6, img.shape), 0, 255)
    blobs, renders, pools = [], [], []
    for n in (None, 1):
        sizes.clear()
        with threads.limited(n):
            vi = encode_pixels(img, 8, EncodeOptions().resolved())
            vi.save(tmp_path / f"{n}.isoph")
            back = isophote.load(tmp_path / f"{n}.isoph")
            renders.append([back.render(width=w, height=h, depth=8) for w, h in ((512, 384), (128, 96))])
        blobs.append((tmp_path / f"{n}.isoph").read_bytes())
        pools.append(list(sizes))
    # the encoder's channels and the renders: threads by default, the caller's thread when limited
    if threads.processors() > 1:
        assert pools[0] and min(pools[0]) >= 2
    assert pools[1] and set(pools[1]) == {1}
    assert blobs[0] == blobs[1]
    assert all(np.array_equal(a, b) for a, b in zip(*renders))


def test_pool_calls_run_in_the_callers_context():
    """A context variable set around an operation (render/blocks.one_window) reaches the
    stages' worker threads, and a call's own changes stay in its copy."""
    import contextvars

    var = contextvars.ContextVar("setting", default=0)
    token = var.set(7)
    try:
        def read_and_change(_):
            seen = var.get()
            var.set(-1)  # in the call's copy of the context only
            return seen

        with threads.pool(2) as pool:
            assert list(pool.map(read_and_change, range(6))) == [7] * 6
        assert var.get() == 7
    finally:
        var.reset(token)
