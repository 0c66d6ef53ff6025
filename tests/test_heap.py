"""shared/heap.py: pages of a consumed input given back as it is read (release_read)."""

import mmap
import sys

import numpy as np
import pytest

from isophote.shared.heap import _glibc, release_read


def _rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * mmap.PAGESIZE


@pytest.mark.skipif(not sys.platform.startswith("linux") or not _glibc(), reason="madvise: Linux with glibc")
def test_release_read_gives_back_the_pages_wholly_inside_the_range_and_no_others():
    n = 8 << 20  # 64 MiB of float64: mapped on its own
    a = np.arange(n, dtype=np.float64)
    before = _rss()
    k = n // 2 + 3  # not on a page boundary
    release_read(a, 5, k)
    freed = before - _rss()
    assert 0.95 * k * 8 < freed <= k * 8  # about half the array's memory, never more
    per_page = mmap.PAGESIZE // 8
    first = -(-(a.ctypes.data + 5 * 8) // mmap.PAGESIZE) * mmap.PAGESIZE
    lo = (first - a.ctypes.data) // 8  # the first element of the first page released
    hi = ((a.ctypes.data + k * 8) // mmap.PAGESIZE * mmap.PAGESIZE - a.ctypes.data) // 8
    assert 5 <= lo < 5 + per_page and k - per_page < hi <= k
    assert np.array_equal(a[:lo], np.arange(lo)) and np.array_equal(a[hi:], np.arange(hi, n))
    assert not a[lo:hi].any()  # released: zeros, never the old values
    release_read(a, 10, 10)  # empty, and a range inside one page: nothing
    release_read(a, hi + 1, hi + 2)
    assert a[hi + 1] == hi + 1


def test_release_read_leaves_other_arrays_alone():
    a = np.arange(1000.0)[::2]  # not contiguous: nothing is released
    release_read(a, 0, 500)
    assert np.array_equal(a, np.arange(0.0, 1000.0, 2.0))
    b = np.arange(12.0).reshape(3, 4)  # not 1-D
    release_read(b, 0, 3)
    assert np.array_equal(b, np.arange(12.0).reshape(3, 4))


def test_arrays_wait_on_disk_but_never_in_a_tmpfs(monkeypatch, tmp_path):
    """An ArrayFile goes to the temporary directory unless that is in memory (a tmpfs: the
    file would save nothing), and the encoder then keeps the plane and the chains, with the
    same bytes."""
    import isophote
    from isophote.encoder import strips
    from isophote.format.isoph import dumps
    from isophote.shared import spill

    assert spill.file_system("/proc/self") in (None, "proc")
    if spill.file_system("/") is not None:
        assert spill.file_system(str(tmp_path)) not in (None, "proc")
    a = np.arange(12.0).reshape(4, 3)
    monkeypatch.setattr(spill, "file_system", lambda path: "tmpfs")
    with pytest.raises(OSError, match="in memory"):
        spill.ArrayFile(a)
    rows = strips.GridRows(a, None, 11, 9)
    assert not rows.spill() and rows.v is a  # kept
    rng = np.random.default_rng(2)
    img = np.clip(rng.normal(128, 40, (60, 80, 3)), 0, 255).astype(np.uint8)
    kept = dumps(isophote.encode(img, memory=1))
    made = []
    real_init = spill.ArrayFile.__init__
    monkeypatch.setattr(spill, "file_system", lambda path: "ext4")
    monkeypatch.setattr(spill.ArrayFile, "__init__", lambda self, x: made.append(x.shape) or real_init(self, x))
    assert dumps(isophote.encode(img, memory=1)) == kept
    assert len(made) == 6  # each channel's plane and chains went to files this time


def test_a_pagers_arrays_lose_nothing_when_their_pages_go(monkeypatch, tmp_path):
    """Pager (shared/spill.py): arrays on temporary files whose pages leave the process's
    memory on release() and come back unchanged when read; release(a) touches a's map
    alone; ordinary arrays where no file can be had, and no pager in a tmpfs."""
    from isophote.shared import spill

    monkeypatch.setattr(spill.tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(spill, "file_system", lambda path: "ext4")
    p = spill.Pager()
    n = 8 << 20  # 64 MiB of float64
    before = _rss()
    a = p.empty(n, np.float64)
    a[:] = np.arange(n)
    b = p.put(np.arange(1000, dtype=np.int32).reshape(10, 100))
    assert b.shape == (10, 100) and b.dtype == np.int32 and spill._map_of(b[3:5, 1:]) is not None
    assert spill._map_of(np.arange(3)) is None
    grown = _rss() - before
    assert grown > 0.9 * n * 8
    p.release(b)  # b's map alone: a's pages stay
    assert _rss() - before > 0.9 * n * 8
    p.release()
    assert _rss() - before < 0.1 * n * 8
    assert np.array_equal(a, np.arange(n)) and np.array_equal(b.ravel(), np.arange(1000))  # nothing lost
    assert p.mapped == n * 8 + 4000
    p.release(np.arange(5.0))  # not on a map: nothing happens
    assert p.empty((0, 3), np.float64).shape == (0, 3)
    monkeypatch.setattr(spill.os, "posix_fallocate", lambda *a: (_ for _ in ()).throw(OSError(28, "full")))
    c = p.empty(10, np.float64)  # a full disk: an ordinary array
    assert spill._map_of(c) is None and c.shape == (10,)
    monkeypatch.setattr(spill, "file_system", lambda path: "tmpfs")
    with pytest.raises(OSError, match="in memory"):
        spill.Pager()
    assert spill.pager_or_none() is None
