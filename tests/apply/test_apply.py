"""Applications of §5-6: exact areas, equalisation, warps (exactness, tolerance, clipping,
orientation, caps, background), colour depth, and their command-line doors. Small synthetic
images with known answers; the corpus numbers live in benchmarks/apply.py."""

from dataclasses import replace

import numpy as np
import pytest

import isophote
from isophote import cli
from isophote.apply import equalise as E
from isophote.errors import OptionError
from isophote.geometry import chain_segments, evaluate
from isophote.apply import warp as W
from isophote.imageio import write_image
from isophote.model import CAP_RAMP, DOME, Channel

H, WD = 40, 56  # not square, so that transposition bugs show


def _scene():
    """A tilted ramp with a bright disc and a dark blob: levels, peaks and pits."""
    y, x = np.mgrid[0:H, 0:WD] + 0.5
    img = 30 + 3.2 * x + 1.5 * y
    img += 90 * np.exp(-((x - 20) ** 2 + (y - 15) ** 2) / 40)
    img -= 60 * np.exp(-((x - 42) ** 2 + (y - 28) ** 2) / 30)
    rgb = np.stack([img, 0.8 * img + 20, 255 - img], axis=-1)
    return np.clip(rgb, 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def vi():
    return isophote.encode(_scene())


@pytest.fixture(scope="module")
def grey_vi():
    return isophote.encode(_scene()[..., 0])


def _psnr(a, b, mask=None):
    a, b = np.asarray(a, float), np.asarray(b, float)
    d = (a - b) ** 2 if mask is None else (a - b)[mask] ** 2
    return 10 * np.log10(255.0**2 / max(float(np.mean(d)), 1e-12))


# ------------------------------------------------------------------------ exact areas


def _polyline_area(chain, n=4000):
    """Brute force: shoelace area of the chain sampled densely (left side positive)."""
    pts = []
    for k in range(0, len(chain) - 1, 3):
        p0, p1, p2, p3 = chain[k : k + 4]
        t = np.linspace(0, 1, n, endpoint=False)[:, None]
        pts.append((1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * p1 + 3 * (1 - t) * t**2 * p2 + t**3 * p3)
    p = np.vstack(pts)
    x, y = p[:, 0], p[:, 1]
    # y down: the area on the left of travel is -1/2 sum(x dy - y dx)
    return -0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def test_bezier_areas_are_exact_against_dense_polylines():
    rng = np.random.default_rng(7)
    for _ in range(20):
        n = int(rng.integers(1, 6))
        chain = rng.uniform(0, 50, (1 + 3 * n, 2))
        chain[-1] = chain[0]
        ch = Channel.empty("Y", [100.0])
        ch = Channel(name="Y", levels=np.array([100.0]), contour_level=np.zeros(1, np.int32),
                     offsets=np.array([0, len(chain)]), points=chain, border=np.zeros(n, bool),
                     parent=np.full(1, -1, np.int32), cap_band=ch.cap_band, cap_contour=ch.cap_contour,
                     cap_xy=ch.cap_xy, cap_value=ch.cap_value)
        assert E.contour_areas(ch)[0] == pytest.approx(_polyline_area(chain), rel=1e-4, abs=1e-3)


def test_level_areas_match_the_rendered_level_sets(grey_vi):
    y = grey_vi.channel("Y")
    areas = E.level_areas(y, grey_vi.width, grey_vi.height) / (grey_vi.width * grey_vi.height)
    r = E._render_channel(y, grey_vi.width, grey_vi.height)
    for k, level in enumerate(y.levels):
        assert areas[k] == pytest.approx((r >= level).mean(), abs=0.02), (k, level)
    assert np.all(np.diff(areas) <= 1e-9)  # nested level sets


# ------------------------------------------------------------------------ equalisation


def test_histogram_stats_of_a_rectangular_histogram():
    s = E.histogram_stats(np.arange(256).repeat(3))
    assert s == {"empty": 0, "ks": pytest.approx(0.0, abs=1e-12), "entropy": pytest.approx(8.0)}
    s = E.histogram_stats(np.full(100, 7))
    assert s["empty"] == 255 and s["entropy"] == 0.0


def test_pixel_equalisation_matches_opencv():
    cv2 = pytest.importorskip("cv2")
    rng = np.random.default_rng(3)
    y = np.clip(rng.normal(90, 25, (40, 50)), 0, 255).astype(np.uint8)
    assert np.array_equal(E.equalise_pixels(y), cv2.equalizeHist(y))


def _band_bounds(ch):
    """(K,) lower and upper bound of each cap's band: its two levels, or the scale's ends."""
    ext = np.concatenate([[0.0], ch.levels, [255.0]])
    b = ch.cap_band.astype(np.int64)
    return ext[b], ext[b + 1]


def test_equalise_moves_levels_not_contours(vi):
    info = {}
    eq = E.equalise(vi, info=info)
    y0, y1 = vi.channel("Y"), eq.channel("Y")
    assert np.array_equal(y0.points, y1.points) and np.array_equal(y0.contour_level, y1.contour_level)
    assert np.all(np.diff(y1.levels) > 0) and y1.levels[0] > 0 and y1.levels[-1] < 255
    assert eq.channel("U").equals(vi.channel("U")) and eq.channel("V").equals(vi.channel("V"))
    # caps stay inside their bands (on the file format's 1/64 grid)
    lo0, hi0 = _band_bounds(y0)
    inside = (y0.cap_value >= lo0) & (y0.cap_value <= hi0)
    lo, hi = _band_bounds(y1)
    q = 1 / 64
    assert np.all(y1.cap_value[inside] >= lo[inside] - q) and np.all(y1.cap_value[inside] <= hi[inside] + q)
    assert set(info) >= {"area_above", "old_levels", "new_levels", "tone_knots", "measured"}
    assert info["tone_knots"] == y1.tone.shape[0] and eq.meta["equalised"] == "levels+tone"
    fast = E.equalise(vi, refine_render=False)
    assert fast.channel("Y").tone is None and np.array_equal(fast.channel("Y").levels, y1.levels)


def test_tone_curve_is_monotone_and_equalising_twice_changes_nothing(vi):
    y = E.equalise(vi).channel("Y")
    t = y.tone
    assert t.ndim == 2 and t.shape[1] == 2 and t.shape[0] >= 2
    assert np.all(np.diff(t[:, 0]) > 0) and np.all(np.diff(t[:, 1]) >= 0)
    assert t.min() >= 0 and t.max() <= 255 and t[0, 0] == 0 and t[-1, 0] == 255
    assert y.cap_ramp == DOME and vi.channel("Y").cap_ramp == CAP_RAMP  # domes (model.py, Caps)
    assert E.equalise(vi, refine_render=False).channel("Y").cap_ramp == CAP_RAMP
    # equalising again gives the same levels and the same curve (the old curve is dropped)
    again = E.equalise(E.equalise(vi)).channel("Y")
    assert np.array_equal(again.levels, y.levels) and np.array_equal(again.tone, t)


def test_domes_let_the_curve_spread_a_plateau():
    """A flat disc holds 20 % of the image at one value: as a plateau no monotone curve can
    spread it (KS >= 0.1); as a dome the equalised histogram is flat."""
    h = w = 128
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    img = 20 + 0.8 * xx + 0.45 * yy
    disc = np.hypot(xx - 60.4, yy - 67.4) < 32.4  # ~20 % of the image
    img[disc] = 230.0
    vi = isophote.encode(np.clip(img, 0, 255))
    plain = replace(E.equalise(vi), channels=(replace(E.equalise(vi).channel("Y"), cap_ramp=CAP_RAMP),))
    flat = E.histogram_stats(E._render_channel(E.with_tone(plain.channel("Y"), w, h), w, h))
    assert flat["ks"] > 0.08
    info = {}
    E.equalise(vi, info=info)
    assert info["measured"]["empty"] == 0 and info["measured"]["ks"] < 0.01 and info["measured"]["entropy"] > 7.95


def test_equaliser_measures_one_window_fields_where_renders_would_block(monkeypatch):
    """The curve is learnt from renders of the equalised channel (domes, whose fill blocks
    approximate): with every level cut into small blocks, as a big master's are, the
    measured values are still the one-window render's (render/blocks.one_window), and
    blocks would have changed them."""
    from isophote.render import blocks

    h = w = 128
    yy, xx = np.mgrid[0:h, 0:w] + 0.5
    img = 20 + 0.8 * xx + 0.45 * yy
    img[np.hypot(xx - 60.4, yy - 67.4) < 32.4] = 230.0  # a dome over several 32-node blocks
    vi = isophote.encode(np.clip(img, 0, 255))
    eq = E.equalise(vi, refine_render=False).channel("Y")
    whole = E.measure_values(eq, w, h)
    monkeypatch.setattr(blocks, "SINGLE_NODES", 0)
    monkeypatch.setattr(blocks, "BLOCK", 32)
    monkeypatch.setattr(blocks, "MARGIN", 8)
    assert np.array_equal(E.measure_values(eq, w, h), whole)
    monkeypatch.setattr(E, "MEASURE_WINDOW_NODES", 0)  # as before: the blocked renders
    assert not np.array_equal(E.measure_values(eq, w, h), whole)


def test_warp_keeps_the_tone_curve(vi):
    """An equalised image warped: the contours move, the tone curve travels with them, so the
    identity warp renders exactly as before."""
    eq = E.equalise(vi)
    same = W.warp(eq, W.Affine([[1, 0, 0], [0, 1, 0]]))
    assert np.array_equal(same.channel("Y").tone, eq.channel("Y").tone)
    assert np.array_equal(same.render(), eq.render())
    turned = W.warp(eq, W.rotation(10, (eq.width / 2, eq.height / 2)))
    assert np.array_equal(turned.channel("Y").tone, eq.channel("Y").tone)


def test_tone_curve_of_known_distributions():
    rng = np.random.default_rng(5)
    levels = np.array([60.0, 180.0])
    # band 1 ([60, 180)) holds values crowded towards its lower level: u**3
    u = rng.uniform(0, 1, 200_000)
    values = np.concatenate([rng.uniform(0, 60, 100_000), 60 + 120 * u**3, rng.uniform(180, 255, 100_000)])
    t = E.tone_curve(values, levels)
    assert np.array_equal(np.interp(levels, t[:, 0], t[:, 1]), levels)
    out = np.interp(values[100_000:300_000], t[:, 0], t[:, 1])
    # inside the band the curve is the band's cumulative distribution: uniform on [60, 180]
    cdf = np.searchsorted(np.sort(out), np.linspace(60, 180, 241)) / out.size
    assert np.abs(cdf - np.linspace(0, 1, 241)).max() < 0.003
    # the band below the first level spreads onto [-0.5, 60], clipped at 0
    low = np.interp(values[:100_000], t[:, 0], t[:, 1])
    assert low.min() == 0.0 and abs(np.median(low) - 29.75) < 0.5
    for bad in ([180.0, 60.0], [0.0, 60.0], [60.0, 255.0]):
        with pytest.raises(OptionError):
            E.tone_curve(values, np.array(bad))


def test_atoms_sit_at_their_mid_rank_and_leave_no_empty_bins():
    rng = np.random.default_rng(6)
    n = 400_000
    # a uniform image with an atom of 4 % at 200 and one of 3 % at the very bottom; the
    # level 127.5 has (nearly) its share below it, as after reassignment
    values = np.concatenate([rng.uniform(0, 255, int(n * 0.93)), np.full(int(n * 0.04), 200.0),
                             np.zeros(int(n * 0.03))])
    t = E.tone_curve(values, np.array([127.5]))
    out = np.interp(values, t[:, 0], t[:, 1])
    s = E.histogram_stats(out)
    assert s["empty"] == 0
    assert s["ks"] < 0.03 + 0.002  # the bottom atom (3 %) cannot leave 0; the other costs 2 %
    assert np.interp(0.0, t[:, 0], t[:, 1]) == 0.0
    # the inner atom sits in the middle of its share of its band ([127.5, 255.5] on output)
    band = values[values >= 127.5]
    mid = ((band < 200).mean() + 0.5 * (band == 200).mean())
    assert abs(np.interp(200.0, t[:, 0], t[:, 1]) - (127.5 + 128 * mid)) < 0.5


def _smooth_scene(h=96, w=128):
    """A ramp, a bright blob, a dark blob and a ripple: no plateau anywhere."""
    y, x = np.mgrid[0:h, 0:w] + 0.5
    img = (40 + 0.9 * x + 0.5 * y + 60 * np.exp(-((x - 0.3 * w) ** 2 + (y - 0.4 * h) ** 2) / (0.04 * w * w))
           - 30 * np.exp(-((x - 0.7 * w) ** 2 + (y - 0.6 * h) ** 2) / (0.02 * w * w))
           + 8 * np.sin(x / 5) * np.cos(y / 7))
    return np.clip(img, 0, 255)


def test_equalised_render_is_rectangular():
    vi = isophote.encode(_smooth_scene())
    w, h = vi.width, vi.height
    before = E.histogram_stats(E._render_channel(vi.channel("Y"), w, h))
    assert before["empty"] > 50 and before["ks"] > 0.1
    info = {}
    y = E.equalise(vi, info=info).channel("Y")
    for scale in (1, 2, 3):
        s = E.histogram_stats(E._render_channel(y, w, h, scale))
        assert s["empty"] == 0 and s["ks"] <= 0.005 and s["entropy"] >= 7.97, (scale, s)
    assert info["measured"] == E.histogram_stats(E._render_channel(y, w, h))
    # the exact areas alone get part of the way; the tone curve does the rest
    fast = E.histogram_stats(E._render_channel(E.equalise(vi, refine_render=False).channel("Y"), w, h))
    assert fast["ks"] > 2 * info["measured"]["ks"]


def test_equalised_histogram_is_flatter_than_the_pixel_way(grey_vi):
    w, h = grey_vi.width, grey_vi.height
    before = E.histogram_stats(E._render_channel(grey_vi.channel("Y"), w, h))
    fast = E.equalise(grey_vi, refine_render=False)
    s_fast = E.histogram_stats(E._render_channel(fast.channel("Y"), w, h))
    info = {}
    full = E.equalise(grey_vi, info=info)
    s_full = E.histogram_stats(E._render_channel(full.channel("Y"), w, h))
    assert s_full == pytest.approx(info["measured"])
    pixel = E.histogram_stats(E.equalise_pixels(_scene()[..., 0]))
    assert s_fast["ks"] < before["ks"] and s_full["ks"] <= s_fast["ks"] + 1e-9
    assert s_full["empty"] < pixel["empty"] and s_full["entropy"] > pixel["entropy"]


def test_equalised_file_round_trips(vi, tmp_path):
    for eq in (E.equalise(vi, refine_render=False), E.equalise(vi)):
        eq.save(tmp_path / "eq.isoph")
        back = isophote.load(tmp_path / "eq.isoph")
        assert back.equals(eq) and back.channel("Y").cap_ramp == eq.channel("Y").cap_ramp
        assert np.array_equal(back.render(), eq.render())


# ------------------------------------------------------------------------ warps: maps


def test_rotation_direction_and_perspective_corners():
    r = W.rotation(90, (0, 0))
    assert np.allclose(r(np.array([[1.0, 0.0]])), [[0.0, -1.0]])  # right of the centre goes up
    src = [(0, 0), (10, 0), (10, 8), (0, 8)]
    dst = [(1, 2), (9, 0), (11, 9), (-1, 7)]
    p = W.perspective_from_points(src, dst)
    assert np.allclose(p(np.asarray(src, float)), dst)
    assert np.allclose(p.inverse()(p(np.array([[3.0, 4.0]]))), [[3.0, 4.0]])


def test_swirl_inverse_and_jacobian():
    s = W.Swirl((20, 15), 2.5, 30)
    p = np.random.default_rng(1).uniform(0, 40, (50, 2))
    assert np.allclose(s(s.inverse_map(p)), p, atol=1e-9)
    num = W.Transform.jacobian(s, p)
    eps = 1e-5
    col0 = (s(p + [eps, 0]) - s(p - [eps, 0])) / (2 * eps)
    assert np.allclose(num[:, :, 0], col0, atol=1e-5)


# ------------------------------------------------------------------------ warps: contours


def _on_curve(ch):
    offs = ch.offsets
    idx = np.concatenate([np.arange(offs[k], offs[k + 1], 3) for k in range(ch.n_contours)]) if ch.n_contours else []
    return ch.points[idx]


def test_identity_warp_changes_nothing(vi):
    out = W.warp(vi, W.Affine([[1, 0, 0], [0, 1, 0]]))
    for a, b in zip(vi.channels, out.channels):
        assert np.array_equal(a.points, b.points) and a.base_band == b.base_band
    assert np.array_equal(vi.render(), out.render())


def test_affine_maps_move_control_points_exactly(vi):
    out = W.warp(vi, W.Affine([[2, 0, 0], [0, 2, 0]]), canvas=(2 * WD, 2 * H))
    for a, b in zip(vi.channels, out.channels):
        assert np.array_equal(b.points, 2 * a.points) and np.array_equal(b.cap_xy, 2 * a.cap_xy)
        assert np.array_equal(b.levels, a.levels) and b.base_band == a.base_band
    # shifted onto a larger canvas: the same contours first, then the frame of the background
    out = W.warp(vi, W.Affine([[2, 0, 3], [0, 2, 5]]), canvas=(2 * WD + 3, 2 * H + 5))
    for a, b in zip(vi.channels, out.channels):
        assert np.array_equal(b.points[: len(a.points)], 2 * a.points + [3, 5])
        assert np.array_equal(b.cap_xy[: len(a.cap_xy)], 2 * a.cap_xy + [3, 5])
        assert b.n_contours > a.n_contours and b.levels.shape[0] == a.levels.shape[0] + 1


def test_reflection_keeps_the_orientation_rule(grey_vi):
    out = W.warp(grey_vi, W.Affine([[-1, 0, WD], [0, 1, 0]]))
    a0 = E.level_areas(grey_vi.channel("Y"), WD, H)
    a1 = E.level_areas(out.channel("Y"), WD, H)
    assert np.allclose(a0, a1, atol=1e-6)
    assert _psnr(grey_vi.render()[:, ::-1], out.render()) > 40


def test_quarter_turn_matches_rotated_pixels(grey_vi):
    out = W.warp(grey_vi, W.rotation(90, (WD / 2, H / 2)), canvas="fit")
    assert (out.width, out.height) == (H, WD)
    assert _psnr(np.rot90(grey_vi.render()), out.render()) > 40


def test_rotation_preserves_level_areas_and_fills_the_background(grey_vi):
    out = W.warp(grey_vi, W.rotation(30, (WD / 2, H / 2)), canvas="fit", background=(200, 200, 200))
    y0, y1 = grey_vi.channel("Y"), out.channel("Y")
    added = len(y1.levels) - len(y0.levels)
    assert added == 1
    below = y1.levels[0] < y0.levels[0]  # the background level is below every level (or above)
    a0 = E.level_areas(y0, WD, H)
    a1 = E.level_areas(y1, out.width, out.height)
    if below:  # the background lies under every old level: the level sets are the old ones
        a1 = a1[1:]
    else:  # it lies above them all: every level set also holds the uncovered area
        a1 = a1[:-1] - (out.width * out.height - WD * H)
    assert np.allclose(a0, a1, rtol=1e-3, atol=0.05)
    r = out.render()
    assert abs(int(r[0, 0]) - 200) <= 1 and abs(int(r[-1, -1]) - 200) <= 1


def test_clipped_contours_stay_on_the_canvas_and_closed(vi):
    out = W.warp(vi, W.rotation(25, (WD / 2, H / 2)))  # same canvas: corners leave it
    for ch in out.channels:
        p = _on_curve(ch)
        assert np.all((p >= 0) & (p <= [WD, H]))
        for k in range(ch.n_contours):
            c = ch.chain(k)
            assert np.array_equal(c[0], c[-1]) and (len(c) - 1) % 3 == 0
        # every segment lying on the canvas border is flagged as border
        segs, brd = chain_segments(ch.points, ch.offsets)
        on_edge = np.all((np.isclose(segs[:, :, 0], 0) | np.isclose(segs[:, :, 0], WD)), axis=1) | np.all(
            (np.isclose(segs[:, :, 1], 0) | np.isclose(segs[:, :, 1], H)), axis=1)
        assert np.all(ch.border[on_edge])


def test_warped_files_round_trip(vi, tmp_path):
    out = W.warp(vi, W.Swirl((WD / 2, H / 2), 2.0, 25.0))
    out.save(tmp_path / "w.isoph")
    assert isophote.load(tmp_path / "w.isoph").equals(out)


def test_warp_matches_a_raster_rotation_of_the_render(vi):
    from skimage.transform import warp as sk_warp

    t = W.rotation(20, (WD / 2, H / 2))
    big = vi.render(scale=4).astype(float)
    s4 = W.Affine([[4, 0, 0], [0, 4, 0]])
    inv4 = s4.inverse().then(t).then(s4).inverse()
    ref = sk_warp(big, lambda q: inv4(q + 0.5) - 0.5, order=3, preserve_range=True)
    ref = ref.reshape(H, 4, WD, 4, 3).mean(axis=(1, 3))
    got = W.warp(vi, t).render().astype(float)
    inside = np.zeros((H, WD), bool)
    inside[10:-10, 10:-10] = True
    assert _psnr(ref, got, inside) > 35


def test_nonlinear_warp_stays_within_tolerance():
    rng = np.random.default_rng(5)
    segs = rng.uniform(5, 35, (30, 4, 2))
    border = np.zeros(30, bool)
    border[::5] = True
    segs[border, 1] = segs[border, 0] + (segs[border, 3] - segs[border, 0]) / 3
    segs[border, 2] = segs[border, 0] + 2 * (segs[border, 3] - segs[border, 0]) / 3
    sw = W.Swirl((20, 20), 3.0, 25.0)
    tol = 0.02
    new, nb, src = W.move_segments(segs, border, sw, tol)
    t = np.linspace(0, 1, 200)
    for s in range(len(segs)):
        exact = sw(evaluate(np.repeat(segs[s][None], len(t), 0), t))
        pieces = new[src == s]
        assert np.all(nb[src == s] == border[s])
        # pieces are in order and joined
        assert np.allclose(pieces[1:, 0], pieces[:-1, 3])
        m = 1000  # samples per piece: their spacing adds < tol / 4 to the measured distance
        if border[s]:  # drawn as chords
            dense = np.concatenate([np.linspace(p[0], p[3], m) for p in pieces])
        else:
            dense = np.concatenate([evaluate(np.repeat(p[None], m, 0), np.linspace(0, 1, m)) for p in pieces])
        step = np.hypot(*np.diff(dense, axis=0).T).max()
        d = np.sqrt(((exact[:, None, :] - dense[None, :, :]) ** 2).sum(-1)).min(axis=1)
        assert d.max() <= tol + step / 2 + 1e-9, (s, d.max(), step)


def test_caps_move_with_the_map(grey_vi):
    out = W.warp(grey_vi, W.Affine([[1, 0, 4], [0, 1, 3]]), canvas=(WD + 4, H + 3))
    a, b = grey_vi.channel("Y"), out.channel("Y")
    assert np.array_equal(b.cap_xy[: len(a.cap_xy)], a.cap_xy + [4, 3])
    assert np.array_equal(b.cap_value[: len(a.cap_value)], a.cap_value)


def test_perspective_and_swirl_render_sensibly(vi):
    per = W.perspective_from_points([(0, 0), (WD, 0), (WD, H), (0, H)],
                                    [(4, 3), (WD - 2, 0), (WD, H), (0, H - 4)])
    for t in (per, W.Swirl((WD / 2, H / 2), 1.5, 20.0)):
        out = W.warp(vi, t)
        r = out.render()
        assert r.shape == (H, WD, 3)
        assert _psnr(vi.render()[15:25, 20:36], r[15:25, 20:36]) > 12  # the middle is still there


def test_bad_transforms_are_refused(vi):
    with pytest.raises(isophote.OptionError):
        W.warp(vi, W.Affine([[1, 2, 0], [2, 4, 0]]))
    with pytest.raises(isophote.OptionError):
        W.warp(vi, W.Perspective([[1, 0, 0], [0, 1, 0], [-0.05, 0, 1]]))  # horizon crosses the image
    with pytest.raises(isophote.OptionError):
        W.warp(vi, W.rotation(10, (0, 0)), canvas=(0, 5))


# ------------------------------------------------------------------------ colour depth


def test_sixteen_bit_renders_have_intermediate_values(grey_vi):
    crop = (8, 24, 16, 12)  # the smooth lower-left part of the ramp
    r8 = grey_vi.render(scale=2, crop=crop, depth=8)
    r16 = grey_vi.render(scale=2, crop=crop, depth=16)
    assert r16.dtype == np.uint16
    assert len(np.unique(r16)) >= 10 * len(np.unique(r8))
    assert np.abs(r16 / 257.0 - r8).max() <= 0.5 + 1e-9


def test_depth_is_independent_of_the_source_depth():
    y, x = np.mgrid[0:24, 0:32]
    img16 = (x * 2000 + y * 50).astype(np.uint16)
    vi16 = isophote.encode(img16)
    assert vi16.source_depth == 16
    assert vi16.render(depth=8).dtype == np.uint8
    vi8 = isophote.encode((img16 // 257).astype(np.uint8))
    assert len(np.unique(vi8.render(depth=16))) > 4 * len(np.unique(vi8.render(depth=8)))


# ------------------------------------------------------------------------ command line


@pytest.fixture(scope="module")
def isoph(tmp_path_factory, vi):
    path = tmp_path_factory.mktemp("apply") / "scene.isoph"
    vi.save(path)
    return path


@pytest.mark.parametrize("flags", [
    ["--rotate", "15"],
    ["--rotate", "-40", "--canvas", "fit", "--background", "255,0,0"],
    ["--affine=-1,0,56,0,1,0"],
    ["--perspective", "4,3 54,0 56,40 0,36"],
    ["--perspective", "1,0.1,0,0,1,0,0.001,0,"],
    ["--swirl", "2,20", "--canvas", "60x44"],
])
def test_cli_warp(isoph, tmp_path, capsys, flags):
    out = tmp_path / "w.isoph"
    assert cli.main(["warp", str(isoph), "-o", str(out), *flags]) == 0
    vi = isophote.load(out)
    assert vi.render().ndim == 3


@pytest.mark.parametrize("flags", [
    ["--rotate", "15", "--affine", "1,0,0,0,1,0"],
    ["--perspective", "1,2,3"],
    ["--swirl", "2,-1"],
    ["--rotate", "5", "--canvas", "0x5"],
    ["--affine", "1,0,0,0,0,0"],
])
def test_cli_warp_refuses_bad_options(isoph, tmp_path, capsys, flags):
    out = tmp_path / "w.isoph"
    assert cli.main(["warp", str(isoph), "-o", str(out), *flags]) == 2
    assert not out.exists()
    err = capsys.readouterr().err
    assert err.startswith("isophote") and "Traceback" not in err


def test_cli_equalize(isoph, tmp_path, capsys):
    out = tmp_path / "eq.isoph"
    assert cli.main(["equalize", str(isoph), "-o", str(out)]) == 0
    assert "empty bins" in capsys.readouterr().out
    assert isophote.load(out).channel("Y").cap_ramp == DOME  # the domes reach the file
    assert cli.main(["info", str(out)]) == 0
    assert "tone curve of" in (text := capsys.readouterr().out) and "dome caps" in text
    assert cli.main(["equalise", str(isoph), "-o", str(out), "--fast", "--quiet"]) == 0
    assert np.all(np.diff(isophote.load(out).channel("Y").levels) > 0)


def test_cli_figures_quick(tmp_path, capsys):
    png = tmp_path / "scene.png"
    write_image(png, _scene().astype(float))
    outdir = tmp_path / "figs"
    assert cli.main(["figures", str(outdir), "--image", str(png), "--quick", "--quiet"]) == 0
    names = {p.name for p in outdir.iterdir()}
    for n in ("fig1a_original.png", "fig1c_diffusion.png", "fig2_Y_plane.png", "fig9_x8_vector.png",
              "fig10b_by_levels_hist.png", "warp_rotate15_vector.png", "index.md"):
        assert n in names
