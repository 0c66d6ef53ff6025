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
