"""Each numba kernel against its plain NumPy (or Python) twin on seeded random inputs
(STYLE.md item 8): marching squares (alone and fused with linking), bands, region labelling,
region levels and cap sums, innermost enclosing loop (by rays and by rows), row bucketing,
scanline rasterisation, distance propagation and the renderer's node regions."""

from __future__ import annotations

import numpy as np
import pytest

from isophote.render._kernels.diffuse import seed as seed_fields
from isophote.render._kernels.diffuse import D, MODE_GEODESIC, MODE_MANHATTAN, NF, V, label_nodes, offsets, propagate
from isophote.render._kernels.diffuse_ref import label_nodes as label_nodes_ref, propagate as propagate_ref
from isophote.encoder._kernels.enclose_ref import innermost_enclosing as innermost_enclosing_ref
from isophote.encoder._kernels.enclose import (
    bucket_rows, innermost_enclosing, innermost_enclosing_rows,
)
from isophote.encoder._kernels.marching import _cubic_t, march, march_loops
from isophote.encoder._kernels.marching_ref import (
    _cubic_t as cubic_t_ref, march as march_ref, march_loops as march_loops_ref,
)
from isophote.render._kernels.raster import rasterise
from isophote.render._kernels.raster_ref import rasterise as rasterise_ref
from isophote.render._kernels.resample import bilinear_at
from isophote.render._kernels.resample_ref import bilinear_at as bilinear_at_ref
from isophote.render._kernels.sharpen import correction
from isophote.render._kernels.sharpen_ref import correction as correction_ref
from isophote.encoder._kernels.regions import cap_sums, label_regions, region_levels, region_stats
from isophote.encoder._kernels.regions_ref import (
    cap_sums as cap_sums_ref, label_regions as label_regions_ref, region_levels as region_levels_ref,
    region_stats as region_stats_ref,
)
from isophote.encoder.isolines import pad_grid
from isophote.encoder.levels import bands
from isophote.encoder.ribbon import gradient_magnitude

SEEDS = range(6)

# ---------------------------------------------------------------------------------------
# random inputs
# ---------------------------------------------------------------------------------------


def random_grid(rng, quantised):
    """A random smooth-ish padded grid and its levels, as find_isolines builds them.

    quantised: values on a 0.5 grid and levels on integers and half-integers, so that many
    samples lie exactly on a level (the "equal counts as above" rule is exercised)."""
    h, w = rng.integers(4, 14, size=2)
    coarse = rng.uniform(0, 255, size=(h // 2 + 2, w // 2 + 2))
    fine = np.kron(coarse, np.ones((2, 2)))[:h, :w] + rng.normal(0, 30, size=(h, w))
    grid = np.clip(fine, 0, 255)
    if quantised:
        grid = np.round(grid * 2) / 2
        levels = np.arange(20.0, 250.0, 17.5)
    else:
        levels = np.sort(rng.uniform(5, 250, size=rng.integers(1, 12)))
    vals, band = pad_grid(grid, levels)
    return vals, band, levels


def star_polygon(rng, cx, cy, radius, n, wobble):
    """A star-shaped polygon around (cx, cy) (angles spread: every gap below pi), in either
    direction at random."""
    t = (np.arange(n) + rng.uniform(0, 0.8, n)) * (2 * np.pi / n)
    r = radius * (1 + wobble * rng.uniform(-1, 1, n))
    p = np.column_stack([cx + r * np.cos(t), cy + r * np.sin(t)])
    return p if rng.random() < 0.5 else p[::-1]


def split_at_half_rows(loop):
    """The loop with a vertex added wherever an edge crosses a line y = k / 2, so that every
    edge lies within one half-pixel row (the bucketing innermost_enclosing expects)."""
    out = []
    for a, b in zip(loop, np.roll(loop, -1, axis=0)):
        out.append(a)
        lo, hi = sorted((a[1], b[1]))
        ks = np.arange(np.floor(lo * 2) + 1, np.ceil(hi * 2)) / 2
        ks = ks[(ks > lo) & (ks < hi)]
        ts = (ks - a[1]) / (b[1] - a[1])
        for t in np.sort(ts):
            p = a + t * (b - a)
            p[1] = a[1] + t * (b[1] - a[1])
            out.append(np.array([p[0], ks[np.argmin(np.abs(ks - p[1]))]]))
    return np.asarray(out)


def shoelace(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def nested_loops(rng, w, h):
    """Random non-crossing loops: families of concentric stars, side by side, some inside a
    frame loop; returns the loops (no repeated first point)."""
    # (w, h) = (30, 20): a frame loop of radius >= 9.5 around (15, 10) holds two families
    # centred 5 px from its centre, each of radius <= 3.2 * 1.25 = 4
    loops = [star_polygon(rng, w / 2, h / 2, 9.6, 48, 0.01)]
    for cx in (w / 2 - 5, w / 2 + 5):
        cy = h / 2
        base = star_polygon(rng, 0.0, 0.0, 1.0, int(rng.integers(5, 14)), 0.25)
        for s in np.sort(rng.uniform(0.3, 3.2, size=rng.integers(1, 4)))[::-1]:
            p = base * s + [cx, cy]
            loops.append(p if rng.random() < 0.5 else p[::-1])
    return loops


# ---------------------------------------------------------------------------------------
# marching squares
# ---------------------------------------------------------------------------------------

SEG_KEYS = ("skey", "ekey", "level", "border", "below", "above", "t")


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("quantised", [False, True], ids=["float", "on-levels"])
def test_march_matches_its_twin(seed, quantised):
    rng = np.random.default_rng(seed)
    vals, band, levels = random_grid(rng, quantised)
    fast = march(vals, band, levels)
    ref = march_ref(vals, band, levels)
    assert len(fast["skey"]) == len(ref["skey"]) > 0
    # every crossing starts exactly one segment: the start key identifies a segment
    f = np.argsort(fast["skey"])
    r = np.argsort(ref["skey"])
    for k in SEG_KEYS:
        assert np.array_equal(fast[k][f], ref[k][r]), k
    # and every crossing ends exactly one segment: the segments close into loops
    assert np.array_equal(np.sort(fast["ekey"]), np.sort(fast["skey"]))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("quantised", [False, True], ids=["float", "on-levels"])
def test_march_loops_matches_its_twin(seed, quantised):
    """Marching, linking and the per-point gathers in one kernel = march_ref, a plain walk
    and NumPy gathers, array for array (loops in the same order, from the same point)."""
    rng = np.random.default_rng(50 + seed)
    vals, band, levels = random_grid(rng, quantised)
    grid = vals[1:-1, 1:-1].copy()
    grid_eps = rng.uniform(0.1, 2.0, grid.shape)
    fast = march_loops(vals, band, levels, grid, grid_eps)
    ref = march_loops_ref(vals, band, levels, grid, grid_eps)
    assert fast[0] and len(fast[1]) == len(ref[1]) > 0
    for k, (a, b) in enumerate(zip(fast, ref)):
        assert np.array_equal(np.asarray(a), np.asarray(b)), k
    # the gradient gathered is encoder/ribbon.py's
    g = gradient_magnitude(grid)
    g_p = np.zeros(vals.shape)
    g_p[1:-1, 1:-1] = g
    assert np.array_equal(fast[8], g_p.ravel()[fast[3]])
    assert np.array_equal(fast[9], g_p.ravel()[fast[4]])


def test_cubic_crossings_have_known_answers_and_a_twin():
    """The crossing on an edge's cubic: exact on quadratics (Catmull-Rom reproduces them),
    the straight line on a ramp, inside the edge and in order of level, kernel = twin."""
    # v = x^2 sampled at -1, 0, 1, 2: the level L crosses at x = sqrt(L)
    for L in (0.01, 0.2, 0.5, 0.9, 1.0):
        assert _cubic_t(1.0, 0.0, 1.0, 4.0, L) == pytest.approx(np.sqrt(L), abs=1e-12)
    # a ramp: the linear t itself
    for t in (0.1, 0.37, 1.0):
        assert _cubic_t(-5.0, 0.0, 5.0, 10.0, t) == pytest.approx(t, abs=1e-12)
    rng = np.random.default_rng(11)
    n = 4000
    v0 = rng.uniform(0, 200, n)
    v1 = v0 + rng.uniform(1e-3, 60, n)
    vm = v0 + rng.uniform(-80, 80, n)
    v2 = v1 + rng.uniform(-80, 80, n)
    t = rng.uniform(0, 1, (n, 3))
    t.sort(axis=1)
    t[:, 2] = np.where(rng.random(n) < 0.1, 1.0, t[:, 2])
    fast = np.array([[_cubic_t(vm[i], v0[i], v1[i], v2[i], t[i, k]) for k in range(3)] for i in range(n)])
    ref = np.column_stack([cubic_t_ref(vm, v0, v1, v2, t[:, k]) for k in range(3)])
    assert np.array_equal(fast, ref)
    assert np.all((fast > 0) & (fast <= 1))
    assert np.all(np.diff(fast, axis=1) >= 0)  # levels on one edge keep their order


def test_march_loops_puts_crossings_on_the_quadratic():
    """A padded grid whose rows are x^2 (x = column - 3): every crossing of level L on a
    horizontal edge between two inner samples lies at x = sqrt(L)."""
    x = np.arange(-2.0, 9.0)
    grid = np.tile(x * x, (5, 1)) + 0.25  # no sample exactly on a level
    levels = np.array([2.0, 7.5, 20.0, 41.0])
    vals, band = pad_grid(grid, levels)
    out = march_loops(vals, band, levels, grid, np.full(grid.shape, 0.5))
    assert out[0]
    pts, border, level, offsets = out[1], out[2], out[10], out[11]
    lev = np.repeat(levels[level], np.diff(offsets))
    # grid column c sits at image x = c / 2 (mapping.py), so grid x-coordinate = 2 * image x
    inner = ~border & (pts[:, 0] > 1.0) & (pts[:, 0] < 4.5)
    assert inner.sum() >= 8
    got = 2.0 * pts[inner, 0] - 2.0  # back to x
    assert np.allclose(got, np.sqrt(lev[inner] - 0.25), atol=1e-9)


@pytest.mark.parametrize("quantised", [False, True], ids=["float", "on-levels"])
def test_pad_grid_bands_are_searchsorted(quantised):
    rng = np.random.default_rng(7)
    grid = rng.uniform(0, 255, (9, 13))
    levels = np.sort(rng.uniform(5, 250, 7))
    if quantised:
        grid = np.round(grid / 10) * 10
        levels = np.arange(10.0, 250.0, 20.0)
    vals, band = pad_grid(grid, levels)
    assert band.dtype == np.int16 and vals.shape == band.shape == (11, 15)
    assert np.array_equal(band[1:-1, 1:-1], bands(grid, levels))
    assert np.array_equal(vals[1:-1, 1:-1], grid)
    inner = np.zeros(band.shape, bool)
    inner[1:-1, 1:-1] = True
    assert not band[~inner].any() and not vals[~inner].any()


# ---------------------------------------------------------------------------------------
# region labelling
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


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("quantised", [False, True], ids=["float", "on-levels"])
def test_label_regions_matches_its_twin(seed, quantised):
    rng = np.random.default_rng(100 + seed)
    vals, band, levels = random_grid(rng, quantised)
    band = band.astype(np.int64)
    labels, m = label_regions(vals, band, levels)
    labels_ref, m_ref = label_regions_ref(vals, band, levels)
    assert m == m_ref
    assert np.array_equal(labels, labels_ref)
    # regions never mix bands
    for k in range(m):
        assert len(np.unique(band[labels == k])) == 1


def test_label_regions_saddle_follows_the_decider():
    """A 2 x 2 checkerboard: the diagonal pair joins only when the saddle value is in its band."""
    levels = np.array([100.0])
    for centre_high, joined in ((True, True), (False, False)):
        hi, lo = (200.0, 90.0) if centre_high else (110.0, 0.0)
        grid = np.array([[hi, lo], [lo, hi]])
        vals, band = pad_grid(grid, levels)
        for fn in (label_regions, label_regions_ref):
            lab, _ = fn(vals, band.astype(np.int64), levels)
            assert (lab[1, 1] == lab[2, 2]) == joined
            assert lab[1, 2] != lab[2, 1] if joined else lab[1, 2] == lab[2, 1]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("quantised", [False, True], ids=["float", "on-levels"])
def test_region_stats_matches_its_twin(seed, quantised):
    rng = np.random.default_rng(200 + seed)
    vals, band, levels = random_grid(rng, quantised)
    labels, m = label_regions(vals, band.astype(np.int64), levels)
    got = region_stats(labels, vals, m)
    ref = region_stats_ref(labels, vals, m)
    for a, b in zip(got, ref):
        assert np.array_equal(a, b)
    deep, total, count = got
    hp, wp = vals.shape
    inner = count > 0
    assert count.sum() == (hp - 2) * (wp - 2)
    assert np.array_equal(labels.ravel()[deep[inner]], np.flatnonzero(inner))  # in its region


def test_region_stats_deepest_sample_of_a_plateau_is_its_centre():
    """A flat disc (every sample equal): its deepest sample is the centre, not the first
    sample in scan order on its edge."""
    n = 41
    yy, xx = np.mgrid[0:n, 0:n]
    grid = np.where(np.hypot(xx - 20, yy - 20) <= 12, 230.0, 100.0)
    levels = np.array([165.0])
    vals, band = pad_grid(grid, levels)
    labels, m = label_regions(vals, band.astype(np.int64), levels)
    deep, _, count = region_stats(labels, vals, m)
    k = labels[21, 21]
    r, c = divmod(int(deep[k]), n + 2)
    assert abs(r - 21) + abs(c - 21) <= 1, (r, c)


@pytest.mark.parametrize("seed", SEEDS)
def test_region_levels_and_cap_sums_match_their_twins(seed):
    rng = np.random.default_rng(300 + seed)
    vals, band, levels = random_grid(rng, seed % 2 == 1)
    labels, m = label_regions(vals, band.astype(np.int64), levels)
    hp, wp = vals.shape
    inner = np.flatnonzero(np.pad(np.ones((hp - 2, wp - 2), bool), 1).ravel())
    n = 200
    below = rng.choice(hp * wp, n)
    above = rng.choice(inner, n)
    lev_seg = rng.integers(0, len(levels), n).astype(np.int64)
    lev_seg[:50] = band.ravel()[above[:50]] - 1  # crossings that do touch the above region
    lev_seg = np.maximum(lev_seg, 0)
    lo, hi = region_levels(labels, band, above, below, lev_seg, m)
    lo_r, hi_r = region_levels_ref(labels, band, above, below, lev_seg, m)
    assert np.array_equal(lo, lo_r) and np.array_equal(hi, hi_r) and (hi >= 0).any()
    for ramp in (0.5, 2.0, 3.7):
        want = rng.random(m) < 0.6
        L = rng.uniform(0, 255, m)
        num, den, has_edge = cap_sums(labels, vals, want, L, ramp)
        num_r, den_r, has_edge_r = cap_sums_ref(labels, vals, want, L, ramp)
        assert has_edge == has_edge_r
        assert np.array_equal(num[want], num_r[want]) and np.array_equal(den[want], den_r[want])


def test_cap_sums_far_from_edges_and_without_edges():
    """Wide regions (samples far beyond the search window) and a single region."""
    labels = np.zeros((42, 42), np.int64)
    labels[1:-1, 1:21] = 1
    labels[1:-1, 21:-1] = 2
    labels[0, :], labels[-1, :], labels[:, 0], labels[:, -1] = 3, 4, 5, 6
    vals = np.random.default_rng(1).uniform(0, 255, labels.shape)
    want = np.array([False, True, True, False, False, False, False])
    L = np.array([0.0, 100.0, 50.0, 0, 0, 0, 0])
    fast = cap_sums(labels, vals, want, L, 2.0)
    ref = cap_sums_ref(labels, vals, want, L, 2.0)
    assert np.array_equal(fast[0], ref[0]) and np.array_equal(fast[1], ref[1]) and fast[2]
    labels[1:-1, 1:-1] = 1
    assert not cap_sums(labels, vals, want, L, 2.0)[2] and not cap_sums_ref(labels, vals, want, L, 2.0)[2]


# ---------------------------------------------------------------------------------------
# innermost enclosing loop
# ---------------------------------------------------------------------------------------


def loop_segments(loops, h):
    """The loops' segments, split at half rows, as the hierarchy holds them: (x0, y0, x1, y1,
    seg_loop, row, n_rows), row being each segment's half-pixel row."""
    split = [split_at_half_rows(p) for p in loops]
    x0 = np.concatenate([p[:, 0] for p in split])
    y0 = np.concatenate([p[:, 1] for p in split])
    x1 = np.concatenate([np.roll(p[:, 0], -1) for p in split])
    y1 = np.concatenate([np.roll(p[:, 1], -1) for p in split])
    seg_loop = np.concatenate([np.full(len(p), k) for k, p in enumerate(split)]).astype(np.int64)
    n_rows = int(2 * h) + 1
    row = np.clip(np.floor(np.minimum(y0, y1) * 2).astype(np.int64), 0, n_rows - 1)
    return x0, y0, x1, y1, seg_loop, row, n_rows


@pytest.mark.parametrize("seed", SEEDS)
def test_innermost_enclosing_matches_its_twin(seed):
    rng = np.random.default_rng(200 + seed)
    w, h = 30.0, 20.0
    loops = nested_loops(rng, w, h)
    area = np.array([shoelace(p) for p in loops])
    level = rng.integers(0, 5, size=len(loops)).astype(np.int64)
    x0, y0, x1, y1, seg_loop, row, n_rows = loop_segments(loops, h)
    assert np.all(np.maximum(y0, y1) <= (row + 1) / 2 + 1e-12)  # one row per segment
    row_order = np.argsort(row, kind="stable")
    row_start = np.searchsorted(row[row_order], np.arange(n_rows + 1))
    # queries: random points, and a point of each loop excluding that loop (as the hierarchy)
    px = np.concatenate([rng.uniform(0, w, 200), [0.5 * (p[0, 0] + p[1, 0]) for p in loops]])
    py = np.concatenate([rng.uniform(0, h, 200), [0.5 * (p[0, 1] + p[1, 1]) for p in loops]])
    exclude = np.concatenate([np.full(200, -1), np.arange(len(loops))]).astype(np.int64)
    fast = innermost_enclosing(px, py, exclude, x0, y0, x1, y1, seg_loop, row_start, row_order,
                               area, level, n_rows)
    ref = innermost_enclosing_ref(px, py, exclude, loops, area, level)
    assert np.array_equal(fast, ref)
    # the known nesting: the frame loop holds both families, each ring holds the next
    parents = fast[200:]
    assert parents[0] == -1
    expected = []
    k = 1
    while k < len(loops):  # a family: consecutive loops, outermost first, around one centre
        j = k
        right = loops[k][:, 0].mean() > w / 2
        while j + 1 < len(loops) and (loops[j + 1][:, 0].mean() > w / 2) == right:
            j += 1
        expected += [0] + list(range(k, j))
        k = j + 1
    assert parents[1:].tolist() == expected
    assert (fast[:200] >= 0).any() and (fast[:200] == -1).any()


@pytest.mark.parametrize("seed", SEEDS)
def test_innermost_enclosing_rows_equals_rays(seed):
    """The row sweep answers as the ray query, also for many queries on one row and y
    (as the caps ask: sample positions), on loops whose vertices sit on the half-pixel grid."""
    rng = np.random.default_rng(400 + seed)
    w, h = 30.0, 20.0
    loops = [np.round(p * 2) / 2 for p in nested_loops(rng, w, h)]
    loops = [p[np.any(p != np.roll(p, 1, axis=0), axis=1)] for p in loops]
    area = np.array([shoelace(p) for p in loops])
    level = rng.integers(0, 3, size=len(loops)).astype(np.int64)
    x0, y0, x1, y1, seg_loop, row, n_rows = loop_segments(loops, h)
    row_start, row_order = bucket_rows(row, n_rows)
    assert np.array_equal(row_order, np.argsort(row, kind="stable"))
    assert np.array_equal(row_start, np.searchsorted(row[row_order], np.arange(n_rows + 1)))
    n = 400
    px = np.concatenate([rng.uniform(-1, w + 1, n), np.round(rng.uniform(0, w, n) * 2) / 2])
    py = np.concatenate([rng.uniform(-1, h + 1, n), np.round(rng.uniform(0, h, n) * 2) / 2])
    exclude = np.where(rng.random(2 * n) < 0.2, rng.integers(0, len(loops), 2 * n), -1).astype(np.int64)
    args = (x0, y0, x1, y1, seg_loop, row_start, row_order, area, level, n_rows)
    rays = innermost_enclosing(px, py, exclude, *args)
    rows = innermost_enclosing_rows(px, py, exclude, *args)
    assert np.array_equal(rows, rays)
    assert (rows >= 0).sum() > n // 2


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
