"""Strips (encoder/strips.py, issue 22): the grid's rows computed alone, and the isolines of
strips joined across their edges, are the whole grid's to the bit, at every strip height."""

from __future__ import annotations

import numpy as np
import pytest

from isophote.colour import rgb_to_yuv
from isophote.encoder.isolines import find_isolines
from isophote.encoder.levels import channel_levels
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
            assert a.dtype == b.dtype and np.array_equal(a, b), (rows, f)
        assert got.base_band == ref.base_band
        # the values are not held: the row source gives the whole grid's rows, any range
        hp = ref.values.shape[0]
        for w0, w1 in ((0, hp), (0, 1), (3, 9), (hp - 2, hp), (5, 5)):
            assert np.array_equal(got.values(w0, w1), ref.values[w0:w1]), (rows, w0, w1)


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
