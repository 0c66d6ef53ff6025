"""Node fields in canvas-aligned blocks: a render whose cost follows its output.

A level is the node grid of one channel at one output scale: r nodes per source pixel
(levels.py). On a small level (at most SINGLE_NODES nodes) the fields are computed over the
whole level at once, as they always were. On a larger one the level is cut into square
blocks of ``block`` nodes, aligned on the level's origin (so the cut depends on the canvas
and the scale only, never on the crop or the strips), and each block's fields are computed
on a window of the block plus ``margin`` nodes on every side, from the edges that reach the
window only (the level's segment index lists them per block: segment_index.py). A target
sample reads the fields of the block its position falls in. Every crop
of a render therefore computes exactly the blocks it touches, with the same windows, and is
the same region of the full render; a render touches only the blocks under its samples.

What is global stays global, computed once per level by a canvas-wide pass that needs only
the bands (``CanvasRegions``: 6 bytes a node while it runs, 4 kept): which node region each
node belongs to, and each region's cap value (a cap's annotation may lie far outside the
window). So are the sources beyond a window: a node farther than the margin from every
source of a side (the middle of a band wider than twice the margin) would find a farther
one within its window, or none, where the whole-level sweep found one. Each blocked level
has a coarse field, the fields of the whole level at a node every ``Level.coarse`` nodes (at
most COARSE_NODES), computed once; a window's nodes on its cut edges are offered the sources
of the coarse nodes around them before the propagation (diffuse.offer_coarse), which carries
them inwards. On Kite (2560 x 1600) at 1x, against the one-window render, at a margin of 32:
values more than 0.5 off 7.6 % -> 2.3 % (the one-window render's own single sweep pair is
3.9 % off its converged fields), more than 2 off 1.1 % -> 0.17 %, for the same time
(benchmarks/results/block_sources.md).
A cap's d_max, its largest distance from the contour, is the window's own for a region
that lies wholly in the window, and the larger of that and the canvas region's as the
coarse field sees it (coarse_dmax) for one that leaves the window: it matters for caps
narrower than the cap ramp (2 source pixels by default) and for domes (an equalised
master's caps: an infinite ramp), which use it everywhere (a dome of radius 36 over 32-node
blocks: max 16 -> 4 levels off the one-window render; the coarse estimate is a node or so
short of the true largest distance).
"""

from __future__ import annotations

import contextvars
import threading
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from .. import threads
from ._kernels.diffuse import (D, NF, V, band_widths, evaluate, label_nodes, offer_coarse, offsets, propagate, region_caps,
                               seed)
from ._kernels.raster import rasterise, rasterise_chains, rasterise_window
from ..shared.spill import pager_or_none
from ._kernels.regions import cap_values, local_cap_values_runs, row_runs
from ._kernels.sharpen import correction
from .distance import MAX_SWEEPS, MODES, NodeField
from .segment_index import SegmentIndex

SINGLE_NODES = 2_500_000  # a level this small is one window (every corpus photograph up to 3x)
BLOCK = 256  # nodes a side of a block at or below 1x; smaller above (block_size)
# nodes of window around a block: with the coarse field's offers 16 is as close to the
# one-window render as 32 on the values more than 2 off, and 9-19 % cheaper a cold tile
# (measured: benchmarks/results/block_sources.md#margin)
MARGIN = 16
COARSE_NODES = 500_000  # at most this many nodes in a blocked level's coarse field
COARSE_TOL = 0.0125  # coarse nodes: the coarse field's flattening tolerance (0.05 px at 1/4)
WINDOW_BYTES = 72  # bytes a node of a kept window (fields 48, band, labels, fill, widths)
WINDOW_PEAK_BYTES = 120  # while it is computed (crossings), as distance.NODE_BYTES
# The canvas-wide passes of blocked levels (their regions, their coarse fields) run one at a
# time, whichever channel or render asks: each holds a level's bands and labels or a
# channel's edges while it runs, and side by side their memory adds up.
CANVAS_LOCK = threading.Lock()
MAX_RUNS = 0.5  # runs a node above which a blocked level keeps its labels whole (8 bytes a run, 4 a label)


def block_size(zoom_per_node: float) -> int:
    """Nodes a side of a block: BLOCK at or below one output pixel a node; above, the
    largest power of two of nodes within BLOCK output pixels (at least 32): a 256 x 256
    tile on its zoom's grid then lies in one block, whose window is its own nodes and the
    margin (2, 4 and 8 output pixels a node give 128, 64 and 32). Bigger blocks cost a full
    enlargement less margin (Kite's 2x render: 5.3 s with 256, 6.1-6.3 s with 128) but a
    cold tile 3.2 times the nodes at 2x (benchmarks/results/render_scale.md, "Blocks of a
    tile's size above 1x")."""
    b = BLOCK
    while b > 32 and zoom_per_node * b > BLOCK:
        b //= 2
    return b


@dataclass(frozen=True)
class Level:
    r: float  # nodes per source pixel
    nr: int
    nc: int
    block: int  # nodes a side; 0: one window over the level
    margin: int = 0  # nodes of window around a block (none on a one-window level)

    @property
    def nodes(self) -> int:
        return self.nr * self.nc

    @property
    def coarse(self) -> int:
        """k: a blocked level's coarse field has a node every k nodes a side (a power of 2, the
        least that keeps it within COARSE_NODES); 0 on a one-window level."""
        if not self.block:
            return 0
        k = 2
        while -(-self.nr // k) * -(-self.nc // k) > COARSE_NODES:
            k *= 2
        return k

    def coarse_level(self) -> "Level":
        """The one-window level of a blocked level's coarse field (r / k nodes a source pixel)."""
        k = self.coarse
        return Level(self.r / k, -(-self.nr // k), -(-self.nc // k), 0)

    def cuts(self, i0: int, j0: int, n: int, m: int) -> tuple[bool, bool, bool, bool]:
        """Which edges of the window (i0, j0, n, m) lie inside the level: top, bottom, left,
        right."""
        return i0 > 0, i0 + n < self.nr, j0 > 0, j0 + m < self.nc

    def blocks(self) -> tuple[int, int]:
        if not self.block:
            return 1, 1
        return -(-self.nr // self.block), -(-self.nc // self.block)

    def window(self, bi: int, bj: int) -> tuple[int, int, int, int]:
        """(i0, j0, n, m): the window of block (bi, bj), clipped to the level."""
        if not self.block:
            return 0, 0, self.nr, self.nc
        B, M = self.block, self.margin
        i0, j0 = max(bi * B - M, 0), max(bj * B - M, 0)
        i1, j1 = min((bi + 1) * B + M, self.nr), min((bj + 1) * B + M, self.nc)
        return i0, j0, i1 - i0, j1 - j0


SINGLE_SEGMENTS = 600_000  # a channel with more segments is flattened a window at a time
_WINDOW_NODES = contextvars.ContextVar("window_nodes", default=0)


@contextmanager
def one_window(max_nodes: int):
    """Within the block (this thread and context), a level of up to ``max_nodes`` luma nodes
    is one window, the fields that a blocked level approximates, whatever SINGLE_NODES says:
    for a caller that measures the fill itself (apply/equalise.py) and can afford
    max_nodes * WINDOW_PEAK_BYTES while it renders."""
    token = _WINDOW_NODES.set(int(max_nodes))
    try:
        yield
    finally:
        _WINDOW_NODES.reset(token)


def make_level(vi, r: float, zoom: float, n_segments: int = 0, fraction: float = 1.0) -> Level:
    """The level at r nodes a source pixel: one window when small, else blocks of
    block_size nodes with MARGIN nodes of margin.

    ``fraction``: the level's nodes a side per node of the luma's level at this zoom (the
    chroma's, levels.CHROMA_NODES): such a level is one window where the luma's is, so that
    a tile's chroma is blocked as its luma is."""
    nr, nc = int(np.ceil(vi.height * r - 1e-9)), int(np.ceil(vi.width * r - 1e-9))
    luma_nodes = int(np.ceil(vi.height * r / fraction - 1e-9)) * int(np.ceil(vi.width * r / fraction - 1e-9))
    if luma_nodes <= max(SINGLE_NODES, _WINDOW_NODES.get()) and n_segments <= SINGLE_SEGMENTS:
        return Level(r, nr, nc, 0)
    return Level(r, nr, nc, block_size(zoom / r), MARGIN)


class ChannelLevel:
    """One channel at one level: its segments indexed by the level's blocks and culled for
    its lattices (segment_index.py), flattened (at ``tol``) a window or a strip at a time (all
    at once on a one-window level), and the canvas-wide regions (blocked levels only). A
    segment's edges do not depend on which others are flattened with it, nor a window's
    bands and crossings on the edges that miss it."""

    def __init__(self, vi, ch, first, tol: float, level: Level, sample_rows=(0.0, 0.0), shared=None,
                 fields_only: bool = False):
        self.vi, self.ch, self.level, self.tol, self.shared = vi, ch, level, tol, shared
        self.gcapv = self.gruns = self.glabels = self.gband_cols = None
        self._coarse, self._coarse_lock = {}, threading.Lock()
        self.edges = self.pager = None
        self.index = SegmentIndex(ch.points, first, ch.border, level.r, level.block, level.nr, level.nc, sample_rows)
        if level.block and shared is None and len(self.index.index) >= PAGED_ENTRIES:
            # a render's big level reads its block lists and label runs a block row at a time,
            # in order: they wait on temporary files' pages, released after each strip
            self.pager = pager_or_none()
            if self.pager is not None:
                self.index.index = self.pager.put(self.index.index)
        if not level.block:
            # a level whose samples are read here keeps its edges; one that only gives fields
            # (a coarse field: ``fields_only``) flattens its segments as it rasterises them
            # (the same bands and crossings, bit for bit: raster.rasterise_chains), which for a
            # 16 MP photograph's luma is a gigabyte of edges and mapped copies less
            if not fields_only:
                self.edges = self.index.edges(None, tol)
            return
        self._regions()

    def window_segments(self, i0: int, j0: int, n: int, m: int) -> np.ndarray:
        """Segments whose box reaches the window's nodes (widened by a node)."""
        return self.index.window(i0, j0, n, m)

    def strip_segments(self, y_lo: float, y_hi: float, x_lo: float = -np.inf, x_hi: float = np.inf) -> np.ndarray:
        """Segments whose box reaches node rows y_lo..y_hi (widened by a node), and node
        columns x_lo..x_hi when given."""
        return self.index.rows(y_lo, y_hi, x_lo, x_hi)

    def rasterise(self, ids, kx, ox, ky, oy, swap, *args):
        """raster.rasterise(*args) of the segments ids (ascending) flattened at the level's tol
        and mapped to x * kx - ox, y * ky - oy (swapped with ``swap``): rasterise_chains."""
        ix = self.index
        return rasterise_chains(ix.points, ix.first, ix.border, ids, self.tol, kx, ox, ky, oy, swap, *args)

    def _regions(self):
        """Bands of the whole level, a block row at a time, then their regions and cap values."""
        lv, ch = self.level, self.ch
        r, B = lv.r, lv.block
        band = np.empty((lv.nr, lv.nc), np.int16)

        def block_row(bi):  # each fills its own rows: any order, any number of threads
            i0, n = bi * B, min(B, lv.nr - bi * B)
            band[i0:i0 + n], *_ = self.rasterise(self.strip_segments(i0, i0 + n), r, 0.0, r, float(i0), False,
                                                 0, 0, n, lv.nc, False)

        nbr = lv.blocks()[0]
        with threads.pool(threads.available(nbr)) as pool:
            list(pool.map(block_row, range(nbr)))
        band += np.int16(ch.base_band)
        labels, m = label_nodes(band)
        self.gcapv = cap_values(band, labels, m, *cap_positions(ch, r),
                                ch.cap_band.astype(np.int64), ch.cap_value)
        if self.pager is not None:  # read by label: a block row's regions lie mostly together
            self.gcapv = self.pager.put(self.gcapv)
        # what the windows read of the level's bands and labels is kept, not the whole (6
        # bytes a node: 98 MB a channel at 1x for 16 MP): the band of each window's first
        # column, the labels as runs along the rows (0.36 runs a node on the mosaic's luma,
        # 0.07 on its chroma: 8 bytes a run, 6 where the columns fit int16), and both at the
        # coarse field's node centres (a level whose labels change more often than every
        # second node keeps them whole: never more than the 4 bytes a node that limits_render
        # counts)
        runs = row_runs(labels)
        if lv.nc <= np.iinfo(np.int16).max:
            runs = (runs[0], runs[1].astype(np.int16), runs[2])
        if self.pager is not None:
            runs = (runs[0], self.pager.put(runs[1]), self.pager.put(runs[2]))
        self.gruns, self.glabels = (runs, None) if len(runs[1]) <= labels.size * MAX_RUNS else (None, labels)
        first_cols = sorted({lv.window(0, bj)[1] for bj in range(lv.blocks()[1])})
        self.gband_cols = {j: np.ascontiguousarray(band[:, j]) for j in first_cols}
        coarse, k = lv.coarse_level(), lv.coarse
        ii = np.minimum(np.arange(coarse.nr) * k + k // 2, lv.nr - 1)
        jj = np.minimum(np.arange(coarse.nc) * k + k // 2, lv.nc - 1)
        self.coarse_labels, self.coarse_bands = labels[np.ix_(ii, jj)], band[np.ix_(ii, jj)].astype(np.int64)
        del labels, band, runs
        self.release_pages()

    def release_pages(self) -> None:
        """The pages of the level's block lists, label runs, cap values and d_max that a
        render's big level keeps on temporary files (``pager``) out of the process's memory,
        to be read back from the page cache or the file as later strips need them: the same
        values (spill.Pager)."""
        if self.pager is not None:
            self.pager.release()

    def _window_caps(self, labels, nreg: int, i0: int, j0: int, values) -> np.ndarray:
        """values (one a canvas region) of each region of the window whose first node is
        (i0, j0): the canvas region's at its first node."""
        if self.gruns is not None:
            return local_cap_values_runs(labels, nreg, i0, j0, *self.gruns, values)
        n, m = labels.shape
        window = row_runs(np.ascontiguousarray(self.glabels[i0:i0 + n, j0:j0 + m]))
        return local_cap_values_runs(labels, nreg, 0, 0, *window, values)

    def _distances(self, i0: int, j0: int, n: int, m: int, mode: int):
        """The window's bands and distance fields (seeded, propagated), in window node
        coordinates."""
        lv, ch, r = self.level, self.ch, self.level.r
        # a blocked window takes only the segments that reach it: the winding of those wholly
        # left of it is the canvas band's at its first column (the same edges, so the same sum)
        if lv.block or self.edges is None:
            ids = self.window_segments(i0, j0, n, m) if lv.block else self.index.ids
            ix = self.index
            (band, *h), (_, *v) = rasterise_window(ix.points, ix.first, ix.border, ids, self.tol, r, float(j0),
                                                   float(i0), n, m)
        else:
            x0, y0, x1, y1, es = self.edges
            band, *h = rasterise(x0 * r - j0, y0 * r - i0, x1 * r - j0, y1 * r - i0, es, 0, 0, n, m, True)
            _, *v = rasterise(y0 * r - i0, x0 * r - j0, y1 * r - i0, x1 * r - j0, es, 0, 0, m, n, True, True)
        band += np.int16(ch.base_band)
        if lv.block:
            band += (self.gband_cols[j0][i0:i0 + n] - band[:, 0])[:, None]
        F = seed(band, tuple(h), tuple(v), ch.levels, mode)
        del h, v
        if lv.block:
            cuts = np.array(lv.cuts(i0, j0, n, m), np.int64)
            if cuts.any():
                offer_coarse(F, band, ch.levels, self.coarse_field(mode), lv.coarse, i0, j0, cuts, mode)
        propagate(F, band, offsets(mode), mode, MAX_SWEEPS)
        return band, F

    def coarse_field(self, mode: int) -> np.ndarray:
        """The fields (2, NF, nrc, ncc) of the whole level at a node every Level.coarse nodes
        (one window at 1/k of the level's nodes a side, flattened at COARSE_TOL of its node),
        what a blocked window's cut edges are offered (diffuse.offer_coarse), so that its
        nodes find the sources beyond it. Made once a metric; the levels of a channel with
        the same coarse grid (a preparation's zooms usually: 1x, 2x, 4x, ... share r / k)
        share it through the preparation when there is one (``shared``: Preparation)."""
        coarse = self.level.coarse_level()

        def make():
            with CANVAS_LOCK:
                cl = ChannelLevel(self.vi, self.ch, self.index.first, COARSE_TOL / coarse.r, coarse, fields_only=True)
                return cl._distances(0, 0, coarse.nr, coarse.nc, mode)[1]

        key = (self.ch.name, coarse, mode)
        if self.shared is not None:
            return self.shared.get(self.shared.coarse, key, make)
        with self._coarse_lock:
            if key not in self._coarse:
                self._coarse[key] = make()
            return self._coarse[key]

    def coarse_dmax(self, mode: int) -> np.ndarray:
        """(2, regions): each canvas region's largest distance from its lower and upper
        sources as the coarse field sees it (its nodes' distances, in the level's node
        units, by the canvas region of the level node at each coarse node's centre); each
        side a contiguous row, which a window reads where its regions' labels point (a
        render's big level keeps it on its pager's files)."""
        with self._coarse_lock:
            out = self._coarse.get(("dmax", mode))
        if out is None:
            Fc, k = self.coarse_field(mode), self.level.coarse
            g, b = self.coarse_labels, self.coarse_bands  # the level's at the coarse nodes' centres
            lv = self.ch.levels.astype(np.float32)
            nl = len(lv)
            out = np.zeros((2, len(self.gcapv)))
            for s in range(2):
                d = Fc[s, D].astype(np.float64) * k
                # a coarse node's source counts for the level node's region where it is of the
                # level that side has in the node's band (else the coarse node lies in another)
                want = b - 1 + s
                ok = np.isfinite(d) & (want >= 0) & (want < nl)
                ok[ok] &= Fc[s, V][ok] == lv[want[ok]]
                np.maximum.at(out[s], g[ok], d[ok])
            if self.pager is not None:
                out = self.pager.put(out)
            with self._coarse_lock:
                self._coarse[("dmax", mode)] = out
        return out

    def field(self, bi: int, bj: int, distance: str, smooth: bool, sharpen) -> NodeField:
        """The fields of block (bi, bj) on its window (the whole level when not blocked), in
        window node coordinates; NodeField.origin gives the window's first node."""
        lv, ch = self.level, self.ch
        i0, j0, n, m = lv.window(bi, bj)
        r = lv.r
        mode = MODES[distance]
        band, F = self._distances(i0, j0, n, m, mode)
        labels, nreg = label_nodes(band)
        if lv.block:
            none = np.zeros(0)
            dmax, _ = region_caps(F, band, labels, nreg, none, none, np.zeros(0, np.int64), none)
            capv = self._window_caps(labels, nreg, i0, j0, self.gcapv)
            # a region that leaves the window: its d_max is at least the canvas region's as
            # the coarse field sees it (coarse_dmax); one within the window keeps its own
            cuts = lv.cuts(i0, j0, n, m)
            if any(cuts):
                leaves = np.zeros(nreg, bool)
                for cut, edge in zip(cuts, (labels[0], labels[-1], labels[:, 0], labels[:, -1])):
                    if cut:
                        leaves[edge] = True
                gd = self.coarse_dmax(mode)
                for s in range(2):
                    wide = self._window_caps(labels, nreg, i0, j0, gd[s])
                    dmax[:, s] = np.where(leaves, np.maximum(dmax[:, s], wide), dmax[:, s])
        else:
            dmax, capv = region_caps(F, band, labels, nreg, *cap_positions(ch, r),
                                     ch.cap_band.astype(np.int64), ch.cap_value)
        ramp = float(ch.cap_ramp) * r
        # the node fill where samples read it: a blocked window's samples lie in its block, and
        # read the nodes of their cell, so the block and a ring of one node; sharpened, the
        # correction at those reads the fill rr nodes further (sharpen.correction), so rr more
        # (the nodes beyond stay NaN, and so do their corrections, which no sample reads)
        a0, a1, c0, c1 = 0, n, 0, m
        sharpened, rr = max(sharpen) > 0.0, int(round(r))
        if lv.block:
            B, ring = lv.block, 1 + (rr if sharpened else 0)
            a0, a1 = max(bi * B - ring - i0, 0), min((bi + 1) * B + ring - i0, n)
            c0, c1 = max(bj * B - ring - j0, 0), min((bj + 1) * B + ring - j0, m)
        bw = band_widths(F, band, labels, dmax, capv, ramp) if smooth else np.zeros((0, 0, 2), np.float32)
        nv = np.full((n, m), np.nan, np.float32)
        core = np.empty((a1 - a0, c1 - c0), np.float32)
        evaluate(F, band, labels, dmax, capv, ramp, np.ascontiguousarray(band[a0:a1, c0:c1]), np.arange(c0, c1) + 0.5,
                 np.arange(a0, a1) + 0.5, ch.levels, mode, False, np.empty((0, 0), np.float32), core, smooth, bw,
                 np.empty((0, 0), np.float32))
        nv[a0:a1, c0:c1] = core
        if sharpened:
            corr, nv = correction(nv, rr, float(sharpen[0]), float(sharpen[1]))
        else:
            corr = np.zeros((0, 0), np.float32)
        nf = NodeField(F, band, ch.levels, r, mode, None, ch.base_band, labels, dmax, capv, nv, smooth, bw,
                       ramp, corr)
        nf.origin = (i0, j0)
        return nf


# Entries of a level's block lists from which an unprepared render keeps them, its runs of
# region labels and its regions' cap values and coarse d_max on temporary files, read a block
# row at a time (4 M: 16 MB of lists; the mosaic's `high` luma has 11 M, with 46 MB of runs
# and 4.4 M regions, 100 MB of values; a preparation's levels, read in any order, keep theirs)
PAGED_ENTRIES = 1 << 22


def cap_positions(ch, r: float):
    """(x, y) float64 of the caps' samples in node units at r nodes a source pixel, computed
    in float64 from cap_xy whatever its dtype (float32 in a compact master: the same values)."""
    return np.multiply(ch.cap_xy[:, 0], r, dtype=np.float64), np.multiply(ch.cap_xy[:, 1], r, dtype=np.float64)


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


def flat_piece(levels, tband, out):
    """The flat fill of the samples tband (n, m) into out: the middle of each sample's band,
    which reads no field (evaluate's flat path, given empty ones), so a flat render
    computes none."""
    n, m = tband.shape
    e2, e1 = np.zeros((0, 0), np.float32), np.zeros(0)
    evaluate(np.zeros((0, 0, 2, NF), np.float32).transpose((2, 3, 0, 1)), np.zeros((0, 0), np.int16),
             np.zeros((0, 0), np.int32), np.zeros((0, 2)), e1, 0.0, tband, np.zeros(m), np.zeros(n), levels, 0, True,
             e2, out, False, np.zeros((0, 0, 2), np.float32), e2)


def evaluate_piece(nf, tband, xs, ys, out):
    """The fill of the samples tband (n, m) at node positions xs, ys (level coordinates)
    from one window's fields, into out (n, m)."""
    i0, j0 = nf.origin
    evaluate(nf.F, nf.band, nf.labels, nf.dmax, nf.capv, nf.ramp, tband, xs - j0, ys - i0, nf.levels, nf.mode, False,
             nf.nv, out, nf.smooth, nf.bw, nf.corr)
