"""A channel's segments at one level, indexed by the level's blocks (render/blocks.py).

Built once per level (and kept by a preparation): the segments that can change a band or a
field at that level, which are those whose box holds one of the level's node rows or columns
or one of the render's sample rows (the others are culled: _kernels/index.py), their boxes in
node units, and for a blocked level a CSR list of them per block. A window or a strip then
reads the segments of its own blocks only, in their original order, and flattens just those.
Below 1x most of a dense photograph's segments are far smaller than a node and cross none of
its rows: a reduction or a tile reads the few that do.
"""

from __future__ import annotations

import numpy as np

from ..geometry import flatten_selected
from ._kernels.index import fill_firsts, grid_index, kept_segments, select

INF = float("inf")
BIN = 32  # nodes a side of the index's cells (at most a block): what a window or a strip scans


def segment_firsts(offsets: np.ndarray) -> np.ndarray:
    """(S,): each segment's first control point in the points (chains.segment_starts' first),
    int32 where the points allow it (8 -> 4 bytes a segment), made without segment_starts'
    temporaries (about 40 bytes a segment)."""
    n = int((offsets[-1] - (offsets.shape[0] - 1)) // 3) if offsets.shape[0] > 1 else 0
    dtype = np.int32 if offsets[-1] < 2**31 else np.int64
    return fill_firsts(offsets, np.empty(n, dtype))


class SegmentIndex:
    """Segments of concatenated chains (points, first: chains.segment_starts) at r nodes a
    source pixel, culled for the node lattice and the sample rows (sky, soff) (sky 0: none),
    on a level of nr x nc nodes in blocks of ``block`` nodes (0: one window, no index),
    indexed by cells of min(BIN, block) nodes. The cells are finer than the blocks: a window
    is its block and a margin, and with cells of a block it scanned the lists of 3 x 3 blocks
    (5.8 times its own area for a tile's 128-node block at 2x: on a dense luma 2-3 ms a
    window); a strip scans its own rows. A segment is listed in every cell its box reaches,
    so finer cells list more entries (the mosaic's luma at 2x: 6.3 M for 4.9 M at 128)."""

    def __init__(self, points, first, border, r: float, block: int, nr: int, nc: int, sample_rows=(0.0, 0.0)):
        self.points, self.first, self.border, self.r = points, first, border, float(r)
        self.sample_rows = float(sample_rows[0]), float(sample_rows[1])
        self.block = block
        self._ids = self._kept()
        if block:  # the cells' lists hold the segments' ids: a blocked level keeps no list of them
            self.bin = min(BIN, block)
            self.nbr, self.nbc = -(-nr // self.bin), -(-nc // self.bin)
            self.index, self.starts = grid_index(points, first, self._ids, self.r, self.bin, self.nbr, self.nbc)
            self._ids = None

    def _kept(self) -> np.ndarray:
        return kept_segments(self.points, self.first, self.r, True, *self.sample_rows)

    @property
    def ids(self) -> np.ndarray:
        """The kept segments (ascending): held by a one-window level, made again (a pass over
        the segments) where a blocked one is asked (a preparation's row windings)."""
        return self._ids if self._ids is not None else self._kept()

    @property
    def nbytes(self) -> int:
        return self.index.nbytes + self.starts.nbytes if self.block else self._ids.nbytes

    def _select(self, b0, b1, c0, c1, x_lo, x_hi, y_lo, y_hi) -> np.ndarray:
        b0, b1 = max(b0, 0), min(b1, self.nbr - 1)
        c0, c1 = max(c0, 0), min(c1, self.nbc - 1)
        if b0 > b1 or c0 > c1:
            return np.zeros(0, np.int64)
        return select(self.index, self.starts, self.nbc, b0, b1, c0, c1, self.points, self.first, self.r,
                      float(x_lo), float(x_hi), float(y_lo), float(y_hi))

    def window(self, i0: int, j0: int, n: int, m: int) -> np.ndarray:
        """Segments (ascending ids) whose box reaches the window's nodes widened by a node (each
        listed in the cells that box, widened by a node, reaches: those of nodes i0 .. i0 + n)."""
        B = self.bin
        return self._select(i0 // B, (i0 + n) // B, j0 // B, (j0 + m) // B, j0 - 1, j0 + m + 1, i0 - 1, i0 + n + 1)

    def rows(self, y_lo: float, y_hi: float, x_lo: float = -INF, x_hi: float = INF) -> np.ndarray:
        """Segments (ascending ids) whose box reaches node rows y_lo..y_hi widened by a node
        (and, when given, node columns x_lo..x_hi)."""
        B = self.bin
        c0 = 0 if x_lo == -INF else int(np.floor((x_lo - 1) / B))
        c1 = self.nbc - 1 if x_hi == INF else int(np.floor((x_hi + 1) / B))
        return self._select(int(y_lo // B), int(y_hi // B), c0, c1, x_lo, x_hi, y_lo - 1, y_hi + 1)

    def edges(self, ids=None, tol: float = 0.05):
        """Edges (x0, y0, x1, y1, is_source) in source pixels of the segments ids (all the kept
        ones when None), flattened at tol."""
        return flatten_selected(self.points, self.first, self.border, self.ids if ids is None else ids, tol)
