"""The smooth-region artefact measure (isophote/banding.py) and grain smoothing
(encoder/noise.py smooth_grain), against known answers."""

import numpy as np
import pytest

from isophote.banding import BAND_GAIN, FLOOR, GAIN, smooth_artefacts, smooth_mask
from isophote.encoder.noise import local_noise, smooth_grain


def _sky(h=160, w=200, noise=0.0, seed=3):
    """A slow grey ramp (0.15 grey levels a pixel), with white noise of deviation ``noise``."""
    y, x = np.mgrid[0:h, 0:w]
    a = 110.0 + 0.15 * x + 0.05 * y
    if noise:
        a = a + np.random.default_rng(seed).normal(0.0, noise, a.shape)
    return np.repeat(a[..., None], 3, axis=2)


def _u8(a):
    return np.clip(np.rint(a), 0, 255).astype(np.uint8)


def test_band_gain_is_the_norm_of_the_difference_of_gaussians():
    # ||G_a - G_b||^2 for white noise, checked on a discrete impulse
    from scipy import ndimage

    d = np.zeros((129, 129))
    d[64, 64] = 1.0
    k = ndimage.gaussian_filter(d, 2.0) - ndimage.gaussian_filter(d, 8.0)
    assert np.sqrt((k ** 2).sum()) == pytest.approx(BAND_GAIN, rel=0.02)
    assert FLOOR == pytest.approx(GAIN * BAND_GAIN / np.sqrt(12.0))


def test_a_ramp_is_smooth_and_a_render_equal_to_it_has_no_artefact():
    ref = _u8(_sky())
    assert smooth_mask(ref).mean() > 0.8
    r = smooth_artefacts(ref, ref)
    assert r["y"] == 0.0 and r["uv"] == 0.0 and r["y_a"] == 0.0 and r["ok"]


def test_terraces_are_flagged_and_faint_noise_is_not():
    ref = _sky()
    terraces = 127.5 + 6.0 * np.floor((ref - 127.5) / 6.0) + 3.0  # levels every 6, flat between
    bad = smooth_artefacts(_u8(ref), _u8(terraces))
    assert not bad["ok"] and bad["y_a"] > 5 * max(bad["y_own"], FLOOR)
    grainy = _sky(noise=1.0)
    fine = smooth_artefacts(_u8(grainy), _u8(grainy + np.random.default_rng(5).normal(0.0, 0.3, grainy.shape)))
    assert fine["ok"], fine  # an error fainter than the original's own grain passes


def test_chroma_blotches_are_flagged_in_uv_only():
    ref = _sky()
    blot = ref.copy()
    yy, xx = np.mgrid[0:160, 0:200]
    bump = 3.0 * np.exp(-((yy - 80) ** 2 + (xx - 100) ** 2) / (2 * 6.0 ** 2))
    blot[..., 0] += bump  # red up, blue down: luma nearly still, chroma moves
    blot[..., 2] -= bump * 0.299 / 0.114
    r = smooth_artefacts(_u8(ref), _u8(blot))
    assert not r["ok"] and r["uv_a"] > 3 * r["y_a"]


def test_the_own_level_follows_the_grain():
    ref = _u8(_sky(noise=2.0))
    r = smooth_artefacts(ref, ref)
    # 2 x 0.128 x sigma, sigma about 2 (the 8-bit rounding adds a little)
    assert r["y_own"] == pytest.approx(GAIN * BAND_GAIN * 2.0, rel=0.2)


def test_textured_images_have_no_smooth_region():
    ref = _u8(np.random.default_rng(1).uniform(0, 255, (120, 120, 3)))
    r = smooth_artefacts(ref, ref)
    assert r["share"] < 0.01 and np.isnan(r["y"]) and r["ok"]


def test_shapes_must_match():
    with pytest.raises(ValueError):
        smooth_artefacts(np.zeros((10, 10, 3)), np.zeros((10, 12, 3)))


# ------------------------------------------------------------------------ grain smoothing


def test_grain_on_a_slow_ramp_is_taken_out_within_its_bound():
    plane = _sky(noise=0.5)[..., 0]
    clean = _sky()[..., 0]
    out = smooth_grain(plane, 2.0)
    inner = (slice(8, -8), slice(8, -8))
    assert np.std((out - clean)[inner]) < 0.35 * np.std((plane - clean)[inner])
    assert np.all(np.abs(out - plane) <= 2.0 * local_noise(plane) + 1e-9)


def test_texture_and_clean_edges_keep_their_samples():
    rng = np.random.default_rng(2)
    texture = 128.0 + rng.normal(0.0, 8.0, (96, 96))  # reads as noise of deviation 8 > 2
    assert np.array_equal(smooth_grain(texture, 2.0), texture)
    edge = np.where(np.arange(96)[None, :] < 48, 50.0, 200.0) * np.ones((96, 1))
    assert np.array_equal(smooth_grain(edge, 2.0), edge)  # no grain: nothing moves
    assert np.array_equal(smooth_grain(texture, 0.0), texture)


# ------------------------------------------------------------------------ finer steps on smooth photographs


def test_smooth_photographs_get_the_finer_step_and_textured_ones_keep_theirs():
    from isophote.encoder.noise import adapt_steps
    from isophote.options import EncodeOptions

    opts = EncodeOptions(preset="balanced").resolved()
    assert (opts.y_step, opts.uv_step, opts.smooth_step) == (6.0, 5.0, 3.0)
    high = EncodeOptions(preset="high").resolved()
    assert (adapt_steps(high, _sky(noise=0.5)[..., 0]).y_step, high.smooth_grain) == (2.0, 2.0)
    smooth = adapt_steps(opts, _sky(noise=0.5)[..., 0])
    assert (smooth.y_step, smooth.uv_step) == (3.0, 3.0)
    texture = 128.0 + np.random.default_rng(4).normal(0.0, 6.0, (96, 96))
    assert (adapt_steps(opts, texture).y_step, adapt_steps(opts, texture).uv_step) == (6.0, 5.0)
    # explicit steps are kept as given; the paper preset has no finer step
    assert EncodeOptions(preset="balanced", y_step=8.0).resolved().smooth_step == 0.0
    assert adapt_steps(EncodeOptions(preset="balanced", y_step=8.0).resolved(), _sky()[..., 0]).y_step == 8.0
    assert adapt_steps(EncodeOptions(preset="paper").resolved(), _sky()[..., 0]).y_step == 10.0


def test_a_smooth_photograph_is_encoded_on_the_finer_levels():
    import isophote

    img = _u8(_sky(64, 80, noise=0.5))
    vi = isophote.encode(img)
    assert np.allclose(np.diff(vi.channel("Y").levels), 3.0)
    assert np.allclose(np.diff(isophote.encode(img, preset="paper").channel("Y").levels), 10.0)


def test_smooth_options_are_checked():
    from isophote.errors import OptionError
    from isophote.options import EncodeOptions

    for bad in (dict(smooth_step=0.2), dict(smooth_grain=-1.0), dict(smooth_grain=17.0)):
        with pytest.raises(OptionError):
            EncodeOptions(**bad).resolved()


def test_grain_smoothing_is_kept_for_smooth_photographs_only():
    from isophote.encoder.noise import adapt_steps
    from isophote.options import EncodeOptions

    opts = EncodeOptions(preset="balanced").resolved()
    assert opts.smooth_grain == 2.0
    assert adapt_steps(opts, _sky(noise=0.5)[..., 0]).smooth_grain == 2.0
    texture = 128.0 + np.random.default_rng(4).normal(0.0, 6.0, (96, 96))
    assert adapt_steps(opts, texture).smooth_grain == 0.0


def test_clean_but_busy_photographs_are_not_smooth():
    from isophote.encoder.noise import is_smooth

    assert is_smooth(_sky(noise=0.5)[..., 0])
    # noise-free stripes 8 px wide: every pixel reads as noiseless, the gradient is large
    stripes = np.where((np.arange(128) // 8) % 2 == 0, 60.0, 180.0)[None, :] * np.ones((96, 1))
    assert not is_smooth(stripes)


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (5, 2), (2, 2)])
def test_tiny_planes_are_never_smooth_and_keep_their_samples(shape):
    from isophote.encoder.noise import is_smooth

    plane = np.arange(np.prod(shape), dtype=np.float64).reshape(shape)
    assert not is_smooth(plane)
    out = smooth_grain(plane, 2.0)
    assert out.shape == shape and (min(shape) < 2 or np.all(np.isfinite(out)))
    if min(shape) < 2:
        assert np.array_equal(out, plane)
