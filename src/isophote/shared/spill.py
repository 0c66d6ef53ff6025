"""Arrays that wait on disk: a large array a stage does not read, held in a temporary file
until a later stage reads it back, whole or rows at a time (the encoder's prepared plane
between the march and the caps, its fitted chains beside the hierarchy: issue 22's bound)."""

from __future__ import annotations

import tempfile

import numpy as np


class ArrayFile:
    """A C-ordered copy of an array in a temporary file (deleted when closed, or when this
    goes): rows(a, b) reads its rows [a, b), whole() all of it. Raises OSError where the
    file cannot be written (the caller keeps the array then)."""

    def __init__(self, a: np.ndarray):
        self.shape, self.dtype = a.shape, a.dtype
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
