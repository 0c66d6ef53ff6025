"""Known answers for the fidelity metrics (isophote.metrics)."""

import math
import subprocess
import sys

import numpy as np
import pytest

from isophote import metrics
from isophote.errors import InputError, OptionError


def _photo(h=64, w=64):
    """A smooth colour image with an edge: ramps in R and G, a disc in B. uint8."""
    y, x = np.mgrid[0:h, 0:w]
    r = 40 + 160 * x / (w - 1)
    g = 200 - 150 * y / (h - 1)
    b = np.where((x - w / 2) ** 2 + (y - h / 2) ** 2 < (min(h, w) / 4) ** 2, 210.0, 60.0)
    return np.rint(np.stack([r, g, b], axis=2)).astype(np.uint8)


def _noisy(img, sigma, seed=0):
    rng = np.random.default_rng(seed)
    return np.clip(img + rng.normal(0.0, sigma, img.shape), 0, 255)


# --------------------------------------------------------------------------- psnr


def test_psnr_identical_is_inf():
    img = _photo()
    assert metrics.psnr(img, img) == math.inf
    assert metrics.psnr(img.astype(np.float64), img) == math.inf


def test_psnr_offset_of_one_grey_level():
    img = _photo().astype(np.float64)
    img = np.clip(img, 0, 254)
    assert metrics.psnr(img, img + 1) == pytest.approx(20 * math.log10(255), abs=1e-9)
    assert 20 * math.log10(255) == pytest.approx(48.13, abs=0.005)


def test_psnr_peak_and_known_mse():
    ref = np.zeros((8, 8))
    test = np.full((8, 8), 10.0)  # MSE 100
    assert metrics.psnr(ref, test) == pytest.approx(10 * math.log10(255**2 / 100))
    assert metrics.psnr(ref, test, peak=100.0) == pytest.approx(20.0)
    with pytest.raises(OptionError):
        metrics.psnr(ref, test, peak=0)


def test_psnr_grey_equals_replicated_rgb():
    grey = _photo()[..., 0]
    noisy = _noisy(grey, 4.0)
    rgb = np.repeat(grey[..., None], 3, axis=2)
    noisy_rgb = np.repeat(noisy[..., None], 3, axis=2)
    assert metrics.psnr(grey, noisy) == pytest.approx(metrics.psnr(rgb, noisy_rgb))


def test_psnr_clips_overshoot_like_a_display():
    ref = np.full((4, 4, 3), 255.0)
    assert metrics.psnr(ref, ref + 30.0) == math.inf


def test_alpha_hides_colour_under_transparency():
    img = np.dstack([_photo(), np.zeros((64, 64), np.uint8)])  # fully transparent
    other = img.copy()
    other[..., :3] = 255 - other[..., :3]
    assert metrics.psnr(img, other) == math.inf
    # ... but the difference image shows every channel as it is
    assert metrics.difference_image(img, other).max() > 0


# --------------------------------------------------------------------------- ssim


def test_ssim_identical_is_one_and_noise_lowers_it():
    img = _photo()
    assert metrics.ssim(img, img) == pytest.approx(1.0)
    assert metrics.ssim(img[..., 1], img[..., 1]) == pytest.approx(1.0)
    s4, s16 = metrics.ssim(img, _noisy(img, 4)), metrics.ssim(img, _noisy(img, 16))
    assert 1.0 > s4 > s16


def test_ssim_refuses_images_smaller_than_its_window():
    tiny = np.zeros((6, 20, 3))
    with pytest.raises(InputError, match="at least 7"):
        metrics.ssim(tiny, tiny)


# --------------------------------------------------------------------------- ssimulacra2


def test_ssimulacra2_identical_and_decreasing_with_noise():
    img = _photo()
    assert metrics.ssimulacra2(img, img) >= 99.0
    scores = [metrics.ssimulacra2(img, _noisy(img, s)) for s in (2, 8, 32)]
    assert 99.0 > scores[0] > scores[1] > scores[2]


def test_ssimulacra2_grey_input():
    grey = _photo()[..., 1]
    assert metrics.ssimulacra2(grey, grey) >= 99.0
    assert metrics.ssimulacra2(grey, _noisy(grey, 8)) < 99.0


def test_ssimulacra2_refuses_images_under_8_pixels():
    # The reference implementation answers 100 for any pair this small.
    tiny = np.zeros((7, 32, 3))
    with pytest.raises(InputError, match="at least 8"):
        metrics.ssimulacra2(tiny, tiny + 100)


# --------------------------------------------------------------------------- flip


def test_flip_identical_is_zero_and_noise_raises_it():
    img = _photo()
    assert metrics.flip(img, img) == 0.0
    f4, f16 = metrics.flip(img, _noisy(img, 4)), metrics.flip(img, _noisy(img, 16))
    assert 0.0 < f4 < f16 <= 1.0


def test_flip_grey_input():
    grey = _photo()[..., 2]
    assert metrics.flip(grey, grey) == 0.0
    assert metrics.flip(grey, _noisy(grey, 8)) > 0.0


# --------------------------------------------------------------------------- compare, difference


def test_compare_returns_the_metrics_asked_in_order():
    img = _photo()
    out = metrics.compare(img, img)
    assert list(out) == ["psnr", "ssim", "ssimulacra2", "flip"]
    assert out["psnr"] == math.inf and out["flip"] == 0.0
    assert list(metrics.compare(img, img, metrics=("flip", "psnr"))) == ["flip", "psnr"]
    assert list(metrics.compare(img, img, metrics="psnr")) == ["psnr"]
    with pytest.raises(OptionError, match="unknown metric"):
        metrics.compare(img, img, metrics=("psnr", "mse"))


def test_difference_image():
    img = _photo()
    d = metrics.difference_image(img, img)
    assert d.shape == (64, 64, 3) and not d.any()
    shifted = img.astype(np.float64) + 3.0
    assert np.all(metrics.difference_image(img, shifted, gain=4)[img < 252] == 12.0)
    assert metrics.difference_image(np.zeros((2, 2)), np.full((2, 2), 200.0)).max() == 255.0
    assert metrics.difference_image(np.zeros((2, 2)), np.ones((2, 2))).shape == (2, 2, 1)
    with pytest.raises(OptionError):
        metrics.difference_image(img, img, gain=0)


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("name", ["psnr", "ssim", "ssimulacra2", "flip"])
def test_bad_pairs_are_input_errors(name):
    f = metrics.METRICS[name]
    img = _photo()
    with pytest.raises(InputError, match="differ in shape"):
        f(img, img[:32])
    bad = img.astype(np.float64)
    bad[3, 3, 1] = np.nan
    with pytest.raises(InputError, match="finite"):
        f(img, bad)
    with pytest.raises(InputError, match="shape"):
        f(np.zeros((8, 8, 5)), np.zeros((8, 8, 5)))
    with pytest.raises(InputError, match="numeric"):
        f(np.full((8, 8), "a"), np.full((8, 8), "a"))


@pytest.mark.parametrize(
    "name, module", [("ssimulacra2", "ssimulacra2"), ("flip", "flip_evaluator")]
)
def test_missing_package_names_the_extra(monkeypatch, name, module):
    monkeypatch.setitem(sys.modules, module, None)  # makes `import module` fail
    img = _photo()
    with pytest.raises(OptionError, match=r"pip install isophote\[metrics\]"):
        metrics.METRICS[name](img, img)


def test_metrics_module_does_not_import_pillow():
    code = "import sys, isophote.metrics; print('PIL' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
