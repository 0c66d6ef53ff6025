"""Tests of the decoder (paper §4; src/isophote/render/).

Synthetic images with known answers are encoded and rendered back: ramps must come back
within a grey level, discs keep their radius and centre at every scale, caps peak at their
annotated value, crops are exact pieces of the full render, and diffusion has no steps
where flat fill has one per level.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import skimage.data

import isophote
from isophote import LimitError, OptionError
from isophote.model import Channel, VectorImage
from isophote.render import render, render_float

# ---------------------------------------------------------------------------------------
# images
# ---------------------------------------------------------------------------------------


def centres(h, w):
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    return yy + 0.5, xx + 0.5


def ramp_image(kind):
    yy, xx = centres(24, 40)
    # offsets chosen so that no sample lies exactly on a level (see the xfail below)
    if kind == "x":
        return 10.0 + 6.0 * xx
    if kind == "y":
        return 20.3 + 9.0 * yy
    return 10.3 + 3.0 * xx + 2.0 * yy


@pytest.fixture(scope="module")
def ramps():
    return {k: (ramp_image(k), isophote.encode(ramp_image(k), preset="paper")) for k in ("x", "y", "diagonal")}


@pytest.fixture(scope="module")
def radial():
    """A smooth radial gradient (slope 4 per pixel) and its encoding."""
    yy, xx = centres(32, 32)
    img = 40.0 + 4.0 * np.hypot(xx - 15.7, yy - 16.2)
    return img, isophote.encode(img, preset="paper")


# ---------------------------------------------------------------------------------------
# fidelity
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["x", "y", "diagonal"])
def test_ramp_renders_back(ramps, kind):
    img, vi = ramps[kind]
    out = render_float(vi)
    assert out.shape == img.shape + (1,)
    err = np.abs(out[..., 0] - img)
    assert err[2:-2, 2:-2].max() <= 1.0, err[2:-2, 2:-2].max()
    assert err[2:-2, 2:-2].mean() <= 0.25
    # the outermost pixels: the frame is no isoline, still close (handles on coarse grids,
    # encoder/fit.py, move a diagonal contour within its ribbon: 2.0009 at a corner)
    assert err.max() <= 2.1


def test_g1_fill_follows_a_curved_profile_better_than_straight_lines():
    """f(x) = 20 + 0.1 x^2: bands narrow to the right, so the straight-line blend has a kink
    at every isoline; the G1 profile (slopes blended across each isoline) is closer to f at
    4x and its slope changes less between neighbouring samples."""
    yy, xx = centres(12, 44)
    img = 20.3 + 0.1 * xx**2
    # Catmull-Rom midpoints are exact on a quadratic: the isolines sit where f crosses the
    # levels, so the two fills are compared on the same, exact contours
    vi = isophote.encode(img, preset="paper", carrato_cubic=1.0)
    x4 = (np.arange(44 * 4) + 0.5) / 4
    truth = 20.3 + 0.1 * x4**2
    errs, kinks = {}, {}
    for fill in ("diffusion", "linear"):
        row = render_float(vi, scale=4, fill=fill, sharpen=0.0)[24, :, 0]  # the fills alone
        inner = slice(64, -12)  # away from the frame and the widest bands on the left
        errs[fill] = np.abs(row - truth)[inner].mean()
        kinks[fill] = np.abs(np.diff(row, 2))[inner].max()
    assert errs["diffusion"] < 0.5 * errs["linear"], errs
    assert kinks["diffusion"] < 0.5 * kinks["linear"], kinks


def test_g1_slopes_agree_on_both_sides_and_keep_ramps_straight():
    from isophote.render._kernels.diffuse import _pchip_slope

    rng = np.random.default_rng(3)
    for _ in range(200):
        s1, s2 = rng.uniform(0.1, 20, 2)
        w1, w2 = rng.uniform(0.2, 30, 2)
        m = _pchip_slope(s1, w1, s2, w2)
        assert m == pytest.approx(_pchip_slope(s2, w2, s1, w1))  # one slope at the isoline
        assert min(s1, s2) <= m <= max(s1, s2) + 1e-12 and m <= 3 * min(s1, s2)  # monotone
        assert _pchip_slope(s1, w1, s1, w2) == pytest.approx(s1)  # a ramp stays a ramp
        assert _pchip_slope(s1, w1, 0.0, 0.0) == s1  # unknown neighbour: the band's own slope


def test_tone_curve_maps_rendered_values(ramps):
    """A channel's tone curve applies per sample: the x ramp (10 + 6x) through a curve that
    doubles slopes below 127.5 and clamps above comes back as that curve of the ramp."""
    img, vi = ramps["x"]
    tone = np.array([[0.0, 0.0], [127.5, 255.0], [255.0, 255.0]])
    toned = replace(vi, channels=(replace(vi.channels[0], tone=tone),))
    plain = render_float(vi)[..., 0]
    out = render_float(toned)[..., 0]
    np.testing.assert_allclose(out, np.clip(2.0 * plain, 0, 255), atol=1e-3)
    assert not toned.equals(vi) and toned.equals(replace(vi, channels=(replace(vi.channels[0], tone=tone.copy()),)))
    assert np.abs(out - np.clip(2.0 * img, 0, 255))[2:-2, 2:-2].max() <= 2.0


@pytest.mark.parametrize("distance", ["euclidean", "manhattan", "geodesic"])
def test_every_distance_mode_renders_the_ramp(ramps, distance):
    img, vi = ramps["x"]
    out = render_float(vi, distance=distance)[..., 0]
    assert np.abs(out - img)[2:-2, 2:-2].max() <= 1.0


def test_diffusion_has_no_steps_flat_fill_does(radial):
    img, vi = radial
    diff = render_float(vi, scale=4)[..., 0]
    flat = render_float(vi, scale=4, fill="flat")[..., 0]
    assert diff.shape == flat.shape == (128, 128)

    def largest_jump(a):
        return max(np.abs(np.diff(a, axis=0)).max(), np.abs(np.diff(a, axis=1)).max())

    # the gradient itself moves 4 / 4 = 1 grey level per output pixel
    assert largest_jump(diff) <= 2.0, largest_jump(diff)
    assert largest_jump(flat) >= 8.0  # one level step (10) at every band boundary
    # flat fill takes only band middles; diffusion follows the cone
    assert len(np.unique(flat)) <= 25
    yy, xx = (np.mgrid[0:128, 0:128] + 0.5) / 4
    truth = 40.0 + 4.0 * np.hypot(xx - 15.7, yy - 16.2)
    inner = (slice(8, -8), slice(8, -8))
    assert np.abs(diff - truth)[inner].mean() < 1.0
    assert np.abs(diff - truth)[inner].mean() < 0.5 * np.abs(flat - truth)[inner].mean()


def disc_image(size=48, radius=10.0, cx=24.3, cy=23.6, ss=8):
    """An anti-aliased disc (coverage by ss x ss supersampling): 50 outside, 200 inside."""
    yy, xx = (np.mgrid[0 : size * ss, 0 : size * ss] + 0.5) / ss
    inside = (xx - cx) ** 2 + (yy - cy) ** 2 <= radius**2
    cov = inside.reshape(size, ss, size, ss).mean(axis=(1, 3))
    return 50.0 + 150.0 * cov


@pytest.mark.parametrize("scale", [1, 2, 4])
def test_disc_keeps_radius_and_centre(scale):
    radius, cx, cy = 10.0, 24.3, 23.6
    vi = isophote.encode(disc_image(radius=radius, cx=cx, cy=cy), preset="paper")
    out = render_float(vi, scale=scale)[..., 0]
    assert out.shape == (48 * scale, 48 * scale)
    inside = out >= 125.0
    yy, xx = (np.mgrid[0 : 48 * scale, 0 : 48 * scale] + 0.5) / scale
    area = inside.sum() / scale**2
    assert area == pytest.approx(np.pi * radius**2, rel=0.02)
    assert xx[inside].mean() == pytest.approx(cx, abs=0.15 / scale + 0.02)
    assert yy[inside].mean() == pytest.approx(cy, abs=0.15 / scale + 0.02)
    # the only disagreements with the analytic disc hug its circle
    r = np.hypot(xx - cx, yy - cy)
    wrong = inside != (r <= radius)
    assert np.all(np.abs(r[wrong] - radius) < 0.25)
    assert np.abs(out[r > radius + 3] - 50.0).max() <= 1.0  # the outer plateau comes back


@pytest.mark.parametrize("scale", [1, 2])
def test_disc_inner_plateau_comes_back(scale):
    vi = isophote.encode(disc_image(), preset="paper")
    out = render_float(vi, scale=scale)[..., 0]
    yy, xx = (np.mgrid[0 : 48 * scale, 0 : 48 * scale] + 0.5) / scale
    r = np.hypot(xx - 24.3, yy - 23.6)
    assert np.abs(out[r < 7.0] - 200.0).max() <= 1.0



@pytest.mark.parametrize("scale", [1, 2])
def test_dome_caps_rise_to_their_value_at_the_centre(scale):
    from isophote.model import DOME

    vi = isophote.encode(disc_image(), preset="paper")
    ch = vi.channels[0]
    top = int(np.argmax(ch.cap_value))
    dome = replace(vi, channels=(replace(ch, cap_ramp=DOME),))
    out = render_float(dome, scale=scale, sharpen=0.0)[..., 0]  # the fill alone
    yy, xx = (np.mgrid[0 : 48 * scale, 0 : 48 * scale] + 0.5) / scale
    r = np.hypot(xx - 24.3, yy - 23.6)
    # no plateau: the profile keeps rising towards the centre, where it reaches the cap value
    inner = out[r < 7.0]
    assert np.unique(np.round(inner, 2)).size > 20 * scale
    ring = [out[(r >= a) & (r < a + 1)].mean() for a in range(0, 9, 2)]
    assert all(a > b + 0.2 for a, b in zip(ring, ring[1:])), ring
    assert ring[0] - ring[-1] > 2.0
    assert abs(out[r < 1.0].mean() - ch.cap_value[top]) <= 3.0
    level = ch.levels[ch.cap_band[top] - 1]
    assert inner.min() >= level - 1.0 and inner.max() <= ch.cap_value[top] + 1.0
    # the contours stay where they were (the surround, a pit against the frame, is a dome too)
    base = render_float(vi, scale=scale, sharpen=0.0)[..., 0]
    assert np.array_equal(out >= 125.0, base >= 125.0)

# ---------------------------------------------------------------------------------------
# enlargement sharpening (render/sharpen.py)
# ---------------------------------------------------------------------------------------


def test_sharpened_enlargement_is_closer_to_the_sharp_disc():
    """The disc's pixels are area averages of a sharp disc; enlarged 4x, the sharpened render
    is closer to that disc's own 4x pixels than the plain one, and rings within its bound."""
    vi = isophote.encode(disc_image(), preset="paper")
    truth = disc_image(48 * 4, 40.0, 24.3 * 4, 23.6 * 4, ss=2)
    plain = render_float(vi, scale=4, sharpen=0.0)[..., 0]
    sharp = render_float(vi, scale=4, sharpen=0.125)[..., 0]
    e_plain, e_sharp = np.abs(plain - truth), np.abs(sharp - truth)
    assert e_sharp.mean() < 0.9 * e_plain.mean(), (e_sharp.mean(), e_plain.mean())
    assert np.sqrt((e_sharp**2).mean()) < 0.9 * np.sqrt((e_plain**2).mean())
    # overshoot at most the two axes' gains times the 150-level step
    bound = 2 * 0.125 * (1 - 1 / 16) * 150
    assert sharp.max() <= 200.25 + bound and sharp.min() >= 50.0 - bound
    assert sharp.max() > 205.0  # it does sharpen
    # flat parts stay as they were: the centre, the corners
    yy, xx = (np.mgrid[0:192, 0:192] + 0.5) / 4
    r = np.hypot(xx - 24.3, yy - 23.6)
    far = (r < 7.0) | (r > 13.5)
    assert np.abs(sharp - plain)[far].max() <= 0.25


def test_sharpening_keeps_ramps_and_leaves_1x_alone(ramps, wavy):
    for kind in ("x", "diagonal"):
        _, vi = ramps[kind]
        d = np.abs(render_float(vi, scale=4) - render_float(vi, scale=4, sharpen=0.0))[..., 0]
        assert d[8:-8, 8:-8].max() <= 0.5 and d.mean() <= 0.05, (d[8:-8, 8:-8].max(), d.mean())
    for options in (dict(), dict(scale=0.5), dict(width=30, height=20), dict(scale=3, fill="flat")):
        assert np.array_equal(render_float(wavy, **options), render_float(wavy, sharpen=0.0, **options))
    assert not np.array_equal(render_float(wavy, scale=2), render_float(wavy, scale=2, sharpen=0.0))


def test_sharpening_correction_known_answers():
    from isophote.render._kernels.sharpen import correction
    from isophote.render.sharpen import gains

    assert gains(0.125, 1.0, 0.5) == (0.0, 0.0)
    gx, gy = gains(0.125, 4.0, 2.0)
    assert gx == pytest.approx(0.125 * 15 / 16) and gy == pytest.approx(0.125 * 3 / 4)
    # f = x^2 + 3 y on the nodes: second differences r nodes apart are 2 r^2 in x, 0 in y
    r = 3
    yy, xx = np.mgrid[0:20, 0:25].astype(np.float64)
    nv = (xx**2 + 3 * yy).astype(np.float32)
    c, sharp = correction(nv, r, gx, gy)
    assert c.dtype == sharp.dtype == np.float32 and c.shape == (20, 25)
    assert np.allclose(sharp, nv + c)
    assert np.allclose(c[:, r:-r], -gx * 2 * r * r, atol=1e-4)
    assert np.all(c[:, :r] == 0) and np.all(c[:, -r:] == 0)  # the neighbour would be off the grid
    assert np.all(correction(np.ones((2, 2), np.float32), r, gx, gy)[0] == 0)


@pytest.mark.parametrize("scale", [1, 2, 4])
def test_cap_peaks_at_its_value(scale):
    yy, xx = centres(32, 32)
    img = 30.0 + 180.0 * np.exp(-((xx - 15.6) ** 2 + (yy - 16.3) ** 2) / (2 * 4.0**2))
    vi = isophote.encode(img, preset="paper")
    ch = vi.channels[0]
    top = int(np.argmax(ch.cap_band))
    assert ch.cap_band[top] == np.searchsorted(ch.levels, img.max(), side="right")
    assert abs(ch.cap_xy[top, 0] - 15.6) < 1 and abs(ch.cap_xy[top, 1] - 16.3) < 1
    out = render_float(vi, scale=scale, sharpen=0.0)[..., 0]  # the fill alone
    assert abs(out.max() - ch.cap_value[top]) <= 1.0, (out.max(), ch.cap_value[top])
    # the maximum is where the bump is
    i, j = np.unravel_index(np.argmax(out), out.shape)
    assert np.hypot((j + 0.5) / scale - 15.6, (i + 0.5) / scale - 16.3) < 2.5


# ---------------------------------------------------------------------------------------
# viewport: crops, sizes, supersampling, depth
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def wavy():
    """A 32 x 48 (H x W) smooth image with many contours."""
    yy, xx = centres(32, 48)
    img = 40.0 + 3.0 * np.hypot(xx - 20.7, yy - 16.2) + 12.0 * np.sin(xx / 3.0) * np.cos(yy / 4.0)
    return isophote.encode(np.clip(img, 0, 255), preset="paper")


@pytest.mark.parametrize("crop", [(5, 7, 10, 9), (0, 20, 12, 12), (36, 0, 12, 32)],
                         ids=["inside", "left-bottom-border", "right-column"])
def test_crop_is_exactly_a_piece_of_the_full_render(wavy, crop):
    full = render_float(wavy, scale=2)
    x, y, w, h = crop
    part = render_float(wavy, scale=2, crop=crop)
    assert part.shape == (2 * h, 2 * w, 1)
    assert np.array_equal(part, full[2 * y : 2 * (y + h), 2 * x : 2 * (x + w)])


def test_sixteen_bits_have_many_more_values(wavy):
    a8 = render(wavy, scale=4, depth=8)
    a16 = render(wavy, scale=4, depth=16)
    assert a8.dtype == np.uint8 and a16.dtype == np.uint16
    assert a8.shape == a16.shape == (128, 192)
    smooth = (slice(40, 88), slice(60, 132))
    assert len(np.unique(a16[smooth])) >= 10 * len(np.unique(a8[smooth]))
    # the same picture: 16-bit / 257 rounds to the 8-bit render
    assert np.abs(a16.astype(np.float64) / 257.0 - a8).max() <= 0.51


def test_sizes_and_supersampling(wavy):
    assert render(wavy).shape == (32, 48)
    assert render(wavy, supersample=2).shape == (32, 48)
    assert render(wavy, scale=2, supersample=2).shape == (64, 96)
    assert render(wavy, width=24).shape == (16, 24)  # width alone keeps the aspect ratio
    assert render(wavy, height=64).shape == (64, 96)  # height alone too
    assert render(wavy, width=10, height=40).shape == (40, 10)  # both stretch
    assert render(wavy, scale=0.5).shape == (16, 24)
    assert render(wavy, crop=(4, 4, 20, 10), scale=3).shape == (30, 60)
    # supersampling averages: close to the point-sampled render, within its range
    a = render_float(wavy, scale=2)[..., 0]
    b = render_float(wavy, scale=2, supersample=2)[..., 0]
    assert np.abs(a - b).mean() < 1.0
    assert a.min() - 1.0 <= b.min() and b.max() <= a.max() + 1.0


def test_rgb_render_shapes_and_colour():
    yy, xx = centres(16, 24)
    rgb = np.stack([40 + 8 * xx, 200 - 9 * yy, np.full_like(xx, 90.0)], axis=-1)
    vi = isophote.encode(np.clip(rgb, 0, 255), preset="paper")
    out = render_float(vi)
    assert out.shape == (16, 24, 3)
    assert np.abs(out - rgb)[2:-2, 2:-2].max() <= 3.0
    assert render(vi, scale=2).shape == (32, 48, 3)


@pytest.mark.parametrize("depth", [8, 16])
@pytest.mark.parametrize("alpha", [False, True])
@pytest.mark.parametrize("toned", [False, True])
def test_fused_colour_kernel_matches_the_numpy_path(depth, alpha, toned):
    from isophote.colour import YUV_TO_RGB
    from isophote.render import _colour, quantise
    from isophote.render._kernels.colour import yuv_quantise

    rng = np.random.default_rng(depth + alpha)
    # out of gamut and out of range on purpose: both clip, or with a tone curve on Y keep their luma
    planes = {k: rng.uniform(-40, 300, (37, 53)).astype(np.float32) for k in ("Y", "U", "V")}
    if alpha:
        planes["A"] = rng.uniform(-10, 270, (37, 53)).astype(np.float32)
    y = type("C", (), {"tone": np.array([[0.0, 0.0], [255.0, 255.0]]) if toned else None})()
    vi = type("V", (), {"colour": "yuv", "channel": lambda self, name: y})()
    want = quantise(_colour(vi, planes), depth)
    got = np.empty_like(want)
    yuv_quantise(planes["Y"], planes["U"], planes["V"], planes.get("A", np.empty((0, 0), np.float32)),
                 YUV_TO_RGB, 257.0 if depth == 16 else 1.0, toned, got)
    assert got.dtype == want.dtype and got.shape == (37, 53, 4 if alpha else 3)
    # the matrix product may round its last bit differently: a sample exactly half-way between
    # two codes may go either way, nothing more
    assert np.abs(got.astype(int) - want.astype(int)).max() <= 1
    assert np.mean(got != want) < 1e-3
    assert got.min() == 0 and got.max() == (65535 if depth == 16 else 255)


def test_strips_join_seamlessly(wavy, monkeypatch):
    import isophote.render as R

    whole = render_float(wavy, scale=3)
    monkeypatch.setattr(R, "STRIP_ROWS", 7)
    # 144 x 96 output: 13 strips of 7 rows and a last one of 5, each turned into colour by
    # whichever task fills its last channel
    assert np.array_equal(render_float(wavy, scale=3), whole)
    assert np.array_equal(render(wavy, scale=3), R.quantise(whole, 8)[..., 0])


def test_colour_strips_join_seamlessly(monkeypatch):
    """RGBA: four channels per strip, the colour made by the task that fills the last one;
    strips of 5 rows give the same bytes as one strip."""
    import isophote.render as R

    yy, xx = np.mgrid[0:24, 0:36].astype(float)
    rgba = np.stack([100 + 60 * np.sin(xx / 5.0), 120 + 50 * np.cos(yy / 4.0),
                     80 + 2 * xx + yy, 255 - 4 * yy], axis=2)
    vi = isophote.encode(np.clip(rgba, 0, 255).astype(np.uint8), preset="paper")
    monkeypatch.setattr(R, "STRIP_ROWS", 1000)
    whole = render(vi, scale=2.5, depth=16)
    assert whole.shape == (60, 90, 4)
    monkeypatch.setattr(R, "STRIP_ROWS", 5)
    assert np.array_equal(render(vi, scale=2.5, depth=16), whole)


@pytest.mark.parametrize(
    "options",
    [
        dict(crop=(-1, 0, 4, 4)),
        dict(crop=(0, -0.5, 4, 4)),
        dict(crop=(40, 0, 10, 4)),
        dict(crop=(0, 30, 4, 4)),
        dict(crop=(0, 0, 49, 4)),
        dict(crop=(0, 0, 0, 4)),
        dict(crop=(0, 0, 4)),
        dict(fill="smooth"),
        dict(distance="chebyshev"),
        dict(depth=12),
        dict(supersample=0),
        dict(supersample=17),
        dict(sharpen=-0.1),
        dict(sharpen=1.5),
        dict(sharpen=float("nan")),
        dict(scale=0),
        dict(scale=-2),
        dict(scale=2, width=10),
        dict(width=0),
        dict(height=-3),
    ],
)
def test_bad_render_options_raise_option_error(wavy, options):
    with pytest.raises(OptionError):
        render(wavy, **options)


def test_too_many_pixels_raise_limit_error(wavy):
    with pytest.raises(LimitError):
        render(wavy, max_pixels=1000)  # 48 x 32 = 1536
    with pytest.raises(LimitError):
        render(wavy, scale=100, max_pixels=10_000_000)  # 4800 x 3200
    assert render(wavy, max_pixels=1536).shape == (32, 48)  # the limit itself is allowed


# ---------------------------------------------------------------------------------------
# known bugs
# ---------------------------------------------------------------------------------------


def _diamond_pit(top_y):
    """One contour of level 100 (levels 50, 100, 150) around a pit: a quadrilateral with its
    top vertex at (8.3, top_y), edges in general position. Caps: 80 in the pit, 120 outside."""
    corners = np.array([(8.3, top_y), (12.8, 8.35), (8.35, 12.8), (4.2, 8.35)])
    pts = [corners[0]]
    for a, b in zip(corners, np.roll(corners, -1, axis=0)):
        pts += [a + (b - a) / 3, a + 2 * (b - a) / 3, b]
    chain = np.array(pts)
    ch = Channel(
        name="Y", levels=np.array([50.0, 100.0, 150.0]), contour_level=np.array([1], np.int32),
        offsets=np.array([0, len(chain)], np.int64), points=chain, border=np.zeros(4, bool),
        parent=np.array([-1], np.int32), cap_band=np.array([1, 2], np.int32),
        cap_contour=np.array([0, -1], np.int32), cap_xy=np.array([[8.5, 8.5], [0.5, 0.5]]),
        cap_value=np.array([80.0, 120.0]), base_band=2,
    )
    return VectorImage(width=17, height=17, colour="grey", channels=(ch,))


def _check_diamond(out, scale):
    yy, xx = (np.mgrid[0 : out.shape[0], 0 : out.shape[1]] + 0.5) / scale
    assert np.abs(out[yy < 2.0] - 120.0).max() <= 1e-3  # the outer plateau
    assert out[int(8.5 * scale), int(8.5 * scale)] == pytest.approx(80.0, abs=1e-3)  # the pit's cap
    assert out.max() <= 120.0 + 1e-3 and out.min() >= 80.0 - 1e-3  # nothing beyond the caps


@pytest.mark.parametrize("scale", [1, 2, 3])
def test_diamond_pit_renders_between_its_caps(scale):
    """The reference for the xfail below: the top vertex a tenth of a pixel lower."""
    out = render_float(_diamond_pit(4.6), scale=scale, sharpen=0.0)[..., 0]  # the fill alone
    _check_diamond(out, scale)


@pytest.mark.parametrize("scale", [1, 2, 3])
def test_vertex_touching_a_node_row_is_no_source(scale):
    out = render_float(_diamond_pit(4.5), scale=scale, sharpen=0.0)[..., 0]
    _check_diamond(out, scale)


def test_samples_exactly_on_a_level_render_at_the_level():
    yy, xx = centres(24, 40)
    img = 20.0 + 9.0 * yy  # rows 7 and 17 hold 87.5 and 177.5: levels of the paper preset
    out = render_float(isophote.encode(img, preset="paper"))[..., 0]
    assert np.abs(out - img)[2:-2, 2:-2].max() <= 1.0  # renders 92.5 and 182.5 there


@pytest.mark.xfail(strict=True, reason=(
    "known limitation: a 1e-6 px shift flips the band of the few nodes that sit exactly on an "
    "isoline (3 pixels here, a legitimate change), and the distance propagation through those "
    "nodes then changes whole neighbourhoods by up to ~3 levels (71 pixels > 0.5)"))
def test_render_is_stable_under_a_tiny_shift():
    img = skimage.data.camera()[100:164, 100:164]
    vi = isophote.encode(img, preset="paper")
    moved = replace(vi, channels=tuple(ch.with_points(ch.points + [0.0, 1e-6]) for ch in vi.channels))
    a = render_float(vi)
    b = render_float(moved)
    assert np.abs(a - b).max() <= 0.5


@pytest.mark.parametrize("scale", [1, 3])
def test_plateau_closed_against_the_frame_keeps_its_value(scale):
    """A dark plateau at 40 that one level (47.5) closes against the frame is a pit cap: the
    level below it (37.5) runs along the frame there only as border stretches, which are no
    isolines (the decoder takes no distance from them), so they do not make it a two-level
    band; it renders at 40, not at a capless band's default (45)."""
    yy, xx = centres(30, 40)
    # up from the plateau, then down to 10 at the right, so the 37.5 contour exists and closes
    # round the plateau along the frame
    img = np.clip(40.0 + 8.0 * np.clip(xx - 15.0, 0.0, 12.0) - 12.0 * np.maximum(0.0, xx - 28.0), 10.0, 235.0)
    vi = isophote.encode(img, preset="paper")
    ch = vi.channels[0]
    band_40 = int(np.searchsorted(ch.levels, 40.0, side="right"))
    assert np.any(ch.cap_band == band_40)
    out = render_float(vi, scale=scale)[..., 0]
    plateau = out[:, : 12 * scale]
    assert np.abs(plateau - 40.0).max() <= 1.0, np.abs(plateau - 40.0).max()


def test_node_resolution_by_scale_and_channel():
    """One node per pixel at or below 1x, two up to 2x, three above for luma and alpha, two
    for chroma (its fields cost less than half as much, for 0.006 dB at 4x), and fewer
    nodes when the budget runs out."""
    from isophote.render import NODE_BUDGET, node_resolution

    assert node_resolution(512, 512, 0.5) == node_resolution(512, 512, 1.0) == 1
    assert node_resolution(512, 512, 1.5) == node_resolution(512, 512, 2.0) == 2
    assert node_resolution(512, 512, 2.0, chroma=True) == 2
    assert node_resolution(512, 512, 4.0) == 3 and node_resolution(512, 512, 4.0, chroma=True) == 2
    side = int((NODE_BUDGET / 9) ** 0.5) + 1  # too big for 3 nodes per pixel, fine for 2
    assert node_resolution(side, side, 4.0) == 2
    assert node_resolution(4 * side, 4 * side, 4.0) == 1
