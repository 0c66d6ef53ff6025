"""Strips (encoder/strips.py, issue 22): the grid's rows computed alone, and the isolines of
strips joined across their edges, are the whole grid's to the bit, at every strip height."""

from __future__ import annotations

import numpy as np
import pytest

from isophote.colour import rgb_to_yuv
from isophote.encoder.isolines import find_isolines
from isophote.encoder.levels import band_dtype, channel_levels
from isophote.encoder.mapping import map_pixels, map_rows
from isophote.encoder.noise import prepare_plane
from isophote.encoder.strips import strip_isolines
from isophote.options import EncodeOptions

from test_encode_budget import texture

FIELDS = ("points", "offsets", "border", "tol", "level", "step", "below", "band")


@pytest.mark.parametrize("h, w", [(1, 1), (1, 5), (2, 3), (5, 1), (7, 9), (12, 17)])
def test_map_rows_are_the_rows_of_map_pixels(h, w):
    rng = np.random.default_rng(h * 31 + w)
    v = rng.uniform(0, 255, (h, w))
    e = rng.uniform(0.5, 3.0, (h, w))
    g, ge = map_pixels(v, e, 0.5, 64.0, 2.0)
    for g0 in range(0, 2 * h + 1):
        for g1 in range(g0, 2 * h + 2):
            a, ae = map_rows(v, e, 0.5, 64.0, 2.0, g0, g1)
            assert np.array_equal(a, g[g0:g1]) and np.array_equal(ae, ge[g0:g1]), (g0, g1)


@pytest.mark.parametrize("preset, name", [("balanced", "Y"), ("balanced", "U"), ("paper", "Y"), ("high", "V")])
def test_strips_give_the_isolines_of_one_march(preset, name):
    opts = EncodeOptions(preset=preset).resolved()
    yuv = rgb_to_yuv(texture(60, 80).astype(np.float64))
    levels = channel_levels(name, opts)
    plane, eps = prepare_plane(name, yuv[..., "YUV".index(name)].copy(), 0.5, levels, opts)
    grid, grid_eps = map_pixels(plane, eps, opts.carrato_p, opts.carrato_scale, opts.carrato_cubic)
    ref = find_isolines(grid, grid_eps, levels, opts.min_tolerance, opts.max_tolerance)
    assert ref.n_loops > 100
    # loops that cross strip edges, and loops on the frame (the lowest levels run round it)
    tall = np.diff(np.array([[ref.loop(i)[:, 1].min(), ref.loop(i)[:, 1].max()]
                             for i in range(ref.n_loops)]), axis=1).max()
    assert tall > 10
    for rows, workers in ((1, 1), (2, 2), (5, 2), (33, 1), (10_000, 1)):
        got = strip_isolines(plane, eps, levels, opts, rows, workers)
        for f in FIELDS:
            a, b = getattr(ref, f), getattr(got, f)
            assert (a.dtype == b.dtype or f == "band") and np.array_equal(a, b), (rows, f)
        assert got.band.dtype == band_dtype(len(levels)) == np.uint8  # every preset's levels fit a byte
        assert got.base_band == ref.base_band
        # the values are not held: the row source gives the whole grid's rows, any range
        hp = ref.values.shape[0]
        for w0, w1 in ((0, hp), (0, 1), (3, 9), (hp - 2, hp), (5, 5)):
            assert np.array_equal(got.values(w0, w1), ref.values[w0:w1]), (rows, w0, w1)
    # and with the plane in a temporary file (the encoder's, between the march and the caps)
    assert got.values.spill() and callable(got.values.v) and got.values.spill()
    for w0, w1 in ((0, hp), (0, 1), (1, 4), (3, 9), (hp - 3, hp), (5, 5)):
        assert np.array_equal(got.values(w0, w1), ref.values[w0:w1]), ("spilled", w0, w1)


def test_a_flat_plane_has_only_frame_loops():
    opts = EncodeOptions(preset="balanced").resolved()
    levels = channel_levels("Y", opts)
    plane = np.full((9, 11), 200.0)
    got = strip_isolines(plane, 0.5, levels, opts, 3)
    assert got.n_loops == 0 and got.base_band == int(np.searchsorted(levels, 200.0, "right"))


def test_band_of_is_searchsorted_right():
    from isophote.encoder._kernels.marching import band_of

    levels = np.array([1.5, 4.5, 7.5, 10.5])
    # values on the levels themselves (ties go above), between, below and above all, signed zero
    v = np.array([[1.5, 4.5, 7.5, 10.5, 0.0, -0.0], [1.4999999, 4.50000001, 200.0, -3.0, 6.0, 10.49]])
    out = np.full(v.shape, -7, np.int16)
    band_of(v, levels, out)
    assert np.array_equal(out, np.searchsorted(levels, v, side="right"))
    assert out.tolist() == [[1, 2, 3, 4, 0, 0], [0, 2, 4, 0, 2, 3]]


@pytest.mark.parametrize("step", [1, 2, 5, 1000])
def test_caps_read_values_row_by_row_as_from_the_whole_grid(step):
    """The caps' kernels reading the values a few rows at a time (the encoder computes them
    again from the plane) give the whole grid's labels, statistics and sums to the bit."""
    from isophote.encoder._kernels import regions as R

    opts = EncodeOptions(preset="balanced").resolved()
    yuv = rgb_to_yuv(texture(40, 50).astype(np.float64))
    levels = channel_levels("Y", opts)
    plane, eps = prepare_plane("Y", yuv[..., 0].copy(), 0.5, levels, opts)
    got = strip_isolines(plane, eps, levels, opts, 7, 1)
    vals = got.values(0, got.band.shape[0])
    lab, m = R.label_regions(vals, got.band, levels)
    lab2, m2 = R.label_regions_rows(got.values, got.band, levels, step)
    assert m == m2 > 20 and np.array_equal(lab, lab2)
    # the strips recorded the joins the values decide: the labels without the values
    assert got.saddles.shape[0] > 0
    lab3, m3 = R.label_regions_saddles(got.band, got.saddles[::-1])  # any order
    assert m3 == m and np.array_equal(lab3, lab)
    for a, b in zip(R.region_stats(lab, vals, m), R.region_stats_rows(lab, got.values, m, step)):
        assert a.tobytes() == b.tobytes()
    want = np.zeros(m, bool)
    want[::3] = True
    L = np.linspace(0, 255, m)
    a, b = R.cap_sums(lab, vals, want, L, 4.0), R.cap_sums_rows(lab, got.values, want, L, 4.0, step)
    assert a[2] and b[2] and a[0].tobytes() == b[0].tobytes() and a[1].tobytes() == b[1].tobytes()
    # what the caps hold per cap (slots), not per region: the same values for those regions
    deep, total, count = R.region_stats(lab, vals, m)
    slot = R.slots_of(want)
    d2, c2 = R.region_deep(lab, slot)
    t2, n2, e2, edge = R.value_sums_rows(lab, got.values, slot, L[want], 4.0, True, step)
    assert d2.shape[0] == want.sum() < m and edge
    assert np.array_equal(d2, deep[want]) and np.array_equal(c2, count[want])
    assert t2.tobytes() == total[want].tobytes()
    assert n2.tobytes() == a[0][want].tobytes() and e2.tobytes() == a[1][want].tobytes()


def test_an_array_file_gives_its_rows_and_says_when_cut_short():
    from isophote.shared.spill import ArrayFile

    plane = np.arange(35.0).reshape(5, 7) / 3.0
    f = ArrayFile(plane)
    assert np.array_equal(f(0, 5), plane) and np.array_equal(f(2, 4), plane[2:4]) and f(3, 3).shape == (0, 7)
    chains = (np.arange(24, dtype=np.float32) * 1.5).reshape(12, 2)
    g = ArrayFile(chains)
    assert g(4, 99).dtype == np.float32 and np.array_equal(g(4, 99), chains[4:])
    back = g.whole()
    assert back.dtype == np.float32 and np.array_equal(back, chains) and g.file.closed
    f.file.truncate(3 * 7 * 8)
    with pytest.raises(OSError, match="cut short"):
        f(2, 5)


@pytest.mark.parametrize("h, w", [(2, 2), (13, 11), (61, 83)])
def test_error_rows_are_the_rows_of_sample_error(h, w):
    """The per-pixel errors asked for a few rows at a time (each strip asks for its own, so
    that they are not held whole through the march) are sample_error's rows to the bit."""
    from isophote.encoder.noise import error_rows, local_noise, noise_rows, sample_error

    rng = np.random.default_rng(h * 7 + w)
    # grain from 0.1 to 2 grey levels across: the errors vary, under the cap (2.4) and over eps0
    plane = 100.0 + np.linspace(0, 40, w) + rng.normal(0, 1, (h, w)) * np.linspace(0.1, 2.0, w)
    levels = np.arange(3.5, 252, 6.0)
    for floor, local in ((0.0, 1.0), (0.6, 1.2)):
        whole = sample_error(plane, 0.5, levels, local, floor)
        rows, sig = error_rows(plane, 0.5, levels, local, floor), noise_rows(plane)
        assert whole.shape == (h, w) and whole.min() >= 0.5
        assert np.unique(whole).size > (10 if min(h, w) > 20 else 0)
        for a in range(h):
            for b in (a, a + 1, min(h, a + 5), h):
                assert np.array_equal(rows(a, b), whole[a:b]), (a, b)
                assert np.array_equal(sig(a, b), local_noise(plane)[a:b]), (a, b)


@pytest.mark.parametrize("preset", ["balanced", "high"])
def test_strips_with_error_rows_give_the_isolines_of_the_whole_errors(preset):
    """The encoder's path (prepare_plane_rows: the errors a row source) gives the Isolines
    of the whole plane of errors at every strip height."""
    from isophote.encoder.noise import ErrorRows, prepare_plane_rows

    opts = EncodeOptions(preset=preset).resolved()
    yuv = rgb_to_yuv(texture(50, 70).astype(np.float64))
    levels = channel_levels("Y", opts)
    plane, eps = prepare_plane("Y", yuv[..., 0].copy(), 0.5, levels, opts)
    plane2, rows = prepare_plane_rows("Y", yuv[..., 0].copy(), 0.5, levels, opts)
    assert isinstance(rows, ErrorRows) and np.array_equal(plane, plane2)
    ref = strip_isolines(plane, eps, levels, opts, 10_000, 1)
    assert ref.n_loops > 50
    for r in (1, 3, 17):
        got = strip_isolines(plane2, rows, levels, opts, r, 2)
        for f in FIELDS:
            assert np.array_equal(getattr(ref, f), getattr(got, f)), (r, f)


def test_band_grid_type_holds_every_band():
    from isophote.encoder._kernels.regions import label_regions_saddles
    from isophote.encoder.levels import bands

    assert band_dtype(254) == np.uint8 and band_dtype(255) == np.int16 and band_dtype(3000) == np.int16
    # 300 levels (a step of 0.85): the bands go past a byte, the strips' grid is int16
    opts = EncodeOptions(preset="balanced").resolved()
    levels = np.arange(0.4, 255, 0.85)
    plane = np.linspace(0, 255, 40 * 30).reshape(30, 40)
    got = strip_isolines(plane, 0.5, levels, opts, 9, 2)
    assert got.band.dtype == np.int16 and got.band.max() > 255
    assert np.array_equal(got.band[2:-2:2, 2:-2:2], bands(plane, levels))  # the pixels' samples
    small = strip_isolines(plane, 0.5, levels[::2], opts, 9, 2)
    assert small.band.dtype == np.uint8 and np.array_equal(small.band[2:-2:2, 2:-2:2], bands(plane, levels[::2]))
    # the regions' labels of a uint8 grid are the int16 grid's
    a = label_regions_saddles(small.band, small.saddles)
    b = label_regions_saddles(small.band.astype(np.int16), small.saddles)
    assert a[1] == b[1] > 10 and np.array_equal(a[0], b[0])
