"""The renderer's numba kernels against their NumPy twins on seeded random inputs (STYLE.md
item 8): node regions, scanline rasterisation, distance propagation and seeding, bilinear
resampling, the enlargement sharpening."""

from __future__ import annotations

import numpy as np
import pytest

from isophote.render._kernels.diffuse import seed as seed_fields
from isophote.render._kernels.diffuse import D, MODE_GEODESIC, MODE_MANHATTAN, NF, V, label_nodes, offsets, propagate
from isophote.render._kernels.diffuse_ref import label_nodes as label_nodes_ref, propagate as propagate_ref
from isophote.render._kernels.raster import rasterise
from isophote.render._kernels.raster_ref import rasterise as rasterise_ref
from isophote.render._kernels.resample import bilinear_at
from isophote.render._kernels.resample_ref import bilinear_at as bilinear_at_ref
from isophote.render._kernels.sharpen import correction
from isophote.render._kernels.sharpen_ref import correction as correction_ref
from kernel_inputs import SEEDS

# ---------------------------------------------------------------------------------------
# node regions
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", SEEDS)
def test_label_nodes_matches_its_twin(seed):
    """The renderer's node regions (8-connected, equal band) against scipy's labelling, on
    random band grids from speckle to large blobs; numbered in scan order of first nodes."""
    rng = np.random.default_rng(300 + seed)
    nr, nc = rng.integers(1, 40, 2)
    coarse = rng.integers(0, 4, (nr // 4 + 1, nc // 4 + 1))
    band = np.kron(coarse, np.ones((4, 4), np.int64))[:nr, :nc]
    band = np.where(rng.random((nr, nc)) < 0.15, rng.integers(0, 4, (nr, nc)), band).astype(np.int16)
    labels, m = label_nodes(band)
    labels_ref, m_ref = label_nodes_ref(band)
    assert labels.dtype == np.int32 and m == m_ref
    assert np.array_equal(labels, labels_ref)
    assert labels.flat[0] == 0 and np.array_equal(np.unique(labels), np.arange(m))


def test_label_nodes_joins_diagonals():
    """8-connected: a checkerboard is two regions, and a diagonal line of one band does not
    part the band on either side of it (their corners touch across it); a wall two nodes
    thick does."""
    board = (np.indices((6, 6)).sum(axis=0) % 2).astype(np.int16)
    labels, m = label_nodes(board)
    assert m == 2 and labels[0, 0] == 0 and labels[0, 1] == 1
    labels, m = label_nodes(np.eye(5, dtype=np.int16))
    assert m == 2 and labels[0, 4] == labels[4, 0]
    wall = np.eye(5, dtype=np.int16) + np.eye(5, k=1, dtype=np.int16)
    labels, m = label_nodes(wall)
    assert m == 3 and labels[0, 4] != labels[4, 0]


# ---------------------------------------------------------------------------------------
# rasterisation
# ---------------------------------------------------------------------------------------


def random_edges(rng, w, h, n_loops, quantised):
    xs0, ys0, xs1, ys1 = [], [], [], []
    for _ in range(n_loops):
        n = int(rng.integers(3, 12))
        p = np.column_stack([rng.uniform(-2, w + 2, n), rng.uniform(-2, h + 2, n)])
        if quantised:  # vertices on the quarter grid: many exactly on sample rows
            p = np.round(p * 4) / 4
        q = np.roll(p, -1, axis=0)
        xs0.append(p[:, 0]), ys0.append(p[:, 1]), xs1.append(q[:, 0]), ys1.append(q[:, 1])
    return tuple(np.concatenate(a) for a in (xs0, ys0, xs1, ys1))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("quantised", [False, True], ids=["float", "quarter-grid"])
def test_rasterise_matches_its_twin(seed, quantised):
    rng = np.random.default_rng(300 + seed)
    w, h = 24, 18
    x0, y0, x1, y1 = random_edges(rng, w, h, int(rng.integers(1, 5)), quantised)
    src = rng.random(len(x0)) < 0.7
    for row0, col0, n_rows, n_cols in ((0, 0, h, w), (3, 5, 9, 11), (-2, -3, h + 4, w + 6)):
        for transposed in (False, True):
            ref = rasterise_ref(x0, y0, x1, y1, row0, col0, n_rows, n_cols, transposed)
            for crossings in (False, True):
                band, *_ = rasterise(x0, y0, x1, y1, src, row0, col0, n_rows, n_cols, crossings, transposed)
                assert band.dtype == ref.dtype == np.int16
                assert np.array_equal(band, ref), (row0, col0, crossings, transposed)


def test_rows_and_columns_settle_edges_through_samples_alike():
    """Diamonds whose straight edges run at 45 degrees exactly through sample centres (and
    squares along sample rows): the band the rows give equals the band the columns give
    (the transposed raster, transposed back), so no crossing is seen on the wrong side."""
    for cx, cy, rad in ((6.5, 5.5, 3.0), (7.5, 6.5, 2.0), (6.0, 6.0, 2.5), (6.5, 6.5, 4.0)):
        for pts in ([(cx, cy - rad), (cx - rad, cy), (cx, cy + rad), (cx + rad, cy)],
                    [(cx - rad, cy - rad), (cx - rad, cy + rad), (cx + rad, cy + rad), (cx + rad, cy - rad)]):
            p = np.array(pts)
            for d in (p, p[::-1]):
                q = np.roll(d, -1, axis=0)
                x0, y0, x1, y1 = d[:, 0], d[:, 1], q[:, 0], q[:, 1]
                src = np.ones(4, bool)
                rows, *_ = rasterise(x0, y0, x1, y1, src, 0, 0, 14, 14, False)
                cols, *_ = rasterise(y0, x0, y1, x1, src, 0, 0, 14, 14, False, True)
                assert np.array_equal(rows, -cols.T), (cx, cy, rad)
                assert np.abs(rows).max() == 1


def test_rasterise_square_has_the_known_winding():
    """A square [2, 6] x [1, 4] traversed with its inside on the left (screen): band 1 exactly
    on the samples whose centres lie inside; half-open on the edges through sample centres."""
    sq = np.array([(2.0, 1.0), (2.0, 4.0), (6.0, 4.0), (6.0, 1.0)])  # down the left side first
    q = np.roll(sq, -1, axis=0)
    x0, y0, x1, y1 = sq[:, 0], sq[:, 1], q[:, 0], q[:, 1]
    band, *_ = rasterise(x0, y0, x1, y1, np.ones(4, bool), 0, 0, 6, 8, False)
    yy, xx = np.mgrid[0:6, 0:8] + 0.5
    inside = (xx > 2) & (xx < 6) & (yy > 1) & (yy < 4)
    assert np.array_equal(band, inside.astype(np.int16))
    assert np.array_equal(rasterise_ref(x0, y0, x1, y1, 0, 0, 6, 8), band)
    # the crossings record the exact edge positions of each row's gaps
    _, fx, fd, lx, ld, fs, ls = rasterise(x0, y0, x1, y1, np.ones(4, bool), 0, 0, 6, 8, True)
    assert fx[2, 2] == 2.0 and fd[2, 2] == 1 and lx[2, 6] == 6.0 and ld[2, 6] == -1
    assert np.all(fd[0] == 0) and np.all(fd[5] == 0)


# ---------------------------------------------------------------------------------------
# distance propagation
# ---------------------------------------------------------------------------------------


def empty_field(nr, nc):
    """F in the layout seed() produces (node-major storage, indexed F[side, field, i, j])."""
    F = np.zeros((nr, nc, 2, NF), np.float32).transpose((2, 3, 0, 1))
    F[:, D] = np.inf
    return F


def blob_bands(rng, nr, nc, n_bands):
    coarse = rng.integers(0, n_bands, size=(nr // 3 + 1, nc // 3 + 1))
    band = np.kron(coarse, np.ones((3, 3), np.int16))[:nr, :nc].astype(np.int16)
    flip = rng.random((nr, nc)) < 0.08
    band[flip] = rng.integers(0, n_bands, size=flip.sum())
    return np.ascontiguousarray(band)


def compare_fields(a, b):
    for s in range(2):
        da, db = a[s, D], b[s, D]
        assert np.array_equal(np.isfinite(da), np.isfinite(db))
        fin = np.isfinite(da)
        np.testing.assert_allclose(da[fin], db[fin], rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("mode", [MODE_MANHATTAN, MODE_GEODESIC], ids=["manhattan", "geodesic"])
def test_propagate_matches_its_twin_on_random_sources(seed, mode):
    rng = np.random.default_rng(400 + seed)
    nr, nc = (int(v) for v in rng.integers(6, 24, size=2))
    band = blob_bands(rng, nr, nc, 4)
    F = empty_field(nr, nc)
    for s in range(2):
        src = rng.random((nr, nc)) < 0.05
        F[s, D][src] = rng.uniform(0, 1, src.sum())
        F[s, V][src] = rng.uniform(0, 255, src.sum())
    # the twin runs in float64 (see test_propagate_ref_converges_on_float32_fields)
    ref = propagate_ref(F.astype(np.float64), band, offsets(mode), mode)
    fast = F.copy()
    sweeps = propagate(fast, band, offsets(mode), mode, 1000)
    assert sweeps < 1000  # converged
    compare_fields(fast, ref)
    # a node with a finite distance got it within its band: every finite node's band holds a
    # source of that side
    for s in range(2):
        for b in np.unique(band[np.isfinite(fast[s, D])]):
            assert np.isfinite(F[s, D][band == b]).any()


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("mode", [MODE_MANHATTAN, MODE_GEODESIC], ids=["manhattan", "geodesic"])
def test_propagate_matches_its_twin_on_seeded_fields(seed, mode):
    """F seeded from the crossings of random polygons, as render/distance.py builds it."""
    rng = np.random.default_rng(500 + seed)
    nr, nc = 18, 24
    x0, y0, x1, y1 = random_edges(rng, nc, nr, 3, quantised=False)
    src = np.ones(len(x0), bool)
    band, *h = rasterise(x0, y0, x1, y1, src, 0, 0, nr, nc, True)
    _, *v = rasterise(y0, x0, y1, x1, src, 0, 0, nc, nr, True, True)
    band = band - band.min()
    levels = np.arange(1, int(band.max()) + 2) * 10.0 + 0.5
    F = seed_field = seed_fields(band, tuple(h), tuple(v), levels, mode)
    assert np.isfinite(seed_field[:, D]).any()
    ref = propagate_ref(F.astype(np.float64), band, offsets(mode), mode)
    fast = F.copy()
    assert propagate(fast, band, offsets(mode), mode, 1000) < 1000
    compare_fields(fast, ref)
    # values are the levels bounding each node's band
    for s, shift in ((0, -1), (1, 0)):
        fin = np.isfinite(fast[s, D])
        assert np.array_equal(fast[s, V][fin], levels[band[fin] + shift].astype(np.float32))


class _CountingNumpy:
    """Stands in for numpy inside _kernels.diffuse_ref: counts np.hypot calls (one per offset and
    sweep of propagate_ref in the geodesic mode)."""

    def __init__(self):
        self.hypot_calls = 0

    def __getattr__(self, name):
        return getattr(np, name)

    def hypot(self, *args):
        self.hypot_calls += 1
        return np.hypot(*args)


def test_propagate_ref_converges_on_float32_fields(monkeypatch):
    from isophote.render._kernels import diffuse_ref

    counter = _CountingNumpy()
    monkeypatch.setattr(diffuse_ref, "np", counter)
    F = empty_field(2, 3)
    F[0, D, 0, 0] = 0.0  # one source; node (1, 2) is a knight's move away: sqrt(5)
    out = propagate_ref(F, np.zeros((2, 3), np.int16), offsets(MODE_GEODESIC), MODE_GEODESIC, max_iter=50)
    assert out[0, D, 1, 2] == np.float32(np.sqrt(5.0))
    passes = counter.hypot_calls / (2 * len(offsets(MODE_GEODESIC)))
    assert passes < 10, passes  # a 2 x 3 grid settles in a couple of passes


def test_seed_offers_only_levels_that_cross():
    """A pit (level 100 only, levels 50 / 100 / 150) whose top vertex touches node row 4."""
    corners = np.array([(8.3, 4.5), (12.8, 8.35), (8.35, 12.8), (4.2, 8.35)])
    q = np.roll(corners, -1, axis=0)
    x0, y0, x1, y1 = corners[:, 0], corners[:, 1], q[:, 0], q[:, 1]
    src = np.ones(4, bool)
    band, *h = rasterise(x0, y0, x1, y1, src, 0, 0, 17, 17, True)
    band = band + np.int16(2)  # outside the pit: above 100; inside: band 1
    _, *v = rasterise(y0, x0, y1, x1, src, 0, 0, 17, 17, True)
    assert set(np.unique(band).tolist()) == {1, 2}
    F = seed_fields(band, tuple(h), tuple(v), np.array([50.0, 100.0, 150.0]), MODE_MANHATTAN)
    seeded = np.isfinite(F[:, D])
    assert seeded.any()
    assert set(np.unique(F[:, V][seeded]).tolist()) == {100.0}


@pytest.mark.parametrize("seed", range(4))
def test_bilinear_at_matches_its_twin(seed):
    """Random fields (one node wide or tall too) read at random points, some beyond the
    outermost nodes (clamped): the kernel and scipy's order-1 map_coordinates agree, and at
    the nodes themselves both give the field's own values."""
    rng = np.random.default_rng(seed)
    nr, nc = [(1, 7), (6, 1), (9, 13), (30, 2)][seed]
    field = rng.normal(0, 10, (nr, nc)).astype(np.float32)
    xs = rng.uniform(-2, nc + 2, 200)
    ys = rng.uniform(-2, nr + 2, 200)
    got = np.array([bilinear_at(field, x, y) for x, y in zip(xs, ys)])
    assert np.allclose(got, bilinear_at_ref(field, xs, ys), atol=1e-4)
    yy, xx = np.mgrid[0:nr, 0:nc] + 0.5
    at_nodes = np.array([bilinear_at(field, x, y) for x, y in zip(xx.ravel(), yy.ravel())])
    assert np.allclose(at_nodes, field.ravel(), atol=1e-5)


@pytest.mark.parametrize("r, gx, gy, shape", [(1, 0.1, 0.0, (5, 9)), (2, 0.0, 0.2, (9, 4)),
                                               (3, 0.117, 0.094, (40, 31)), (3, 0.1, 0.1, (6, 6))])
def test_sharpen_correction_matches_its_twin(r, gx, gy, shape):
    nv = np.random.default_rng(r).uniform(0, 255, shape).astype(np.float32)
    corr, sharp = correction(nv, r, gx, gy)
    corr_ref, sharp_ref = correction_ref(nv, r, gx, gy)
    assert np.allclose(corr, corr_ref, atol=1e-4) and np.allclose(sharp, sharp_ref, atol=1e-4)


@pytest.mark.parametrize("seed", range(4))
def test_label_runs_give_the_dense_labels_caps(seed):
    """A blocked level keeps its canvas labels as runs along the rows (regions.row_runs): the
    cap values a window reads through them are those of the dense labels, at any window."""
    from isophote.render._kernels.regions import local_cap_values_runs, row_runs

    rng = np.random.default_rng(seed)
    band = rng.integers(0, 3, (37, 53)).astype(np.int16)
    band[5:20, 10:40] = 7  # a large region beside the noise: long runs and single nodes
    labels, m = label_nodes(band)
    row_start, col, lab = row_runs(labels)
    assert row_start[-1] == len(col) and np.all(col[row_start[:-1]] == 0)
    dense = np.concatenate([np.repeat(lab[a:b], np.diff(np.r_[col[a:b], labels.shape[1]]))
                            for a, b in zip(row_start[:-1], row_start[1:])])
    assert np.array_equal(dense.reshape(labels.shape), labels)
    gcapv = rng.normal(size=m)
    for i0, j0, n, w in [(0, 0, 37, 53), (3, 7, 20, 30), (30, 40, 7, 13)]:
        win, k = label_nodes(np.ascontiguousarray(band[i0:i0 + n, j0:j0 + w]))
        flat = win.ravel()
        first = np.array([np.flatnonzero(flat == q)[0] for q in range(k)])  # each region's first node
        want = gcapv[labels[i0:i0 + n, j0:j0 + w].ravel()[first]]
        got = local_cap_values_runs(win, k, i0, j0, row_start, col, lab, gcapv)
        assert np.array_equal(got, want)
