"""Luma-preserving gamut mapping (colour.fit_gamut) and its kernel twin in the fused colour
step: known answers on colours just outside every face of the RGB cube."""

import numpy as np
import pytest

from isophote.colour import RGB_TO_YUV, fit_gamut
from isophote.render._kernels.colour import _fit

LUMA = RGB_TO_YUV[0]


def faces():
    """(rgb just outside one face, the channel, the face's value) for the six faces."""
    base = np.array([90.0, 140.0, 200.0])
    out = []
    for c in range(3):
        for face, step in ((0.0, -3.0), (255.0, 3.0)):
            rgb = base.copy()
            rgb[c] = face + step
            out.append((rgb, c, face))
    return out


@pytest.mark.parametrize("rgb, c, face", faces())
def test_a_colour_just_outside_a_face_lands_on_it_with_its_luma(rgb, c, face):
    y = float(rgb @ LUMA)
    got = fit_gamut(rgb, np.float64(y))
    assert got[c] == pytest.approx(face, abs=1e-9)  # the face it crossed is the one it meets
    assert float(got @ LUMA) == pytest.approx(y, abs=1e-9)  # same luma
    assert np.all(got >= 0.0) and np.all(got <= 255.0)
    # on the straight line to the grey of that luma: got - y = t (rgb - y), 0 < t < 1
    t = (got - y) / (rgb - y)
    assert np.allclose(t, t[0], atol=1e-12) and 0.9 < t[0] < 1.0
    # per-channel clipping would have changed the luma by the excess times the channel's weight
    assert abs(float(np.clip(rgb, 0, 255) @ LUMA) - y) == pytest.approx(3.0 * LUMA[c], abs=1e-9)


def test_known_answer_red_above_the_top():
    # (257, 100, 100): y = 146.943, chroma offset (110.057, -46.943, -46.943), t = 108.057 / 110.057
    y = 0.299 * 257 + 0.587 * 100 + 0.114 * 100
    got = fit_gamut(np.array([257.0, 100.0, 100.0]), np.float64(y))
    t = (255 - y) / (257 - y)
    np.testing.assert_allclose(got, [255.0, y + t * (100 - y), y + t * (100 - y)], atol=1e-12)
    np.testing.assert_allclose(got[1], 100.8530, atol=1e-4)


def test_inside_the_cube_nothing_changes_and_luma_outside_its_range_gives_black_or_white():
    rgb = np.array([[0.0, 255.0, 12.5], [255.0, 255.0, 255.0], [3.0, 4.0, 5.0]])
    np.testing.assert_array_equal(fit_gamut(rgb, rgb @ LUMA), rgb)
    np.testing.assert_array_equal(fit_gamut(np.array([262.0, 258.0, 270.0]), np.float64(261.0)), [255.0] * 3)
    np.testing.assert_array_equal(fit_gamut(np.array([-5.0, -1.0, 2.0]), np.float64(-2.0)), [0.0] * 3)


def test_a_colour_outside_two_faces_meets_the_nearer_and_stays_inside_the_other():
    rgb = np.array([300.0, 100.0, -60.0])  # above R's face and below B's
    y = float(rgb @ LUMA)
    got = fit_gamut(rgb, np.float64(y))
    assert float(got @ LUMA) == pytest.approx(y, abs=1e-9)
    assert min(got[0], 255.0 - got[0]) < 1e-9 or got[2] < 1e-9  # on one of the two faces
    assert np.all(got >= -1e-12) and np.all(got <= 255.0 + 1e-12)


def test_the_kernel_twin_agrees_with_the_numpy_mapping():
    rng = np.random.default_rng(5)
    rgb = rng.uniform(-80, 335, (2000, 3))
    y = rng.uniform(-20, 275, 2000)
    want = fit_gamut(rgb, y)
    for k in range(len(y)):
        if np.all((rgb[k] >= 0) & (rgb[k] <= 255)):
            continue
        got = np.clip(np.array(_fit(*rgb[k], y[k])), 0, 255)
        np.testing.assert_allclose(got, want[k], atol=1e-9)


def _saturated(w=64, h=48):
    """Saturated blue, red and green ramps: equalisation lifts the dark blues' luma out of
    the cube and sinks the bright greens' under it."""
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    img = np.zeros((h, w, 3))
    img[: h // 3, :, 2] = 120 + 135 * xx[: h // 3] / w
    img[h // 3: 2 * h // 3, :, 0] = 100 + 155 * xx[h // 3: 2 * h // 3] / w
    img[2 * h // 3:, :, 1] = 160 + 95 * xx[2 * h // 3:] / w
    return np.clip(img, 0, 255).astype(np.uint8)


def test_equalised_render_keeps_the_luma_of_its_y_channel(monkeypatch):
    import isophote
    import isophote.render as R
    from isophote.apply.equalise import _render_channel

    eq = isophote.equalise(isophote.encode(_saturated()))
    y = _render_channel(eq.channel("Y"), eq.width, eq.height)  # the equalised Y, tone applied
    luma = eq.render().astype(np.float64) @ LUMA
    assert np.abs(luma - y).max() <= 0.5 + 1e-6  # only the rounding of R, G and B
    monkeypatch.setattr(R, "_fits", lambda vi: False)  # what per-channel clipping gave
    clipped = eq.render().astype(np.float64) @ LUMA
    assert np.abs(clipped - y).max() > 5.0


def test_plain_renders_still_clip_each_channel(monkeypatch):
    import isophote
    import isophote.render as R

    vi = isophote.encode(_saturated())
    plain = vi.render()
    monkeypatch.setattr(R, "_fits", lambda vi: False)
    assert np.array_equal(vi.render(), plain)  # no tone curve: per-channel clipping, as before
    monkeypatch.setattr(R, "_fits", lambda vi: True)
    assert not np.array_equal(vi.render(), plain)  # the render does leave the cube somewhere
