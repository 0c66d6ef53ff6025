"""The C allocator's habits, set for a process whose large arrays come and go (the
encoder's strips, the renderer's canvas passes and block windows).

glibc raises its mmap threshold to the largest block freed so far (up to 32 MB), and its
heaps then keep each freed temporary beneath the arrays that follow it: the peak RSS then
follows what was freed, not what is held. Each stage fixes the thresholds for its own
habits when it starts (glibc only; elsewhere nothing): return_freed_memory for the encoder's
strips, the loader and a render (large blocks mapped on their own and unmapped when
freed), keep_freed_memory for tiles; trim_heap gives the arenas' free
pages back. A block is freed as it was allocated, whatever the thresholds are by then.
"""

from __future__ import annotations

# Blocks of this size and up are mapped on their own, and given back to the system when
# freed (glibc's M_MMAP_THRESHOLD, fixed: glibc otherwise raises it to the largest block freed
# so far, up to 32 MB, and its heaps then keep every strip's freed temporaries beneath the
# results that follow them). Whole process, balanced: the 2 MP mosaic crop 2,170 MB with
# glibc's default, 1,578 MB with 1 MiB, 1,230 MB with 256 KiB (the per-strip results of
# narrow strips are blocks of a few hundred KiB); benchmarks/results/encode_scale.md.
MMAP_THRESHOLD = 1 << 18
# A render allocates and frees a window's arrays (a few MB each, 780 windows for the mosaic
# at 1x) again and again, each faulted in afresh (2.2 M page faults, 4.3 s of system time in
# the mosaic's 15 s 1x render). Taking blocks under 8 MB from the heaps (16 MB of freed pages
# kept) saved 7-13 % of a full render's time but raised its peak by 30-85 MB: the `high`
# mosaic to 3840 wide 919 -> 974 MB beside the output, over issue 22's 1 GB (two more runs
# each: 885-925 MB against 924-967). Not done.
# A process that serves tiles (a preparation's: render/prepare.py) allocates and frees the
# same few megabytes of window arrays for every tile; mapped on their own, each tile paid
# about 2,200 page faults (3-4 ms of system time on two processors, a sixth of a 2x tile's
# processor time). There blocks up to glibc's largest threshold come from the heaps, and
# up to TILE_TRIM bytes of freed pages stay in them for the next tile.
TILE_MMAP_THRESHOLD = 32 << 20
TILE_TRIM = 64 << 20
_M_MMAP_THRESHOLD = -3  # glibc's malloc.h
_M_TRIM_THRESHOLD = -1
_MODES = {"strips": (MMAP_THRESHOLD, 128 << 10),  # (glibc's default trim threshold)
          "tiles": (TILE_MMAP_THRESHOLD, TILE_TRIM)}
_libc = None
_mode = None


def _glibc():
    """The C library when it is glibc (mallopt, malloc_trim), else False."""
    global _libc
    if _libc is None:
        try:
            import ctypes

            lib = ctypes.CDLL(None)
            _libc = lib if hasattr(lib, "malloc_trim") and hasattr(lib, "gnu_get_libc_version") else False
        except OSError:  # no C library to ask: the default allocator
            _libc = False
    return _libc


def _use(mode: str) -> None:
    global _mode
    if mode != _mode and _glibc():
        mmap_threshold, trim = _MODES[mode]
        _glibc().mallopt(_M_MMAP_THRESHOLD, mmap_threshold)
        _glibc().mallopt(_M_TRIM_THRESHOLD, trim)
    _mode = mode


def mode() -> str | None:
    """The thresholds last set: "strips", "tiles", or None."""
    return _mode


def return_freed_memory() -> None:
    """Have the C allocator give large freed blocks back to the system at once (the
    encoder, the loader, a render). The encoder's strips free and allocate blocks of many
    sizes; without this the peak RSS follows what was freed, not what is held."""
    _use("strips")


def keep_freed_memory() -> None:
    """For a process that serves tiles: blocks up to TILE_MMAP_THRESHOLD come from the
    heaps, whose freed pages (up to TILE_TRIM) the next tile's arrays reuse without faults."""
    _use("tiles")


def trim_heap() -> None:
    """Give the free pages of every heap arena back to the system (glibc's malloc_trim;
    elsewhere nothing): small blocks freed between the ones kept stay in the arenas otherwise."""
    if _glibc():
        _glibc().malloc_trim(0)


_MADV_DONTNEED = 4  # Linux's sys/mman.h


def release_read(a, start: int, stop: int) -> None:
    """Give the system back the memory pages lying wholly inside a[start:stop] of a 1-D
    C-contiguous array whose elements there will not be read again (Linux's madvise
    MADV_DONTNEED; elsewhere nothing). For an input consumed in order by a long stage (the
    fitter's tolerances, batch by batch): its pages go as it is read, not when the whole
    array is freed. The array keeps its size; a later read of those elements gives zeros,
    never the old values, so a caller releases only what it has finished with. Pages
    shared with other data (the array's first and last, partly) are kept."""
    import mmap
    import sys

    if not sys.platform.startswith("linux") or not _glibc() or a.ndim != 1 or not a.flags.c_contiguous \
            or stop <= start:
        return
    page = mmap.PAGESIZE
    base = a.ctypes.data
    lo = -(-(base + int(start) * a.itemsize) // page) * page
    hi = (base + int(stop) * a.itemsize) // page * page
    if hi > lo:
        import ctypes

        _glibc().madvise(ctypes.c_void_p(lo), ctypes.c_size_t(hi - lo), _MADV_DONTNEED)
