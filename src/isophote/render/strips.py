"""One strip of output rows of one channel, read from the block fields (blocks.py).

A channel renders from a ChannelLevel (its level, edges and regions) through a BlockCache
(the block fields it has computed, least recently used first out). Strips follow the block
rows of the first blocked channel, so that a full render computes every block once and
keeps at most a row of blocks (the ones a straddling output row still needs). A strip's
blocks are computed and filled a group at a time, a block per thread the process may use,
so that a channel much costlier than the others (a dense luma beside smooth chroma) does not
leave a processor idle, and only a group's windows are held beyond that row; the flat fill
reads no field and computes none.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

from .. import threads
from ..model import apply_tone_curve
from ._kernels.raster import rasterise, row_windings
from .blocks import WINDOW_BYTES, evaluate_piece, flat_piece, split

STRIP_ROWS = 128  # output rows per strip of a one-window render
SAMPLE_BUCKET = 64  # sample rows per bucket of the samples' edge index
WINDING_STEP = 128  # sample columns per bin of a preparation's row windings


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
        self.n, self.size = n, size

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


class FieldBudget:
    """Bytes of block fields that several BlockCaches hold together (a preparation's: every
    channel at every zoom), the least recently used block of any of them out first."""

    def __init__(self, capacity: int):
        self.capacity = capacity
        self.bytes = 0
        self.order = OrderedDict()  # (id(cache), key) -> (cache, bytes)
        self.lock = threading.Lock()

    def used(self, cache, key) -> None:
        with self.lock:
            if (id(cache), key) in self.order:
                self.order.move_to_end((id(cache), key))

    def add(self, cache, key, nbytes: int) -> list:
        """Count a block in; returns the (cache, key) of the blocks to let go (never the new
        one): the caller pops them from their caches."""
        with self.lock:
            self.order[(id(cache), key)] = (cache, nbytes)
            self.bytes += nbytes
            out = []
            while self.bytes > self.capacity and len(self.order) > 1:
                (_, k), (c, b) = self.order.popitem(last=False)
                self.bytes -= b
                out.append((c, k))
            return out

    def remove(self, cache, key) -> None:
        with self.lock:
            got = self.order.pop((id(cache), key), None)
            if got is not None:
                self.bytes -= got[1]


class FieldSlots:
    """At most as many block fields computed at once in the process as it may use threads
    (threads.available, asked at each start): the channels' strips run side by side, each
    prefetching a group, and without this up to a group per channel (six windows' working
    arrays, about 12 MB each at 1x) were made at once on two processors. A field does not
    depend on when it is computed."""

    def __init__(self):
        self.cv = threading.Condition()
        self.busy = 0

    def __enter__(self):
        with self.cv:
            self.cv.wait_for(lambda: self.busy < threads.available())
            self.busy += 1

    def __exit__(self, *exc):
        with self.cv:
            self.busy -= 1
            self.cv.notify()


FIELD_SLOTS = FieldSlots()


class BlockCache:
    """The fields of one channel's blocks, computed on demand (thread-safe, one at a time),
    within ``capacity`` bytes, or within a FieldBudget shared with other caches."""

    def __init__(self, cl, distance: str, smooth: bool, sharpen, capacity: int, budget: FieldBudget | None = None):
        self.cl, self.distance, self.smooth, self.sharpen = cl, distance, smooth, sharpen
        self.capacity = capacity if budget is None else budget.capacity
        self.budget = budget
        self.blocks = OrderedDict()
        self.bytes = 0
        self.lock = threading.RLock()

    def get(self, bi: int, bj: int):
        with self.lock:
            nf = self.blocks.get((bi, bj))
            if nf is not None:
                self.blocks.move_to_end((bi, bj))
                if self.budget is not None:
                    self.budget.used(self, (bi, bj))
                return nf
            return self._put((bi, bj), self._field((bi, bj)))

    def prefetch(self, keys) -> None:
        """Compute the fields of the blocks ``keys`` not held yet at once, on the threads the
        process may use (as many as the capacity holds): a block's fields do not depend on
        which others are computed, nor when, so this changes the time only."""
        with self.lock:
            lv = self.cl.level
            missing = [k for k in keys if k not in self.blocks]
            if len(missing) < 2:
                return
            _, _, n, m = lv.window(*missing[0])
            missing = missing[:max(1, self.capacity // ((n * m) * WINDOW_BYTES))]
            with threads.pool(threads.available(len(missing))) as pool:
                fields = list(pool.map(self._field, missing))
            for k, nf in zip(missing, fields):
                self._put(k, nf)

    def _field(self, key):
        with FIELD_SLOTS:
            return self.cl.field(key[0], key[1], self.distance, self.smooth, self.sharpen)

    def _put(self, key, nf):
        self.blocks[key] = nf
        self.bytes += nf.band.size * WINDOW_BYTES
        if self.budget is not None:
            # another cache's block is popped without its lock (that would order locks across
            # caches): a reader already holding the block keeps it; its next get recomputes it
            for cache, k in self.budget.add(self, key, nf.band.size * WINDOW_BYTES):
                gone = cache.blocks.pop(k, None)
                if gone is not None:
                    cache.bytes -= gone.band.size * WINDOW_BYTES
            return nf
        while self.bytes > self.capacity and len(self.blocks) > 1:
            _, old = self.blocks.popitem(last=False)
            self.bytes -= old.band.size * WINDOW_BYTES
        return nf

    def drop(self, bi: int, bj: int) -> None:
        with self.lock:
            nf = self.blocks.pop((bi, bj), None)
            if nf is not None:
                self.bytes -= nf.band.size * WINDOW_BYTES
                if self.budget is not None:
                    self.budget.remove(self, (bi, bj))


class SampleEdges:
    """A channel's edges in target-sample units. On a one-window level
    all of them, indexed by buckets of SAMPLE_BUCKET sample rows; on a blocked level the
    segments of the block rows a strip reaches, flattened for that strip. The bands do not
    depend on which extra edges a strip is given (a winding sum of the edges that cross its
    rows), so any strip cut gives the same samples."""

    def __init__(self, cl, vp, n_rows: int, windings=None, buckets=None):
        self.cl, self.vp = cl, vp
        self.windings = windings  # (row_windings of the whole canvas, its step), for crops
        self.buckets = buckets  # a preparation's (canvas_buckets): of the canvas's sample rows
        self.X0 = None
        if cl.level.block:
            return
        self.row0 = vp.row0 if buckets is not None else 0  # the buckets' first sample row
        if buckets is not None:  # a crop of a prepared master: its rows' edges only (band)
            return
        self.X0, self.Y0, self.X1, self.Y1 = to_samples(cl.edges, vp)
        self.src = cl.edges[4]
        lo = np.minimum(self.Y0, self.Y1) - vp.row0
        hi = np.maximum(self.Y0, self.Y1) - vp.row0
        self.buckets = Buckets(lo, hi, SAMPLE_BUCKET, max(1, -(-n_rows // SAMPLE_BUCKET)))

    def band(self, ys, a0: int, n: int, m: int) -> np.ndarray:
        """Bands of sample rows [a0, a0 + n) of the output (at node rows ys), m columns."""
        vp, cl = self.vp, self.cl
        if cl.level.block and self.windings is not None:
            tband = self._crop_band(ys, a0, n, m)
        elif cl.level.block:
            tband, *_ = cl.rasterise(cl.strip_segments(ys[a0], ys[a0 + n - 1]), vp.kx, vp.offx, vp.ky, vp.offy, False,
                                     vp.row0 + a0, vp.col0, n, m, False)
        else:
            b0, b1 = self.row0 + a0, self.row0 + a0 + n - 1
            sel = self.buckets.of(b0 // self.buckets.size, b1 // self.buckets.size)
            if self.X0 is None:  # the canvas's buckets: map only the edges these rows read (the same values)
                X0, Y0, X1, Y1 = to_samples([v[sel] for v in cl.edges[:4]], vp)
                src = cl.edges[4][sel]
            else:
                X0, Y0, X1, Y1, src = self.X0[sel], self.Y0[sel], self.X1[sel], self.Y1[sel], self.src[sel]
            tband, *_ = rasterise(X0, Y0, X1, Y1, src, vp.row0 + a0, vp.col0, n, m, False)
        tband += np.int16(cl.ch.base_band)
        return tband

    def _crop_band(self, ys, a0: int, n: int, m: int) -> np.ndarray:
        """A crop's bands from the edges that reach it and those between it and the bin of
        columns left of it, plus the windings of everything left of that bin (row_windings):
        the same sums as the whole rows', at the cost of the crop's columns."""
        vp, cl = self.vp, self.cl
        W, step = self.windings
        c = vp.col0 // step
        kc = c * step
        r = cl.level.r
        x_lo = (kc - 1.5 + vp.offx) / vp.kx * r - 2.0
        x_hi = (vp.col0 + m + 0.5 + vp.offx) / vp.kx * r + 2.0
        ids = cl.strip_segments(ys[a0], ys[a0 + n - 1], x_lo, x_hi)
        part, *_ = cl.rasterise(ids, vp.kx, vp.offx, vp.ky, vp.offy, False, vp.row0 + a0, kc - 1, n,
                                vp.col0 + m - kc + 1, False)
        left = W[vp.row0 + a0:vp.row0 + a0 + n, c] - part[:, 0]
        return (part[:, vp.col0 - kc + 1:] + left[:, None]).astype(np.int16)


def to_samples(edges, vp):
    """(X0, Y0, X1, Y1): edges (x0, y0, x1, y1, ...) in source pixels mapped to the
    viewport's global sample lattice."""
    x0, y0, x1, y1 = edges[:4]
    return x0 * vp.kx - vp.offx, y0 * vp.ky - vp.offy, x1 * vp.kx - vp.offx, y1 * vp.ky - vp.offy


def canvas_buckets(cl, vp, canvas_h: float) -> Buckets:
    """A one-window level's edges by the buckets of SAMPLE_BUCKET sample rows of the whole
    canvas at this viewport's lattice (global sample rows from 0): what a preparation keeps so
    that a crop maps and rasterises only the edges of its own rows (SampleEdges.band). A
    strip given more edges than those that cross its rows has the same bands."""
    _, Y0, _, Y1 = to_samples(cl.edges, vp)
    n_rows = int(np.ceil(canvas_h * vp.ky - vp.offy)) + 1
    return Buckets(np.minimum(Y0, Y1), np.maximum(Y0, Y1), SAMPLE_BUCKET, max(1, -(-n_rows // SAMPLE_BUCKET)))


def crop_windings(cl, vp, canvas_w: float, canvas_h: float):
    """row_windings of every sample row of the canvas at this viewport's lattice, bins of
    WINDING_STEP sample columns: what a preparation keeps so that crops rasterise only their
    own columns (SampleEdges._crop_band)."""
    n_rows = int(np.ceil(canvas_h * vp.ky - vp.offy)) + 1
    n_bins = int(np.ceil(canvas_w * vp.kx - vp.offx)) // WINDING_STEP + 2
    ix = cl.index
    W = row_windings(ix.points, ix.first, ix.border, ix.ids, cl.tol, vp.kx, vp.offx, vp.ky, vp.offy, 0, n_rows,
                     WINDING_STEP, n_bins)
    return W, WINDING_STEP


def sample_positions(vp, r: float):
    """Node coordinates of the output's sample columns and rows at r nodes a source pixel."""
    xs = (vp.col0 + np.arange(vp.out_w * vp.s) + 0.5 + vp.offx) / vp.kx * r
    ys = (vp.row0 + np.arange(vp.out_h * vp.s) + 0.5 + vp.offy) / vp.ky * r
    return xs, ys


def covered_blocks(lv, xs, ys) -> list[tuple[int, int]]:
    """The blocks of level lv every sample of whose lattice (the render's: columns xs, rows
    ys, node units, evenly spaced) the render reads: the lattice's samples before and after
    the render's lie in other blocks, or off the level. A block-cache policy (a block left
    out is recomputed if asked again, one kept costs memory): the pixels do not depend on it."""
    if not lv.block or len(xs) < 2 or len(ys) < 2:
        return []
    nbr, nbc = lv.blocks()

    def spans(pos, nb, extent):
        step = pos[1] - pos[0]
        out = []
        for b, _, _ in split(pos, lv.block, nb):
            lo, hi = b * lv.block, min((b + 1) * lv.block, extent)
            if pos[0] - step < lo and pos[-1] + step >= hi:
                out.append(b)
        return out

    return [(bi, bj) for bi in spans(ys, nbr, lv.nr) for bj in spans(xs, nbc, lv.nc)]


def strip_cuts(vp, level, ys) -> list[tuple[int, int]]:
    """Output row ranges of the strips: STRIP_ROWS rows, or for a blocked level the runs of
    output rows whose first sample row lies in one block row (at most 2 * BLOCK rows)."""
    if not level.block:
        return [(r0, min(r0 + STRIP_ROWS, vp.out_h)) for r0 in range(0, vp.out_h, STRIP_ROWS)]
    first = ys[:: vp.s][: vp.out_h]
    cuts = []
    for _, a, z in split(first, level.block, level.blocks()[0]):
        for r0 in range(a, z, 2 * level.block):
            cuts.append((r0, min(r0 + 2 * level.block, z)))
    return cuts


def fill_rows(cache: BlockCache, sedges: SampleEdges, vp, xs, ys, out_r0: int, out_r1: int, flat: bool,
              tone, last_use=None) -> np.ndarray:
    """Output rows [out_r0, out_r1) of one channel, (rows, out_w) float32. last_use: block
    row -> the last output row that reads it; blocks past it are let go."""
    return finish(fill_samples(cache, sedges, vp, xs, ys, out_r0, out_r1, flat, last_use), tone, vp.s)


def finish(out: np.ndarray, tone, s: int) -> np.ndarray:
    """A strip's samples (n, m), C-contiguous, to its output pixels: the tone curve, then the
    s x s box filter."""
    out = apply_tone_curve(out, tone)
    if s > 1:
        n, m = out.shape
        out = out.reshape(n // s, s, m // s, s).mean(axis=(1, 3), dtype=np.float64).astype(np.float32)
    return out


def fill_samples(cache: BlockCache, sedges: SampleEdges, vp, xs, ys, out_r0: int, out_r1: int, flat: bool,
                 last_use=None) -> np.ndarray:
    """The samples of output rows [out_r0, out_r1) of one channel, (rows x s, out_w x s)
    float32, before the tone curve and the box filter (finish)."""
    cl = cache.cl
    lv = cl.level
    s = vp.s
    a0, a1 = out_r0 * s, out_r1 * s
    n, m = a1 - a0, vp.out_w * s
    tband = sedges.band(ys, a0, n, m)
    out = np.empty((n, m), np.float32)
    if flat:
        flat_piece(cl.ch.levels, tband, out)  # the bands' middles: no field is read
    else:
        nbr, nbc = lv.blocks()
        col_runs = split(xs, lv.block, nbc)
        jobs = [(bi, bj, p0, p1, c0, c1) for bi, p0, p1 in split(ys[a0:a1], lv.block, nbr) for bj, c0, c1 in col_runs]

        def piece(job):  # each writes its own samples: any order, any number of threads
            nf, p0, p1, c0, c1 = job
            part = np.empty((p1 - p0, c1 - c0), np.float32)
            evaluate_piece(nf, np.ascontiguousarray(tband[p0:p1, c0:c1]), xs[c0:c1], ys[a0 + p0:a0 + p1], part)
            out[p0:p1, c0:c1] = part

        # a group of blocks per thread at a time: computed together, filled, let go when no
        # later strip reads them, so only a group's windows are in memory at once
        width = threads.available(len(jobs))
        for g in range(0, len(jobs), width):
            group = jobs[g:g + width]
            cache.prefetch([(bi, bj) for bi, bj, *_ in group])
            pieces = [(cache.get(bi, bj), *rest) for bi, bj, *rest in group]
            if len(pieces) == 1:
                piece(pieces[0])
            else:
                with threads.pool(len(pieces)) as pool:
                    list(pool.map(piece, pieces))
            del pieces
            for bi, bj, *_ in group:
                if last_use is not None and lv.block and last_use.get(bi, -1) <= out_r1:
                    cache.drop(bi, bj)  # no later strip reads this block
    cl.release_pages()  # the level's paged lists and runs this strip read (a big render's: blocks.PAGED_ENTRIES)
    return out
