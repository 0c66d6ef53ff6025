"""Render progress on a terminal: a percentage as strips complete, and, once, a note that the
kernels are being compiled (numba's on-disk cache is empty: the first run only)."""

from __future__ import annotations

import os
import sys


def kernels_cached() -> bool:
    """Whether the renderer's kernels are in numba's on-disk cache (the evaluation kernel,
    compiled with the others, stands for them)."""
    from ._kernels.diffuse import evaluate

    try:
        return os.path.exists(evaluate._cache._cache_file._index_path)
    except AttributeError:  # another numba: say nothing
        return True


class TerminalProgress:
    """Callable with the fraction done; writes 'PREFIX NN%' on stderr when it is a terminal
    (quiet in pipes, or when ``quiet``)."""

    def __init__(self, prefix: str, quiet: bool = False, stream=None):
        self.stream = stream or sys.stderr
        self.on = not quiet and self.stream.isatty()
        self.prefix, self.last = prefix, -1
        if self.on and not kernels_cached():
            self.stream.write(f"\r\033[K{prefix} compiling kernels (first run only)\n")
            self.stream.flush()

    def __call__(self, fraction: float) -> None:
        pct = int(100 * min(max(fraction, 0.0), 1.0))
        if self.on and pct != self.last:
            self.last = pct
            self.stream.write(f"\r\033[K{self.prefix} {pct}%")
            self.stream.flush()

    def done(self) -> None:
        if self.on:
            self.stream.write("\r\033[K")
            self.stream.flush()
