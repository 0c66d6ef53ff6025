"""Node fields in canvas-aligned blocks: a render whose cost follows its output.

A level is the node grid of one channel at one output scale: r nodes per source pixel
(levels.py). On a small level (at most SINGLE_NODES nodes) the fields are computed over the
whole level at once, as they always were. On a larger one the level is cut into square
blocks of ``block`` nodes, aligned on the level's origin (so the cut depends on the canvas
and the scale only, never on the crop or the strips), and each block's fields are computed
on a window of the block plus ``margin`` nodes on every side, from the edges that reach the
window only. A target sample reads the fields of the block its position falls in. Every crop
of a render therefore computes exactly the blocks it touches, with the same windows, and is
the same region of the full render; a render touches only the blocks under its samples.

What is global stays global, computed once per level by a canvas-wide pass that needs only
the bands (``CanvasRegions``: 6 bytes a node while it runs, 4 kept): which node region each
node belongs to, and each region's cap value (a cap's annotation may lie far outside the
window). Two things are taken within the window instead of the whole region:
- the distances: a node finds sources within its window only, so a node farther than the
  margin from every source of a side (the middle of a band wider than twice the margin) may
  find a farther one, or none, where the whole-canvas sweep found one;
- a cap's d_max, its largest distance from the contour: it matters only for caps narrower
  than the cap ramp (2 source pixels by default), which fit in a window unless they are long
  and thin and cross a block border; domes (an infinite ramp) use it everywhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._kernels.diffuse import band_widths, evaluate, label_nodes, offsets, propagate, region_caps, seed
from ._kernels.raster import rasterise
from ._kernels.regions import cap_values, local_cap_values
from ._kernels.sharpen import correction
from ..geometry import flatten
from .distance import MAX_SWEEPS, MODES, NodeField

SINGLE_NODES = 2_500_000  # a level this small is one window (every corpus photograph up to 3x)
BLOCK = 256  # nodes a side of a block at or below 1x; smaller above (block_size)
MARGIN = 32  # nodes of window around a block
WINDOW_BYTES = 72  # bytes a node of a kept window (fields 48, band, labels, fill, widths)
WINDOW_PEAK_BYTES = 120  # while it is computed (crossings), as distance.NODE_BYTES


def block_size(zoom_per_node: float) -> int:
    """Nodes a side of a block: BLOCK at or below one output pixel a node, smaller above (a
    deep-zoom tile covers fewer nodes: 8 output pixels a node give 64)."""
    b = BLOCK
    while b > 64 and zoom_per_node * b > 2 * BLOCK:
        b //= 2
    return b


@dataclass(frozen=True)
class Level:
    r: float  # nodes per source pixel
    nr: int
    nc: int
    block: int  # nodes a side; 0: one window over the level

    @property
    def nodes(self) -> int:
        return self.nr * self.nc

    def blocks(self) -> tuple[int, int]:
        if not self.block:
            return 1, 1
        return -(-self.nr // self.block), -(-self.nc // self.block)

    def window(self, bi: int, bj: int) -> tuple[int, int, int, int]:
        """(i0, j0, n, m): the window of block (bi, bj), clipped to the level."""
        if not self.block:
            return 0, 0, self.nr, self.nc
        B = self.block
        i0, j0 = max(bi * B - MARGIN, 0), max(bj * B - MARGIN, 0)
        i1, j1 = min((bi + 1) * B + MARGIN, self.nr), min((bj + 1) * B + MARGIN, self.nc)
        return i0, j0, i1 - i0, j1 - j0


SINGLE_SEGMENTS = 600_000  # a channel with more segments is flattened a window at a time


def make_level(vi, r: float, zoom: float, n_segments: int = 0) -> Level:
    """The level at r nodes a source pixel: one window when small, else blocks."""
    nr, nc = int(np.ceil(vi.height * r - 1e-9)), int(np.ceil(vi.width * r - 1e-9))
    small = nr * nc <= SINGLE_NODES and n_segments <= SINGLE_SEGMENTS
    block = 0 if small else block_size(zoom / r)
    return Level(r, nr, nc, block)


class Buckets:
    """Indices of edges by the bands of ``size`` nodes their extent [lo, hi] reaches (widened
    by a node), in their original order within each band."""

    def __init__(self, lo, hi, size: int, n: int):
        first = np.clip(np.floor((lo - 1.0) / size), 0, n - 1).astype(np.int64)
        last = np.clip(np.floor((hi + 1.0) / size), 0, n - 1).astype(np.int64)
        count = np.maximum(last - first + 1, 0)
        edge = np.repeat(np.arange(len(lo)), count)
        bucket = np.repeat(first - np.cumsum(count) + count, count) + np.arange(len(edge))
        order = np.argsort(bucket, kind="stable")
        self.index = edge[order]
        self.starts = np.searchsorted(bucket[order], np.arange(n + 1))
        self.n = n

    def of(self, b0: int, b1: int) -> np.ndarray:
        """Edges reaching buckets b0..b1 (inclusive), each once, in original order."""
        b0, b1 = max(b0, 0), min(b1, self.n - 1)
        idx = self.index[self.starts[b0]:self.starts[b1 + 1]]
        if b0 == b1 or len(idx) == 0:
            return idx  # one bucket: ascending already
        lo = int(idx.min())
        mark = np.zeros(int(idx.max()) - lo + 1, np.bool_)
        mark[idx - lo] = True
        return np.flatnonzero(mark) + lo


class Buckets2D:
    """Indices of segments by the blocks (row, column) their bounding box reaches (widened
    by a node), in their original order within each block."""

    def __init__(self, x_lo, x_hi, y_lo, y_hi, size: int, nbr: int, nbc: int):
        r0 = np.clip(np.floor((y_lo - 1.0) / size), 0, nbr - 1).astype(np.int64)
        r1 = np.clip(np.floor((y_hi + 1.0) / size), 0, nbr - 1).astype(np.int64)
        c0 = np.clip(np.floor((x_lo - 1.0) / size), 0, nbc - 1).astype(np.int64)
        c1 = np.clip(np.floor((x_hi + 1.0) / size), 0, nbc - 1).astype(np.int64)
        nrow, ncol = r1 - r0 + 1, c1 - c0 + 1
        count = nrow * ncol
        seg = np.repeat(np.arange(len(r0)), count)
        k = np.arange(len(seg)) - np.repeat(np.cumsum(count) - count, count)  # rank within its segment
        row = r0[seg] + k // ncol[seg]
        col = c0[seg] + k % ncol[seg]
        bucket = row * nbc + col
        order = np.argsort(bucket, kind="stable")
        self.index = seg[order]
        self.starts = np.searchsorted(bucket[order], np.arange(nbr * nbc + 1))
        self.nbr, self.nbc = nbr, nbc

    def of(self, b0: int, b1: int, c0: int, c1: int) -> np.ndarray:
        """Segments reaching blocks rows b0..b1 x columns c0..c1, each once, ascending."""
        b0, b1, c0, c1 = max(b0, 0), min(b1, self.nbr - 1), max(c0, 0), min(c1, self.nbc - 1)
        parts = [self.index[self.starts[b * self.nbc + c0]:self.starts[b * self.nbc + c1 + 1]] for b in range(b0, b1 + 1)]
        idx = np.concatenate(parts) if parts else np.zeros(0, np.int64)
        if len(idx) == 0:
            return idx
        lo = int(idx.min())
        mark = np.zeros(int(idx.max()) - lo + 1, np.bool_)
        mark[idx - lo] = True
        return np.flatnonzero(mark) + lo


class ChannelLevel:
    """One channel at one level: its segments, flattened (at ``tol``) a window at a time
    from an index of their bounding boxes by block rows and columns (all at once on a
    one-window level), and the canvas-wide regions (blocked levels only). A segment's edges
    do not depend on which others are flattened with it, nor a window's bands and crossings
    on the edges that miss it."""

    def __init__(self, vi, ch, segs, border, tol: float, level: Level):
        self.ch, self.level, self.tol = ch, level, tol
        self.segs, self.border = segs, border
        self.glabels = self.gcapv = None
        self.edges = None
        if not level.block:
            self.edges = flatten(segs, border, tol)
            return
        r = level.r
        nbr, nbc = level.blocks()
        xs, ys = segs[:, :, 0], segs[:, :, 1]
        # bounding boxes in node units (the curve lies in its control points' hull)
        self.box = np.stack([xs.min(axis=1) * r, xs.max(axis=1) * r, ys.min(axis=1) * r, ys.max(axis=1) * r]).astype(np.float32)
        del xs, ys
        self.rows = Buckets(self.box[2], self.box[3], level.block, nbr)
        self.grid = Buckets2D(self.box[0], self.box[1], self.box[2], self.box[3], level.block, nbr, nbc)
        self._regions()

    def window_segments(self, i0: int, j0: int, n: int, m: int) -> np.ndarray:
        """Segments whose box reaches the window's nodes (widened by a node)."""
        B = self.level.block
        idx = self.grid.of(i0 // B, (i0 + n - 1) // B, j0 // B, (j0 + m - 1) // B)
        bx = self.box[:, idx]
        keep = (bx[1] >= j0 - 1) & (bx[0] <= j0 + m + 1) & (bx[3] >= i0 - 1) & (bx[2] <= i0 + n + 1)
        return idx[keep]

    def strip_segments(self, y_lo: float, y_hi: float) -> np.ndarray:
        """Segments whose box reaches node rows y_lo..y_hi (widened by a node)."""
        B = self.level.block
        idx = self.rows.of(int(y_lo // B), int(y_hi // B))
        bx = self.box[:, idx]
        return idx[(bx[3] >= y_lo - 1) & (bx[2] <= y_hi + 1)]

    def edges_of(self, idx):
        """Edges of the segments idx (ascending), in source pixels."""
        if idx is None:
            return self.edges
        return flatten(self.segs[idx], self.border[idx], self.tol)

    def _regions(self):
        """Bands of the whole level, a block row at a time, then their regions and cap values."""
        lv, ch = self.level, self.ch
        r, B = lv.r, lv.block
        band = np.empty((lv.nr, lv.nc), np.int16)
        for bi in range(lv.blocks()[0]):
            i0, n = bi * B, min(B, lv.nr - bi * B)
            x0, y0, x1, y1, src = self.edges_of(self.strip_segments(i0, i0 + n))
            band[i0:i0 + n], *_ = rasterise(x0 * r, y0 * r - i0, x1 * r, y1 * r - i0, src, 0, 0, n, lv.nc, False)
        band += np.int16(ch.base_band)
        labels, m = label_nodes(band)
        self.gcapv = cap_values(band, labels, m, ch.cap_xy[:, 0] * r, ch.cap_xy[:, 1] * r,
                                ch.cap_band.astype(np.int64), ch.cap_value)
        self.glabels, self.gband = labels, band

    def field(self, bi: int, bj: int, distance: str, smooth: bool, sharpen) -> NodeField:
        """The fields of block (bi, bj) on its window (the whole level when not blocked), in
        window node coordinates; NodeField.origin gives the window's first node."""
        lv, ch = self.level, self.ch
        i0, j0, n, m = lv.window(bi, bj)
        r = lv.r
        # a blocked window takes only the segments that reach it: the winding of those wholly
        # left of it is the canvas band's at its first column (the same edges, so the same sum)
        x0, y0, x1, y1, es = self.edges_of(self.window_segments(i0, j0, n, m) if lv.block else None)
        band, *h = rasterise(x0 * r - j0, y0 * r - i0, x1 * r - j0, y1 * r - i0, es, 0, 0, n, m, True)
        band += np.int16(ch.base_band)
        if lv.block:
            band += (self.gband[i0:i0 + n, j0] - band[:, 0])[:, None]
        _, *v = rasterise(y0 * r - i0, x0 * r - j0, y1 * r - i0, x1 * r - j0, es, 0, 0, m, n, True, True)
        mode = MODES[distance]
        F = seed(band, tuple(h), tuple(v), ch.levels, mode)
        del h, v
        propagate(F, band, offsets(mode), mode, MAX_SWEEPS)
        labels, nreg = label_nodes(band)
        if lv.block:
            none = np.zeros(0)
            dmax, _ = region_caps(F, band, labels, nreg, none, none, np.zeros(0, np.int64), none)
            capv = local_cap_values(labels, nreg, self.glabels[i0:i0 + n, j0:j0 + m], self.gcapv)
        else:
            dmax, capv = region_caps(F, band, labels, nreg, ch.cap_xy[:, 0] * r, ch.cap_xy[:, 1] * r,
                                     ch.cap_band.astype(np.int64), ch.cap_value)
        ramp = float(ch.cap_ramp) * r
        bw = band_widths(F, band, labels, dmax, capv, ramp) if smooth else np.zeros((0, 0, 2), np.float32)
        nv = np.empty((n, m), np.float32)
        evaluate(F, band, labels, dmax, capv, ramp, band, np.arange(m) + 0.5, np.arange(n) + 0.5,
                 ch.levels, mode, False, np.empty((0, 0), np.float32), nv, smooth, bw, np.empty((0, 0), np.float32))
        if max(sharpen) > 0.0:
            corr, nv = correction(nv, int(round(r)), float(sharpen[0]), float(sharpen[1]))
        else:
            corr = np.zeros((0, 0), np.float32)
        nf = NodeField(F, band, ch.levels, r, mode, None, ch.base_band, labels, dmax, capv, nv, smooth, bw,
                       ramp, corr)
        nf.origin = (i0, j0)
        return nf


def split(pos: np.ndarray, block: int, nb: int) -> list[tuple[int, int, int]]:
    """Runs of consecutive sample positions (node units, increasing) by the block they fall
    in: [(block index, first, stop)]."""
    if not block:
        return [(0, 0, len(pos))]
    b = np.clip(np.floor(pos / block), 0, nb - 1).astype(np.int64)
    cuts = np.flatnonzero(np.diff(b)) + 1
    starts = np.concatenate([[0], cuts])
    stops = np.concatenate([cuts, [len(pos)]])
    return [(int(b[a]), int(a), int(z)) for a, z in zip(starts, stops)]


def evaluate_piece(nf, tband, xs, ys, flat, out):
    """The fill of the samples tband (n, m) at node positions xs, ys (level coordinates)
    from one window's fields, into out (n, m)."""
    i0, j0 = nf.origin
    evaluate(nf.F, nf.band, nf.labels, nf.dmax, nf.capv, nf.ramp, tband, xs - j0, ys - i0, nf.levels, nf.mode, flat,
             nf.nv, out, nf.smooth, nf.bw, nf.corr)
