"""Arrays that wait on disk: a large array a stage does not read, held in a temporary file
until a later stage reads it back, whole or rows at a time (the encoder's prepared plane
between the march and the caps, its fitted chains beside the hierarchy: issue 22's bound)."""

from __future__ import annotations

import os
import tempfile

import numpy as np

# File systems whose files live in memory: a file there saves no memory (Linux's /tmp is
# often a tmpfs); TMPDIR may name a directory on disk instead.
IN_MEMORY = ("tmpfs", "ramfs")
# Points (or segments) a stage holds between the calls of a Pager's release() when it passes
# over arrays on its files in runs (the encoder's joint moves and hierarchy): 4 M points,
# about 90 MiB of a channel's polylines.
RELEASE_POINTS = 1 << 22


def file_system(path: str) -> str | None:
    """The type of the file system holding ``path`` (the longest mount point above it in
    /proc/mounts), or None where unknown (no /proc/mounts: not Linux)."""
    try:
        with open("/proc/mounts") as f:
            mounts = [line.split()[1:3] for line in f if len(line.split()) >= 3]
    except OSError:
        return None
    path = os.path.realpath(path)
    best, kind = "", None
    for point, fs in mounts:
        point = point.replace("\\040", " ")
        inside = path == point or path.startswith(point.rstrip("/") + "/")
        if inside and len(point) >= len(best):
            best, kind = point, fs
    return kind


class ArrayFile:
    """A C-ordered copy of an array in a temporary file (deleted when closed, or when this
    goes): rows(a, b) reads its rows [a, b), whole() all of it. Raises OSError where the
    file cannot be written, or where the temporary directory is in memory (a tmpfs: the
    file would save nothing); the caller keeps the array then."""

    def __init__(self, a: np.ndarray):
        self.shape, self.dtype = a.shape, a.dtype
        where = tempfile.gettempdir()
        if file_system(where) in IN_MEMORY:
            raise OSError(f"the temporary directory {where} is in memory")
        self.file = tempfile.TemporaryFile(prefix="isophote-")
        try:
            np.ascontiguousarray(a).tofile(self.file)
            self.file.flush()
        except BaseException:
            self.file.close()
            raise

    def __call__(self, a: int, b: int) -> np.ndarray:
        row = int(np.prod(self.shape[1:], dtype=np.int64))
        n = max(min(b, self.shape[0]) - a, 0)
        self.file.seek(a * row * self.dtype.itemsize)
        out = np.fromfile(self.file, self.dtype, n * row)
        if out.shape[0] != n * row:
            raise OSError("a temporary file of the encoder was cut short")
        return out.reshape((n,) + self.shape[1:])

    def whole(self) -> np.ndarray:
        """The array, read back (the file is closed after)."""
        out = self(0, self.shape[0])
        self.file.close()
        return out


class Pager:
    """Arrays whose memory is a temporary file's pages, mapped (MAP_SHARED): a stage that
    reads or writes a large array in passes calls release() between them, and the pages it
    touched go from the process's memory to the page cache (the system's, which writes
    them to the file and evicts them as it needs): release() loses nothing, unlike
    heap.release_read on ordinary memory. Each array has a file of its own, unlinked at
    once, so its disk space goes with the array.

    Raises OSError where no temporary file can be made or where the temporary directory is
    in memory (a tmpfs: the pages would be memory again). Where a file cannot be made or
    given its size later (a full disk), empty() gives an ordinary array instead: the same
    values, only held in memory.
    """

    def __init__(self):
        where = tempfile.gettempdir()
        if file_system(where) in IN_MEMORY:
            raise OSError(f"the temporary directory {where} is in memory")
        self._maps = []  # weak references: a map goes when the last array on it does
        self.mapped = 0  # bytes mapped so far (what the files took on disk, at most)

    def empty(self, shape, dtype) -> np.ndarray:
        """An uninitialised array of ``shape`` and ``dtype`` on a file of its own."""
        import mmap
        import weakref

        dtype = np.dtype(dtype)
        shape = tuple(int(s) for s in np.atleast_1d(shape))
        count = int(np.prod(shape, dtype=np.int64))
        if count == 0:
            return np.empty(shape, dtype)
        nbytes = count * dtype.itemsize
        try:
            with tempfile.TemporaryFile(prefix="isophote-") as f:
                os.posix_fallocate(f.fileno(), 0, nbytes)  # its blocks now: a full disk raises here
                m = mmap.mmap(f.fileno(), nbytes)  # the map keeps the file (unlinked) open
        except OSError:
            return np.empty(shape, dtype)
        if len(self._maps) % 256 == 255:  # the references of maps gone, now and then
            self._maps = [r for r in self._maps if r() is not None]
        self._maps.append(weakref.ref(m))
        self.mapped += nbytes
        return np.frombuffer(m, dtype, count).reshape(shape)

    def put(self, a: np.ndarray) -> np.ndarray:
        """A copy of ``a`` on a file of its own, its pages released once written."""
        out = self.empty(a.shape, a.dtype)
        if out.size:
            out[...] = a
            self.release(out)
        return out

    def release(self, *arrays) -> None:
        """The pages of the maps under ``arrays`` (none given: every live map) out of the
        process's memory (madvise MADV_DONTNEED on a shared file mapping: the data stays in
        the file and the page cache). Arrays on no map of a pager are left as they are."""
        import mmap

        if not hasattr(mmap, "MADV_DONTNEED"):  # no madvise here (Windows): the pages stay mapped
            return
        maps = [r() for r in self._maps] if not arrays else [_map_of(a) for a in arrays]
        for m in maps:
            if m is not None:
                m.madvise(mmap.MADV_DONTNEED)


def _map_of(a):
    """The mmap under array ``a`` (a view of a Pager's array), or None."""
    import mmap

    while a is not None and not isinstance(a, mmap.mmap):
        a = a.obj if isinstance(a, memoryview) else getattr(a, "base", None)
    return a


def pager_or_none():
    """A Pager, or None where none can be made (the caller keeps ordinary arrays)."""
    try:
        return Pager()
    except OSError:
        return None
