"""The level's segment index (render/segment_index.py): its kernels against their NumPy twins,
and culling: a culled segment crosses no node row or column and no sample row, so the bands
and crossings of the kept edges equal those of all the edges."""

from __future__ import annotations

import numpy as np
import pytest

from isophote.geometry import flatten, flatten_selected
from isophote.render._kernels import index as K
from isophote.render._kernels import index_ref as R
from isophote.render._kernels.raster import rasterise
from kernel_inputs import SEEDS


def _chains(rng, n=300, span=60.0, size=3.0):
    """n random cubic segments (most smaller than a node at the levels below), their control
    points on the file's 1/64 grid as stored, as (points, first)."""
    p0 = rng.uniform(0, span, (n, 1, 2))
    segs = p0 + rng.uniform(-size, size, (n, 4, 2)) * rng.uniform(0.05, 1.0, (n, 1, 1))
    segs = np.round(segs * 64) / 64
    return segs.reshape(-1, 2), np.arange(n) * 4, segs


@pytest.mark.parametrize("seed", SEEDS)
def test_index_kernels_match_their_twins(seed):
    rng = np.random.default_rng(900 + seed)
    points, first, _ = _chains(rng)
    for r, cull, sky, soff in [(1.0, False, 0.0, 0.0), (0.25, True, 0.0, 0.0), (0.125, True, 0.25, 0.3)]:
        ids = K.kept_segments(points, first, r, cull, sky, soff)
        assert np.array_equal(ids, R.kept_segments(points, first, r, cull, sky, soff)) and ids.dtype == np.int32
        assert cull or len(ids) == len(first)
        box = R.segment_boxes(points, first, ids, r)  # the boxes the kernels test (index._node_box)
        assert box.dtype == np.float32
        size, nbr, nbc = 4, int(np.ceil(64 * r / 4)) + 1, int(np.ceil(64 * r / 4)) + 2
        index, starts = K.grid_index(points, first, ids, r, size, nbr, nbc)
        index_r, starts_r = R.grid_index(points, first, ids, r, size, nbr, nbc)
        assert np.array_equal(index, index_r) and np.array_equal(starts, starts_r)
        for _ in range(5):
            b0, c0 = rng.integers(0, nbr), rng.integers(0, nbc)
            b1, c1 = rng.integers(b0, nbr), rng.integers(c0, nbc)
            lims = (float(c0 * size - 1), float((c1 + 1) * size + 1), float(b0 * size - 1), float((b1 + 1) * size + 1))
            got = K.select(index, starts, nbc, b0, b1, c0, c1, points, first, r, *lims)
            assert np.array_equal(got, R.select(index, starts, nbc, b0, b1, c0, c1, points, first, r, *lims))
            assert np.all(np.diff(got) > 0)
            # the known answer: every kept segment whose box reaches the blocks and the limits
            reach = ((box[1] >= lims[0]) & (box[0] <= lims[1]) & (box[3] >= lims[2]) & (box[2] <= lims[3])
                     & (box[3] + 1 >= b0 * size) & (box[2] - 1 < (b1 + 1) * size)
                     & (box[1] + 1 >= c0 * size) & (box[0] - 1 < (c1 + 1) * size))
            assert np.array_equal(got, ids[np.flatnonzero(reach)])


def test_flatten_selected_is_flatten_of_those_segments():
    rng = np.random.default_rng(5)
    points, first, segs = _chains(rng, 50)
    border = rng.random(50) < 0.2
    ids = np.sort(rng.choice(50, 20, replace=False))
    for a, b in zip(flatten_selected(points, first, border, ids, 0.05), flatten(segs[ids], border[ids], 0.05)):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("r", [1.0, 0.25, 0.0625])
def test_culled_segments_change_no_band_or_crossing(r):
    """Rasterised on the node rows and columns and on the sample rows, the kept segments'
    edges give the same bands and crossings as all of them, while most are culled."""
    rng = np.random.default_rng(11)
    points, first, segs = _chains(rng, 2000, span=64.0, size=1.5)
    border = rng.random(len(first)) < 0.1
    sky = 2 * r  # the samples of a reduction: two a pixel side
    ids = K.kept_segments(points, first, r, True, sky, 0.0)
    if r < 1:
        assert len(ids) < 0.8 * len(first)
    for scale, transposed in [(r, False), (r, True), (sky, False)]:
        res = []
        for sel in (np.arange(len(first)), ids):
            x0, y0, x1, y1, src = flatten_selected(points, first, border, sel, 0.01)
            if transposed:
                x0, y0, x1, y1 = y0, x0, y1, x1
            m = int(np.ceil(64 * scale)) + 1
            res.append(rasterise(x0 * scale, y0 * scale, x1 * scale, y1 * scale, src, 0, 0, m, m, True, transposed))
        for a, b in zip(*res):
            assert np.array_equal(a, b)


@pytest.mark.parametrize("seed", SEEDS)
def test_rasterise_chains_is_rasterise_of_the_flattened_edges(seed):
    """The fused kernel gives the band and every crossing array of flattening then
    rasterising, bit for bit, in both orientations; its band matches the NumPy twin."""
    from isophote.render._kernels.raster import rasterise_chains
    from isophote.render._kernels.raster_ref import rasterise_chains as rasterise_chains_ref

    rng = np.random.default_rng(700 + seed)
    points, first, _ = _chains(rng, 80, span=30.0, size=4.0)
    border = rng.random(80) < 0.2
    ids = np.sort(rng.choice(80, 50, replace=False))
    tol = 0.05
    for kx, ox, ky, oy, swap, transposed in [(1.0, 0.0, 1.0, 0.0, False, False), (0.5, 3.0, 0.5, 2.0, True, True),
                                             (1.5, 0.25, 1.5, 0.75, False, False)]:
        x0, y0, x1, y1, src = flatten_selected(points, first, border, ids, tol)
        x0, x1, y0, y1 = x0 * kx - ox, x1 * kx - ox, y0 * ky - oy, y1 * ky - oy
        if swap:
            x0, y0, x1, y1 = y0, x0, y1, x1
        for row0, col0, n, m in [(0, 0, 30, 40), (4, -3, 12, 17)]:
            a = rasterise(x0, y0, x1, y1, src, row0, col0, n, m, True, transposed)
            b = rasterise_chains(points, first, border, ids, tol, kx, ox, ky, oy, swap, row0, col0, n, m, True,
                                 transposed)
            for u, v in zip(a, b):
                assert np.array_equal(u, v)
            ref = rasterise_chains_ref(points, first, border, ids, tol, kx, ox, ky, oy, swap, row0, col0, n, m,
                                       transposed)
            assert np.array_equal(b[0], ref)


@pytest.mark.parametrize("seed", SEEDS)
def test_row_windings_match_the_band_left_of_each_bin(seed):
    """row_windings against its twin (the band of whole rows read at each bin's left), and a
    crop's band rebuilt from them and the edges right of its bin equals the whole row's."""
    from isophote.render._kernels.raster import rasterise_chains, row_windings
    from isophote.render._kernels.raster_ref import row_windings as row_windings_ref

    rng = np.random.default_rng(800 + seed)
    points, first, _ = _chains(rng, 120, span=40.0, size=5.0)
    border = rng.random(120) < 0.2
    ids = np.arange(120)
    kx, ox, ky, oy, step = 1.5, 0.0, 1.5, 0.0, 8
    w = row_windings(points, first, border, ids, 0.05, kx, ox, ky, oy, 2, 40, step, 9)
    assert np.array_equal(w, row_windings_ref(points, first, border, ids, 0.05, kx, ox, ky, oy, 2, 40, step, 9))
    full = rasterise_chains(points, first, border, ids, 0.05, kx, ox, ky, oy, False, 2, 0, 40, 64, False)[0]
    for col0, m in [(0, 10), (13, 20), (40, 24)]:
        c = col0 // step
        part = rasterise_chains(points, first, border, ids, 0.05, kx, ox, ky, oy, False, 2, c * step - 1, 40,
                                col0 + m - c * step + 1, False)[0]
        got = w[:, c:c + 1] + part[:, col0 - c * step + 1:] - part[:, :1]
        assert np.array_equal(got, full[:, col0:col0 + m])


def test_rasterise_window_is_rows_and_columns():
    from isophote.render._kernels.raster import rasterise_chains, rasterise_window

    rng = np.random.default_rng(3)
    points, first, _ = _chains(rng, 100, span=30.0, size=4.0)
    border = rng.random(100) < 0.2
    ids = np.arange(0, 100, 2)
    rows, cols = rasterise_window(points, first, border, ids, 0.05, 0.5, 2.0, 3.0, 11, 13)
    a = rasterise_chains(points, first, border, ids, 0.05, 0.5, 2.0, 0.5, 3.0, False, 0, 0, 11, 13, True)
    b = rasterise_chains(points, first, border, ids, 0.05, 0.5, 2.0, 0.5, 3.0, True, 0, 0, 13, 11, True, True)
    for u, v in zip(rows + cols, a + b):
        assert np.array_equal(u, v)


def test_segment_firsts_are_the_chains_segment_starts():
    """Each segment's first control point, int32, against chains.segment_starts and the
    NumPy twin: chains of 1, 2 and 5 segments and an empty channel."""
    from isophote.geometry import segment_starts
    from isophote.render.segment_index import segment_firsts

    offsets = np.array([0, 4, 11, 27, 31], np.int64)  # 1, 2, 5 and 1 segments
    got = segment_firsts(offsets)
    assert got.dtype == np.int32
    assert got.tolist() == [0, 4, 7, 11, 14, 17, 20, 23, 27]
    assert np.array_equal(got, segment_starts(offsets)[0])
    assert np.array_equal(R.fill_firsts(offsets, np.empty(9, np.int32)), got)
    assert segment_firsts(np.zeros(1, np.int64)).shape == (0,)


@pytest.mark.parametrize("seed", SEEDS)
def test_windows_and_rows_read_every_segment_that_reaches_them(seed):
    """The index's cells (BIN nodes, finer than the blocks) give a window, or a strip of rows
    and columns, exactly the kept segments whose box reaches it widened by a node, ascending:
    windows on cell and block edges among them."""
    from isophote.render.segment_index import BIN, SegmentIndex

    rng = np.random.default_rng(1300 + seed)
    points, first, _ = _chains(rng, 3000, span=200.0, size=4.0)
    border = rng.random(len(first)) < 0.1
    r, block, nr, nc = 1.0, 64, 200, 200
    ix = SegmentIndex(points, first, border, r, block, nr, nc)
    assert ix.bin == BIN < block and (ix.nbr, ix.nbc) == (-(-nr // BIN), -(-nc // BIN))
    ids = K.kept_segments(points, first, r, True, 0.0, 0.0)
    box = R.segment_boxes(points, first, ids, r)

    def reaching(x_lo, x_hi, y_lo, y_hi):
        return ids[(box[1] >= x_lo) & (box[0] <= x_hi) & (box[3] >= y_lo) & (box[2] <= y_hi)]

    windows = [(0, 0, 80, 80), (48, 48, 96, 96), (64 - 16, 128 - 16, 96, 72), (32, 0, 64, 32), (160, 168, 40, 32)]
    windows += [tuple(int(v) for v in rng.integers(0, 150, 2)) + tuple(int(v) for v in rng.integers(1, 50, 2))
                for _ in range(10)]
    for i0, j0, n, m in windows:
        got = ix.window(i0, j0, n, m)
        assert np.array_equal(got, reaching(j0 - 1, j0 + m + 1, i0 - 1, i0 + n + 1)), (i0, j0, n, m)
    for y_lo, y_hi, x_lo, x_hi in [(10.5, 40.25, -np.inf, np.inf), (63.0, 64.0, 30.0, 95.5), (0.0, 199.0, 96.0, 97.0)]:
        got = ix.rows(y_lo, y_hi, x_lo, x_hi)
        assert np.array_equal(got, reaching(x_lo, x_hi, y_lo - 1, y_hi + 1))
