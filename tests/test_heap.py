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
