"""Per-pixel noise (encoder/noise.py), pruning (encoder/prune.py) and the JPEG floor
(imageio.dct_quantisation_error), each against known answers."""

import numpy as np
import pytest

import isophote
from isophote.encoder.noise import CAP_FRACTION, local_noise, medians, prepare_plane, residual, sample_error
from isophote.encoder._kernels.prune_ref import prune as prune_ref
from isophote.encoder.prune import prune_extrema
from isophote.imageio import dct_quantisation_error, read_image
from isophote.options import EncodeOptions

# The IJG luminance and chrominance tables (ITU-T T.81 Annex K), natural order: what
# libjpeg writes at quality 50, where its scaling factor is 100 %.
IJG_LUMA = np.array([
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55,
    14, 13, 16, 24, 40, 57, 69, 56, 14, 17, 22, 29, 51, 87, 80, 62,
    18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113, 92,
    49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99,
])
IJG_CHROMA = np.array([17, 18, 24, 47, 99, 99, 99, 99, 18, 21, 26, 66, 99, 99, 99, 99,
                       24, 26, 56, 99, 99, 99, 99, 99, 47, 66, 99, 99, 99, 99, 99, 99] + [99] * 32)


def _ramp(h=96, w=128):
    y, x = np.mgrid[0:h, 0:w]
    return 40.0 + 1.2 * x + 0.4 * y


# ------------------------------------------------------------------------ local estimate


def test_residual_ignores_planes():
    assert np.abs(residual(_ramp())[1:-1, 1:-1]).max() < 1e-9


@pytest.mark.parametrize("win", [16, 15, 4, 3])
def test_window_medians_are_numpys(win):
    """The kernel selects each window's middle samples in place; its twin gathers the
    windows and takes NumPy's median: the same bits, with ties (integer samples), odd and
    even windows, and windows that overlap or skip samples."""
    from isophote.encoder._kernels.median import window_medians
    from isophote.encoder._kernels.median_ref import window_medians as window_medians_ref

    rng = np.random.default_rng(win)
    for rp in (rng.integers(0, 6, (61, 83)).astype(np.float64), rng.standard_normal((61, 83)) * 7.3,
               np.full((61, 83), 2.5)):
        rows = np.arange(0, 61 - win + 1, 5, dtype=np.int64)
        cols = np.array([0, 1, 2, 17, 83 - win], np.int64)
        got = window_medians(rp, rows, cols, win)
        assert np.array_equal(got, window_medians_ref(rp, rows, cols, win))
        # the encoder's runs of lattice rows on threads: the same values, any count
        for workers in (1, 2, 3, 40):
            assert np.array_equal(medians(rp, rows, cols, win, workers), got), workers
    one = np.arange(9.0).reshape(3, 3)[::-1]  # 8 .. 0: the middle of 9 is 4
    assert window_medians(np.ascontiguousarray(one), np.zeros(1, np.int64), np.zeros(1, np.int64), 3)[0, 0] == 4.0
    two = np.array([[1.0, 9.0], [3.0, 4.0]])  # the mean of the middle two, 3 and 4
    assert window_medians(two, np.zeros(1, np.int64), np.zeros(1, np.int64), 2)[0, 0] == 3.5


@pytest.mark.parametrize("sigma", [1.0, 3.0, 8.0])
def test_white_noise_deviation_comes_back_within_15_percent(sigma):
    rng = np.random.default_rng(7)
    plane = _ramp() + rng.normal(0.0, sigma, (96, 128))
    est = local_noise(plane)
    assert est.shape == plane.shape
    assert 0.85 * sigma < np.median(est) < 1.15 * sigma
    assert est.min() > 0.6 * sigma and est.max() < 1.5 * sigma


def test_estimate_is_local():
    rng = np.random.default_rng(8)
    plane = _ramp() + rng.normal(0.0, 1.0, (96, 128))
    plane[:, 64:] += rng.normal(0.0, 6.0, (96, 64))  # right half: deviation sqrt(37)
    est = local_noise(plane)
    left, right = np.median(est[:, :48]), np.median(est[:, 80:])
    assert 0.8 < left < 1.25
    assert 0.8 * np.sqrt(37) < right < 1.2 * np.sqrt(37)


def test_an_edge_does_not_read_as_noise():
    """A 100-level step crosses every window it touches; the median ignores it."""
    rng = np.random.default_rng(9)
    plane = _ramp() + rng.normal(0.0, 2.0, (96, 128))
    plane[:, 61:] += 100.0
    est = local_noise(plane)
    assert est[:, 50:72].max() < 1.6 * 2.0


def test_clean_quantised_ramp_has_little_noise():
    est = local_noise(np.round(_ramp()))
    assert est.max() < 0.5


# ------------------------------------------------------------------------ sample error


def test_sample_error_floors_and_cap():
    rng = np.random.default_rng(10)
    plane = _ramp() + rng.normal(0.0, 2.0, (96, 128))
    levels = np.arange(7.5, 250, 10.0)
    eps = sample_error(plane, 0.5, levels, local=1.0)
    assert 1.5 < np.median(eps) < 2.5
    # the global error is a floor, the JPEG-like floor raises the deviation, the cap holds
    assert np.all(sample_error(plane, 3.0, levels, local=1.0) >= 3.0)
    assert np.allclose(sample_error(plane, 0.5, levels, local=1.0, floor=3.5), 3.5)
    capped = sample_error(plane, 0.5, levels, local=10.0)
    assert np.allclose(capped, CAP_FRACTION * 10.0)


def test_paper_options_leave_the_plane_untouched():
    plane = _ramp()
    opts = EncodeOptions(preset="paper").resolved()
    out, eps = prepare_plane("Y", plane, 0.5, np.arange(7.5, 250, 10.0), opts)
    assert out is plane and eps == 0.5


def test_paper_encode_equals_the_explicit_global_error():
    rng = np.random.default_rng(11)
    img = np.clip(_ramp() + rng.normal(0, 3, (96, 128)), 0, 255).astype(np.uint8)
    a = isophote.encode(img, preset="paper")
    b = isophote.encode(img, preset="paper", noise=0.5, local_noise=0, prune_area_y=0, prune_area_uv=0,
                        max_tolerance=0.5)
    assert a.equals(b)


def test_wider_ribbons_where_noisy_mean_fewer_segments():
    rng = np.random.default_rng(12)
    y, x = np.mgrid[0:96, 0:128]
    img = 128 + 60 * np.sin(x / 9.0) * np.cos(y / 13.0) + rng.normal(0, 3.0, (96, 128))
    img = np.clip(img, 0, 255).astype(np.uint8)
    fixed = isophote.encode(img, preset="paper")
    auto = isophote.encode(img, preset="paper", noise="auto")
    assert auto.channels[0].n_contours == fixed.channels[0].n_contours  # same isolines
    assert auto.channels[0].n_segments < 0.85 * fixed.channels[0].n_segments


# ------------------------------------------------------------------------ pruning


def _blob_scene():
    """A smooth ramp with a tiny, faint blob (peak 1.5 levels over 127.5) and a
    high-contrast disc, both crossing the level 127.5."""
    y, x = np.mgrid[0:64, 0:96].astype(float)
    plane = 100.0 + 0.2 * x  # 100 .. 119: below 127.5 everywhere
    plane[30:32, 20:22] = 129.0  # 4 pixels, 1.5 over the level
    disc = (x - 70) ** 2 + (y - 32) ** 2 < 3.0**2  # about 29 pixels, 100 levels over
    plane[disc] = 227.0
    return plane, disc


def test_prune_flattens_the_faint_blob_and_keeps_the_disc():
    plane, disc = _blob_scene()
    out = prune_extrema(plane, [127.5], area=40, contrast=2.0)
    assert out[30:32, 20:22].max() < 127.5 <= plane[30:32, 20:22].min()
    assert np.array_equal(out[disc], plane[disc])
    moved = out != plane
    assert np.count_nonzero(moved) == 4 and np.abs(out - plane).max() < 2.0


def test_prune_raises_faint_pits_to_the_level():
    plane = np.full((40, 40), 140.0)
    plane[10:12, 10:13] = 127.0  # a 6-pixel pit half a level under 127.5
    out = prune_extrema(plane, [127.5], area=16, contrast=1.0)
    assert out.min() == 127.5


def test_prune_keeps_faint_but_large_regions():
    plane, _ = _blob_scene()
    plane[5:15, 40:55] = 128.0  # 150 pixels just over the level
    out = prune_extrema(plane, [127.5], area=40, contrast=2.0)
    assert np.array_equal(out[5:15, 40:55], plane[5:15, 40:55])


def test_prune_kernel_equals_its_twin():
    """The compiled pruning (components grown from the samples near each level) gives the
    twin's bits (every component labelled over the plane), on noisy planes with integer
    and real samples, scalar and per-pixel thresholds, fractional areas, and a plane whose
    every sample lies near the level (one large component the kernel must give up)."""
    rng = np.random.default_rng(0)
    changed = 0
    for _ in range(300):
        h, w = rng.integers(1, 40, 2)
        f = rng.normal(128.0, rng.uniform(0.5, 20.0), (h, w))
        if rng.random() < 0.5:
            f = np.round(f)
        levels = np.sort(rng.uniform(100.0, 160.0, rng.integers(1, 8)))
        thr = rng.uniform(0.0, 4.0, (h, w)) if rng.random() < 0.5 else float(rng.uniform(0.0, 4.0))
        area = float(rng.choice([2.0, 3.0, 5.0, 15.5, 16.0, 40.0, 1e6]))
        out = prune_extrema(f, levels, area, thr)
        assert np.array_equal(out, prune_ref(f, levels, area, thr))
        changed += int(np.count_nonzero(out != f))
    assert changed > 1000  # the comparison saw real pruning
    flat = 127.5 + rng.uniform(-0.4, 0.4, (30, 30))
    out = prune_extrema(flat, [127.5], 16, 1.0)
    assert np.array_equal(out, prune_ref(flat, [127.5], 16, 1.0)) and not np.array_equal(out, flat)


def test_pruned_encode_loses_the_blob_loop_only():
    plane, _ = _blob_scene()
    img = np.clip(np.round(plane), 0, 255).astype(np.uint8)
    levels = (127.5,)
    kept = isophote.encode(img, levels_y=levels)
    pruned = isophote.encode(img, levels_y=levels, prune_area_y=40, prune_contrast=4.0)
    assert kept.channels[0].n_contours == 2
    assert pruned.channels[0].n_contours == 1
    # the survivor is the disc's loop
    ch = pruned.channels[0]
    centre = ch.points[ch.offsets[0]:ch.offsets[1]].mean(axis=0)
    assert np.hypot(centre[0] - 70.5, centre[1] - 32.5) < 1.0


# ------------------------------------------------------------------------ JPEG floor


def test_dct_quantisation_error_known_answers():
    assert dct_quantisation_error(np.ones(64)) == pytest.approx(np.sqrt(1 / 12))
    assert dct_quantisation_error(np.full(64, 6.0)) == pytest.approx(6 / np.sqrt(12))
    with pytest.raises(ValueError):
        dct_quantisation_error(np.ones(63))


@pytest.mark.parametrize("quality, luma, chroma", [
    (50, IJG_LUMA, IJG_CHROMA),
    (100, np.ones(64), np.ones(64)),
])
def test_jpeg_floor_read_from_a_pillow_jpeg(tmp_path, quality, luma, chroma):
    from PIL import Image

    rng = np.random.default_rng(13)
    rgb = rng.integers(0, 256, (32, 48, 3), dtype=np.uint8)
    path = tmp_path / "x.jpg"
    Image.fromarray(rgb).save(path, quality=quality)
    floor = read_image(path).noise_floor
    want_y, want_c = dct_quantisation_error(luma), dct_quantisation_error(chroma)
    assert floor == pytest.approx((want_y, want_c, want_c))
    Image.fromarray(rgb[..., 0]).save(tmp_path / "g.jpg", quality=quality)
    assert read_image(tmp_path / "g.jpg").noise_floor == pytest.approx((want_y,))


def test_no_floor_for_lossless_files(tmp_path):
    from PIL import Image

    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(tmp_path / "x.png")
    assert read_image(tmp_path / "x.png").noise_floor is None


@pytest.mark.parametrize("shape", [(3, 3), (5, 200), (257, 131)])
def test_smoothness_measures_in_runs_of_rows_have_the_whole_computations_bits(monkeypatch, shape):
    """is_smooth's share of fine-grained pixels and mean gradient, a run of 1, 7 or all rows
    at a time, equal the whole-plane formulas bit for bit (and so decide alike)."""
    from scipy import ndimage

    from isophote.encoder import noise

    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    luma = 128 + 40 * np.sin(xx / 9.0) * np.cos(yy / 13.0) + np.random.default_rng(0).normal(0, 0.6, shape)
    share = float(np.mean(local_noise(luma) < noise.GRAIN_FULL))
    grad = float(np.hypot(*np.gradient(ndimage.gaussian_filter(luma, 1.0))).mean())
    assert 0 < share <= 1 and grad > 0
    for rows in (1, 7, shape[0]):
        monkeypatch.setattr(noise, "SMOOTH_RUN_PIXELS", rows * shape[1])
        assert noise.fine_share(luma) == share and noise.mean_gradient(luma) == grad
        assert noise.is_smooth(luma) == (share >= noise.SMOOTH_SHARE and grad < noise.SMOOTH_GRADIENT)


def test_pruning_thresholds_made_in_runs_of_rows_prune_alike(monkeypatch):
    """The pruning's thresholds, made a run of the error rows at a time (1, 5 rows or all),
    prune the plane to the same bits, and pruning does move samples here."""
    from isophote.encoder import noise

    rng = np.random.default_rng(4)
    plane = _ramp() + rng.normal(0, 2.0, (96, 128))
    opts = EncodeOptions(preset="balanced").resolved()
    levels = np.arange(3.5, 250, 4.0)
    want, _ = prepare_plane("U", plane, 0.5, levels, opts)
    assert not np.array_equal(want, plane)
    for rows in (1, 5):
        monkeypatch.setattr(noise, "SMOOTH_RUN_PIXELS", rows * plane.shape[1])
        got, _ = prepare_plane("U", plane, 0.5, levels, opts)
        assert np.array_equal(got, want)


@pytest.mark.parametrize("shape", [(2, 2), (3, 50), (257, 131)])
def test_grain_smoothing_in_runs_of_rows_is_the_whole_formulas(monkeypatch, shape):
    """smooth_grain a run of 1, 7 or all rows at a time gives the whole-plane formula's
    bits (module docstring, "Grain smoothing"), with the noise estimated or given, and moves
    the grain."""
    from scipy import ndimage

    from isophote.encoder import noise

    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    plane = 128 + 40 * np.sin(xx / 9.0) * np.cos(yy / 13.0) + np.random.default_rng(1).normal(0, 0.6, shape)
    plane[:, :1] = 100.0
    t = 2.0
    for sigma in (None, np.full(shape, 0.4)):
        s = local_noise(plane) if sigma is None else sigma
        g = ndimage.gaussian_filter(plane, noise.GRAIN_SIGMA, mode="nearest")
        grad = np.hypot(*np.gradient(g))
        with np.errstate(divide="ignore", invalid="ignore"):
            wander = np.where(grad > 0, s / np.maximum(grad, 1e-300), np.inf)
        bound = (t * s * np.clip(2.0 - s / noise.GRAIN_FULL, 0.0, 1.0)
                 * np.clip(np.nan_to_num(wander / noise.GRAIN_WANDER - 1.0, posinf=1.0), 0.0, 1.0))
        want = plane + np.clip(g - plane, -bound, bound)
        assert shape[0] < 100 or not np.array_equal(want, plane)  # the grain moves where there is room
        for rows in (1, 7, shape[0]):
            monkeypatch.setattr(noise, "SMOOTH_RUN_PIXELS", rows * shape[1])
            assert np.array_equal(noise.smooth_grain(plane, t, sigma), want)
