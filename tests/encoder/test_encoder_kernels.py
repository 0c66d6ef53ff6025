"""The encoder's numba kernels against their NumPy twins on seeded random inputs (STYLE.md
item 8): marching squares (alone and fused with linking), bands, region labelling, region
levels and cap sums, the innermost enclosing loop (by rays and by rows)."""

from __future__ import annotations

import numpy as np
import pytest

from isophote.encoder._kernels.enclose import (
    bucket_rows, innermost_enclosing, innermost_enclosing_rows, loop_blocks,
)
from isophote.encoder._kernels.enclose_ref import innermost_enclosing as innermost_enclosing_ref
from isophote.encoder._kernels.marching import _cubic_t, march, march_loops
from isophote.encoder._kernels.marching_ref import (
    _cubic_t as cubic_t_ref, march as march_ref, march_loops as march_loops_ref,
)
from isophote.encoder.isolines import above_of, step_codes
from isophote.encoder._kernels.regions import cap_sums, label_regions, loop_levels, region_stats
from isophote.encoder._kernels.regions_ref import (
    cap_sums as cap_sums_ref, label_regions as label_regions_ref, region_levels as region_levels_ref,
    region_stats as region_stats_ref,
)
from isophote.encoder.isolines import pad_grid
from isophote.encoder.levels import bands
from isophote.encoder.ribbon import gradient_magnitude
from kernel_inputs import SEEDS, nested_loops, random_grid, shoelace, split_at_half_rows


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
    # the encoder's loop by loop kernel: the twin's levels from loops, without border
    # segments, each segment's above sample a 4-neighbour of its below one named by its step
    below = rng.choice(inner, n)
    step = rng.integers(0, 4, n).astype(np.int8)
    above = above_of(below, step, wp)
    assert np.array_equal(step_codes(below, above, wp), step)
    counts = rng.integers(1, 9, 40)
    offsets = np.concatenate([[0], np.cumsum(counts)])[: np.searchsorted(np.cumsum(counts), n) + 1]
    offsets[-1] = n
    loop_lev = rng.integers(0, len(levels), offsets.shape[0] - 1).astype(np.int32)
    per_seg = np.repeat(loop_lev, np.diff(offsets)).astype(np.int64)
    border = rng.random(n) < 0.2
    lo_l, hi_l = loop_levels(labels, band, step, below, border, offsets, loop_lev, m)
    lo_r, hi_r = region_levels_ref(labels, band, above[~border], below[~border], per_seg[~border], m)
    assert np.array_equal(lo_l[hi_l >= 0], lo_r[hi_r >= 0]) and np.array_equal(hi_l, hi_r)
    assert (hi_l >= 0).sum() > 5
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
    """The loops' segments, split at half rows, as the hierarchy holds them: (x, y, nxt,
    seg_loop, row, n_rows, loop_start), segment s running from point s to point nxt[s] (the
    kernels find it from loop_start, each loop's first point), row being each segment's
    half-pixel row."""
    split = [split_at_half_rows(p) for p in loops]
    x = np.concatenate([p[:, 0] for p in split])
    y = np.concatenate([p[:, 1] for p in split])
    start = np.cumsum([0] + [len(p) for p in split])
    nxt = np.concatenate([s + np.roll(np.arange(len(p)), -1) for s, p in zip(start, split)]).astype(np.int32)
    seg_loop = np.concatenate([np.full(len(p), k) for k, p in enumerate(split)]).astype(np.int32)
    n_rows = int(2 * h) + 1
    row = np.clip(np.floor(np.minimum(y, y[nxt]) * 2).astype(np.int64), 0, n_rows - 1)
    return x, y, nxt, seg_loop, row, n_rows, start[:-1].astype(np.int64)


@pytest.mark.parametrize("seed", SEEDS)
def test_innermost_enclosing_matches_its_twin(seed):
    rng = np.random.default_rng(200 + seed)
    w, h = 30.0, 20.0
    loops = nested_loops(rng, w, h)
    area = np.array([shoelace(p) for p in loops])
    level = rng.integers(0, 5, size=len(loops)).astype(np.int64)
    x0, y0, nxt, seg_loop, row, n_rows, loop_start = loop_segments(loops, h)
    assert np.all(np.maximum(y0, y0[nxt]) <= (row + 1) / 2 + 1e-12)  # one row per segment
    row_order = np.argsort(row, kind="stable")
    row_start = np.searchsorted(row[row_order], np.arange(n_rows + 1))
    # queries: random points, and a point of each loop excluding that loop (as the hierarchy)
    px = np.concatenate([rng.uniform(0, w, 200), [0.5 * (p[0, 0] + p[1, 0]) for p in loops]])
    py = np.concatenate([rng.uniform(0, h, 200), [0.5 * (p[0, 1] + p[1, 1]) for p in loops]])
    exclude = np.concatenate([np.full(200, -1), np.arange(len(loops))]).astype(np.int64)
    offsets = np.append(loop_start, len(x0))
    assert np.array_equal(np.repeat(np.arange(len(loops)), np.diff(offsets)), seg_loop)
    fast = innermost_enclosing(px, py, exclude, x0, y0, offsets, loop_blocks(offsets), row_start, row_order,
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
    x, y, nxt, seg_loop, row, n_rows, loop_start = loop_segments(loops, h)
    row_start, row_order = bucket_rows(row, n_rows)
    assert np.array_equal(row_order, np.argsort(row, kind="stable"))
    assert np.array_equal(row_start, np.searchsorted(row[row_order], np.arange(n_rows + 1)))
    n = 400
    px = np.concatenate([rng.uniform(-1, w + 1, n), np.round(rng.uniform(0, w, n) * 2) / 2])
    py = np.concatenate([rng.uniform(-1, h + 1, n), np.round(rng.uniform(0, h, n) * 2) / 2])
    exclude = np.where(rng.random(2 * n) < 0.2, rng.integers(0, len(loops), 2 * n), -1).astype(np.int64)
    offsets = np.append(loop_start, len(x))
    args = (x, y, offsets, loop_blocks(offsets), row_start, row_order, area, level, n_rows)
    rays = innermost_enclosing(px, py, exclude, *args)
    rows = innermost_enclosing_rows(px, py, exclude, *args)
    assert np.array_equal(rows, rays)
    assert (rows >= 0).sum() > n // 2




@pytest.mark.parametrize("seed", SEEDS)
def test_points_are_their_compact_form_to_the_bit(seed):
    """Isolines hold a crossing as its edge's below sample, which 4-neighbour the above one
    is (step) and its coordinate along the edge (along): the other coordinate is the below
    sample's, so points_of gives the march's points back to the bit, border points (whose
    below sample is padding) included, and above_of its above samples."""
    from isophote.encoder.isolines import along_of, find_isolines, pad_grid, points_of, xy_in_place
    from isophote.encoder.levels import preset_levels
    from isophote.encoder.mapping import map_pixels

    rng = np.random.default_rng(900 + seed)
    img = np.clip(rng.normal(128, 60, (17, 23)), 0, 255)
    levels = preset_levels(16)
    grid, grid_eps = map_pixels(img, 0.5)
    vals, band = pad_grid(grid, levels)
    raw = march_loops(vals, band, np.asarray(levels, np.float64), grid, np.broadcast_to(grid_eps, grid.shape).copy())
    points, border, below, above = raw[1], raw[2], raw[3], raw[4]
    wp = band.shape[1]
    step = step_codes(below, above, wp)
    assert np.array_equal(above_of(below, step, wp), above)
    got = points_of(below, step, along_of(points, step), wp)
    assert got.tobytes() == points.tobytes()
    assert border.any() and (step <= 1).any() and (step >= 2).any()
    iso = find_isolines(grid, grid_eps, levels)
    assert iso.points.tobytes() == points.tobytes()
    along = along_of(points, step)
    x, y = xy_in_place(along, below, step, wp)  # x made in along's memory
    assert x is along and x.tobytes() == points[:, 0].copy().tobytes() and y.tobytes() == points[:, 1].copy().tobytes()


def test_xy_in_place_giving_back_the_compact_form_as_it_goes(monkeypatch):
    """With release, below and step go chunk by chunk as y is made (their pages, once read:
    never before), and x and y are those of the plain call."""
    from isophote.encoder import isolines as I

    rng = np.random.default_rng(3)
    n, wp = 5000, 57
    below = rng.integers(wp, 30 * wp, n).astype(np.int32)
    step = rng.integers(0, 4, n).astype(np.int8)
    along = rng.uniform(0, 20, n)
    want = I.xy_in_place(along.copy(), below, step, wp)
    seen = []
    real = I.release_read
    def spy(a, lo, hi):
        assert hi <= n and (a is below or a is step)
        seen.append((lo, hi))
        real(a, lo, hi)
    monkeypatch.setattr(I, "release_read", spy)
    monkeypatch.setattr(I, "POINTS_CHUNK", 700)
    b2, s2 = below.copy(), step.copy()
    below, step = b2, s2
    got = I.xy_in_place(along.copy(), below, step, wp, release=True)
    assert all(np.array_equal(a, b) for a, b in zip(got, want))
    assert seen[::2] == [(a, min(a + 700, n)) for a in range(0, n, 700)]  # in order, each chunk once read
