"""Tests of the encoder (paper §3; src/isophote/encoder/).

Every test encodes a synthetic image whose contours are known in closed form (cones,
ramps, saddles, nested rings, Gaussian bumps) and checks the isolines, the fitted chains and
the hierarchy against that answer. Crossings are found by brute force over segment pairs,
fitting errors with ``chain_distance`` (dense sampling of the curve), never with the
encoder's own estimates.

Coordinates (model.py): x right, y down, pixel (i, j) covers [j, j+1) x [i, i+1) and its
sample sits at (j + 0.5, i + 0.5).
"""

from __future__ import annotations

import numpy as np
import pytest
import skimage.data

import isophote
from isophote import InputError, OptionError
from isophote.colour import rgb_to_yuv
from isophote.encoder import QUANT
from isophote.encoder.fit import chain_distance
from isophote.encoder.hierarchy import build_hierarchy
from isophote.encoder.isolines import find_isolines, signed_area
from isophote.encoder.levels import channel_levels, preset_levels
from isophote.encoder.mapping import map_pixels
from isophote.format.isoph import dumps
from isophote.options import EncodeOptions
from isophote.render import render_float
from isophote.geometry import flatten, segments

# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------


def centres(h, w):
    """(y, x) of every pixel's sample: (i + 0.5, j + 0.5)."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    return yy + 0.5, xx + 0.5


def isolines_of(img, levels, eps=0.5):
    """The isolines of a float image, through the encoder's own mapping (default options)."""
    o = EncodeOptions(preset="paper").resolved()
    grid, grid_eps = map_pixels(np.asarray(img, np.float64), eps, o.carrato_p, o.carrato_scale,
                                  o.carrato_cubic)
    return find_isolines(grid, grid_eps, np.asarray(levels, np.float64), o.min_tolerance, o.max_tolerance)


def loop_border(iso, i):
    return iso.border[iso.offsets[i] : iso.offsets[i + 1]]


def chain_segments(chain):
    """(n, 4, 2) control points of each cubic of a chain."""
    n = (len(chain) - 1) // 3
    return np.stack([chain[3 * s : 3 * s + 4] for s in range(n)])


def polyline_pieces(iso):
    """Per loop: (starts, ends, is_isoline) of its segments, zero-length ones dropped."""
    out = []
    for i in range(iso.n_loops):
        p = iso.loop(i)
        q = np.roll(p, -1, axis=0)
        keep = np.any(p != q, axis=1)
        out.append((p[keep], q[keep], ~loop_border(iso, i)[keep]))
    return out


def chain_pieces(ch, tol=0.01):
    """Per contour: its flattened chain as (starts, ends, is_isoline), zero-length dropped."""
    segs, border = segments(ch)
    so = ch.segment_offsets()
    out = []
    for k in range(ch.n_contours):
        x0, y0, x1, y1, src = flatten(segs[so[k] : so[k + 1]], border[so[k] : so[k + 1]], tol)
        a, b = np.column_stack([x0, y0]), np.column_stack([x1, y1])
        keep = np.any(a != b, axis=1)
        out.append((a[keep], b[keep], src[keep]))
    return out


def _orient(p, q, r):
    dq, dr = q - p, r - p
    return dq[..., 0] * dr[..., 1] - dq[..., 1] * dr[..., 0]


def _within(p, q, r):
    """r inside the bounding box of segment pq (for collinear r)."""
    return (
        (np.minimum(p[..., 0], q[..., 0]) <= r[..., 0]) & (r[..., 0] <= np.maximum(p[..., 0], q[..., 0]))
        & (np.minimum(p[..., 1], q[..., 1]) <= r[..., 1]) & (r[..., 1] <= np.maximum(p[..., 1], q[..., 1]))
    )


def crossing_pairs(pieces):
    """Pairs of isoline segments that cross or touch, by brute force over all pairs.

    ``pieces`` is a list of closed loops (starts, ends, is_isoline). Two segments count when
    they intersect properly or an endpoint of one lies on the other (touching), except for
    segments next to each other on the same loop, which share their joint.
    """
    A, B, loop, pos, length, iso_flag = [], [], [], [], [], []
    for k, (a, b, f) in enumerate(pieces):
        n = len(a)
        A.append(a), B.append(b), iso_flag.append(f)
        loop.append(np.full(n, k)), pos.append(np.arange(n)), length.append(np.full(n, n))
    A, B = np.vstack(A), np.vstack(B)
    loop, pos, length = np.concatenate(loop), np.concatenate(pos), np.concatenate(length)
    sel = np.flatnonzero(np.concatenate(iso_flag))
    A, B, loop, pos, length = A[sel], B[sel], loop[sel], pos[sel], length[sel]
    lo, hi = np.minimum(A, B), np.maximum(A, B)
    bad = []
    chunk = 256
    for s in range(0, len(A), chunk):
        i = np.arange(s, min(s + chunk, len(A)))[:, None]
        j = np.arange(len(A))[None, :]
        cand = (j > i) & np.all(lo[i] <= hi[j], axis=2) & np.all(lo[j] <= hi[i], axis=2)
        ii, jj = np.nonzero(cand)
        ii = ii + s
        jj = j[0, jj]
        p1, p2, q1, q2 = A[ii], B[ii], A[jj], B[jj]
        d1, d2 = _orient(q1, q2, p1), _orient(q1, q2, p2)
        d3, d4 = _orient(p1, p2, q1), _orient(p1, p2, q2)
        proper = (d1 * d2 < 0) & (d3 * d4 < 0)
        touch = (
            ((d1 == 0) & _within(q1, q2, p1)) | ((d2 == 0) & _within(q1, q2, p2))
            | ((d3 == 0) & _within(p1, p2, q1)) | ((d4 == 0) & _within(p1, p2, q2))
        )
        gap = np.abs(pos[ii] - pos[jj])
        adjacent = (loop[ii] == loop[jj]) & ((gap == 1) | (gap == length[ii] - 1))
        hit = (proper | touch) & ~adjacent
        bad.extend(zip(ii[hit].tolist(), jj[hit].tolist()))
    return bad


def test_crossing_pairs_finds_crossings_and_touches():
    """The brute-force checker itself: a crossing, a touch and a clean pair."""
    sq = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)

    def piece(p):
        return p, np.roll(p, -1, axis=0), np.ones(len(p), bool)

    assert crossing_pairs([piece(sq), piece(sq + 5)]) == []
    assert len(crossing_pairs([piece(sq), piece(sq + 1)])) == 2  # two proper crossings
    touching = np.array([[2, 1], [4, 0], [4, 2]], float)  # a vertex on the square's side
    assert len(crossing_pairs([piece(sq), piece(touching)])) >= 1
    bow = np.array([[0, 0], [2, 2], [2, 0], [0, 2]], float)  # self-crossing bow tie
    assert len(crossing_pairs([piece(bow)])) == 1


# ---------------------------------------------------------------------------------------
# cones: circles of known radii
# ---------------------------------------------------------------------------------------

N_CONE, CX, CY, PEAK, SLOPE = 48, 23.7, 24.2, 200.0, 8.0


def cone(sign):
    yy, xx = centres(N_CONE, N_CONE)
    r = np.hypot(xx - CX, yy - CY)
    v = np.maximum(PEAK - SLOPE * r, 10.0)  # flat below 10: no level-7.5 loop on the frame
    return v if sign > 0 else 255.0 - v


@pytest.mark.parametrize("sign", [1, -1], ids=["peak", "pit"])
def test_cone_isolines_are_circles(sign):
    img = cone(sign)
    levels = preset_levels(10.0)
    iso = isolines_of(img, levels)
    # one loop per level between the flat floor and the apex, none elsewhere
    crossing = [k for k, L in enumerate(levels) if img.min() < L < img.max()]
    assert sorted(iso.level.tolist()) == crossing
    assert not iso.border.any()
    for i in range(iso.n_loops):
        L = levels[iso.level[i]]
        radius = (PEAK - L) / SLOPE if sign > 0 else (PEAK - (255.0 - L)) / SLOPE
        p = iso.loop(i)
        r = np.hypot(p[:, 0] - CX, p[:, 1] - CY)
        assert abs(r.mean() - radius) < 0.05, (L, r.mean(), radius)
        # near the apex and near the crease where the cone meets its floor (radius 23.75)
        # the cubic midpoints (Keys' a = -1, encoder/mapping.py) bend the circle most
        bound = 0.1 if 2.5 < radius < (PEAK - 10.0) / SLOPE - 1.5 else 0.2
        assert np.abs(r - radius).max() < bound, (L, radius)
        # orientation: higher values on the left as seen on screen (y down)
        area = signed_area(p)
        assert np.sign(area) == -sign  # peaks: negative shoelace area; pits: positive
        assert abs(abs(area) - np.pi * radius**2) < 0.02 * np.pi * radius**2 + 0.5
        # and locally: a step to the left of each segment goes up
        q = np.roll(p, -1, axis=0)
        d = q - p
        ok = np.hypot(d[:, 0], d[:, 1]) > 1e-6
        mid, d = 0.5 * (p + q)[ok], d[ok]
        left = np.column_stack([d[:, 1], -d[:, 0]]) / np.hypot(d[:, 0], d[:, 1])[:, None]
        rl = np.hypot(*(mid + 0.05 * left - [CX, CY]).T)
        rr = np.hypot(*(mid - 0.05 * left - [CX, CY]).T)
        assert np.all(sign * (rr - rl) > 0)  # peak: left is nearer the apex


def test_cone_chains_keep_orientation_and_radius():
    img = cone(1)
    vi = isophote.encode(img, preset="paper")
    ch = vi.channels[0]
    assert ch.n_contours == np.count_nonzero((ch.levels > img.min()) & (ch.levels < img.max())) == 18
    assert ch.base_band == 1
    assert not ch.border.any()
    for (lev, chain, _), (a, b, _) in zip(ch.chains(), chain_pieces(ch)):
        radius = (PEAK - ch.levels[lev]) / SLOPE
        assert np.array_equal(chain[0], chain[-1])
        r = np.hypot(a[:, 0] - CX, a[:, 1] - CY)
        assert np.abs(r - radius).max() < 0.5  # the curve stays in the ribbon (tol <= 0.5 px)
        assert signed_area(a) == pytest.approx(-np.pi * radius**2, rel=0.03)


# ---------------------------------------------------------------------------------------
# linear ramp: straight isolines, border stretches on the frame
# ---------------------------------------------------------------------------------------

RAMP_H, RAMP_W, RAMP_A, RAMP_S = 24, 40, 10.0, 6.0


def ramp():
    # pixel j (centre x = j + 0.5) holds a + s * j, so v(x) = a + s * (x - 0.5)
    return np.tile(RAMP_A + RAMP_S * np.arange(RAMP_W, dtype=np.float64), (RAMP_H, 1))


def test_ramp_isolines_are_straight_at_known_x():
    img = ramp()
    levels = preset_levels(10.0)
    iso = isolines_of(img, levels)
    expected = [k for k, L in enumerate(levels) if img.min() < L < img.max()]
    assert iso.level.tolist() == expected  # loops in level order, one each
    assert iso.base_band == 1  # the image lies above 7.5: that level only runs round the frame
    for i in range(iso.n_loops):
        L = levels[iso.level[i]]
        x_l = (L - RAMP_A) / RAMP_S + 0.5
        p, brd = iso.loop(i), loop_border(iso, i)
        q = np.roll(p, -1, axis=0)
        line = np.vstack([p[~brd], q[~brd]])  # both ends of the isoline segments
        # the Carrato midpoint next to the frame sees a zero outer difference, and a
        # crossing's cubic reads one sample beyond its edge: exact only from x = 2 on
        exact = 2.0 <= x_l <= RAMP_W - 2.0
        assert np.abs(line[:, 0] - x_l).max() < (1e-9 if exact else 0.01), (L, x_l)
        assert line[:, 1].min() == 0.0 and line[:, 1].max() == RAMP_H
        # border stretches: both ends exactly on one and the same image edge, on the right
        # of the isoline (values rise to the right)
        a, b = p[brd], q[brd]
        assert len(a) > 0
        on = [
            (a[:, 1] == 0) & (b[:, 1] == 0),
            (a[:, 0] == RAMP_W) & (b[:, 0] == RAMP_W),
            (a[:, 1] == RAMP_H) & (b[:, 1] == RAMP_H),
        ]
        assert np.all(on[0] | on[1] | on[2])
        assert np.all(on[0].any() & on[1].any() & on[2].any())
        assert np.all(np.minimum(a[:, 0], b[:, 0]) >= x_l - 0.01)
        # the loop is the rectangle [x_l, W] x [0, H], enclosing the higher values
        assert signed_area(p) == pytest.approx(-(RAMP_W - x_l) * RAMP_H, abs=0.01 if exact else 0.01 * RAMP_H)


def test_ramp_chains_border_flags_only_on_frame():
    vi = isophote.encode(ramp(), preset="paper")
    ch = vi.channels[0]
    assert ch.n_contours == 23
    for lev, chain, flags in ch.chains():
        x_l = (ch.levels[lev] - RAMP_A) / RAMP_S + 0.5
        segs = chain_segments(chain)
        on_frame = (
            np.all(segs[:, :, 1] == 0, axis=1) | np.all(segs[:, :, 0] == RAMP_W, axis=1)
            | np.all(segs[:, :, 1] == RAMP_H, axis=1)
        )
        assert np.array_equal(flags, on_frame)
        inner = segs[~flags]
        assert np.abs(inner[:, :, 0] - x_l).max() < 0.02  # the isoline stretch is straight


# ---------------------------------------------------------------------------------------
# saddles: isolines never cross or touch
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "centre_value, cx, cy",
    [(128.0, 16.0, 16.0), (127.5, 16.0, 16.0), (127.5, 16.25, 15.5), (131.0, 15.5, 16.5)],
    ids=["between-levels", "saddle-on-level", "off-grid", "on-sample"],
)
def test_saddle_isolines_never_cross_or_touch(centre_value, cx, cy):
    yy, xx = centres(32, 32)
    img = np.clip(centre_value + 0.4 * (xx - cx) * (yy - cy), 0.0, 255.0)
    levels = preset_levels(10.0)
    iso = isolines_of(img, levels)
    assert iso.n_loops > 20
    assert crossing_pairs(polyline_pieces(iso)) == []
    # the fitted chains (flattened) keep the property
    vi = isophote.encode(img, preset="paper")
    ch = vi.channels[0]
    assert ch.n_contours == iso.n_loops
    bad = crossing_pairs(chain_pieces(ch))
    assert bad == [], f"{len(bad)} crossing pairs among the fitted chains"


def test_isolines_of_a_natural_crop_never_cross():
    img = skimage.data.camera()[120:152, 100:132].astype(np.float64)
    iso = isolines_of(img, preset_levels(10.0))
    assert iso.n_loops > 10
    assert crossing_pairs(polyline_pieces(iso)) == []


# ---------------------------------------------------------------------------------------
# shapes cut by the border
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("corner", [False, True], ids=["half-disc-left", "quarter-disc-corner"])
def test_border_shapes_close_along_the_frame(corner):
    h, w = 40, 32
    cx, cy = 0.0, (0.0 if corner else 20.0)
    yy, xx = centres(h, w)
    r = np.hypot(xx - cx, yy - cy)
    img = np.clip(220.0 - 10.0 * r, 20.0, 255.0)
    levels = np.array([60.5, 100.5, 140.5, 180.5])
    iso = isolines_of(img, levels)
    assert iso.level.tolist() == [0, 1, 2, 3]
    part = 4 if corner else 2
    for i in range(iso.n_loops):
        radius = (220.0 - levels[iso.level[i]]) / 10.0
        p, brd = iso.loop(i), loop_border(iso, i)
        q = np.roll(p, -1, axis=0)
        a, b = p[brd], q[brd]
        assert len(a) > 0
        if corner:
            assert np.all(((a[:, 0] == 0) & (b[:, 0] == 0)) | ((a[:, 1] == 0) & (b[:, 1] == 0)))
            assert ((a[:, 0] == 0) & (b[:, 0] == 0)).any() and ((a[:, 1] == 0) & (b[:, 1] == 0)).any()
        else:
            assert np.all((a[:, 0] == 0) & (b[:, 0] == 0))
            # the border stretch spans the chord [cy - R, cy + R] of the frame
            ys = np.concatenate([a[:, 1], b[:, 1]])
            assert ys.min() == pytest.approx(cy - radius, abs=0.1)
            assert ys.max() == pytest.approx(cy + radius, abs=0.1)
        rr = np.hypot(p[~brd, 0] - cx, p[~brd, 1] - cy)
        assert abs(rr.mean() - radius) < 0.05 and np.abs(rr - radius).max() < 0.1
        # closed: the isoline arc and the border stretch bound the disc's part
        assert signed_area(p) == pytest.approx(-np.pi * radius**2 / part, rel=0.02)
    vi = isophote.encode(img, levels_y=tuple(levels), preset="paper")
    ch = vi.channels[0]
    assert ch.n_contours == 4
    for lev, chain, flags in ch.chains():
        assert np.array_equal(chain[0], chain[-1])
        segs = chain_segments(chain)
        on_frame = np.all(segs[:, :, 0] == 0, axis=1)
        if corner:
            on_frame |= np.all(segs[:, :, 1] == 0, axis=1)
        assert flags.any()
        assert np.array_equal(flags, on_frame)


# ---------------------------------------------------------------------------------------
# constant images
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "img",
    [
        np.full((16, 20), 100, np.uint8),
        np.full((16, 20), 0, np.uint8),
        np.full((16, 20), 255, np.uint8),
        np.full((12, 16, 3), (200, 30, 90), np.uint8),
        np.full((12, 16, 4), (200, 30, 90, 128), np.uint8),
    ],
    ids=["grey-100", "black", "white", "rgb", "rgba"],
)
def test_constant_image_has_no_contours_and_renders_exactly(img):
    vi = isophote.encode(img, preset="paper")
    if img.ndim == 2:
        values = {"Y": float(img.flat[0])}
    else:
        yuv = rgb_to_yuv(img[0, 0, :3].astype(np.float64))
        values = dict(zip("YUV", yuv))
        if img.shape[2] == 4:
            values["A"] = float(img[0, 0, 3])
    assert [ch.name for ch in vi.channels] == list(values)
    for ch in vi.channels:
        assert ch.n_contours == 0 and ch.n_segments == 0
        assert ch.base_band == np.searchsorted(ch.levels, values[ch.name], side="right")
    out = vi.render()
    assert out.dtype == np.uint8 and out.shape == img.shape
    assert np.array_equal(out, img)


def test_constant_on_a_level_counts_as_above():
    img = np.full((8, 8), 127.5)  # exactly on the paper preset's middle Y level
    vi = isophote.encode(img, preset="paper")
    ch = vi.channels[0]
    k = int(np.flatnonzero(ch.levels == 127.5)[0])
    assert ch.n_contours == 0 and ch.base_band == k + 1
    assert np.all(render_float(vi) == 127.5)


# ---------------------------------------------------------------------------------------
# noise, tolerance, fitting
# ---------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def camera_crop():
    return skimage.data.camera()[100:164, 100:164]


def test_more_noise_fewer_segments(camera_crop):
    counts = [isophote.encode(camera_crop, noise=e, preset="paper").channels[0].n_segments for e in (0.5, 2.0, 8.0)]
    assert counts[0] > counts[1] > counts[2], counts
    assert counts[2] < 0.7 * counts[0]


def test_fitted_chains_stay_within_the_ribbon(camera_crop):
    """Every isoline point is within its tolerance of its fitted and stored chain: the fitter
    checks the joints and handles on the file's 1/64 px grid itself, so the rounding moves
    nothing (it could move the handles of a segment that no rounding fits, by at most
    1/128 px a coordinate: there is none here)."""
    opts = EncodeOptions(preset="paper").resolved()
    img = camera_crop.astype(np.float64)
    levels = channel_levels("Y", opts)
    iso = isolines_of(img, levels)
    vi = isophote.encode(camera_crop, preset="paper")
    ch = vi.channels[0]
    assert ch.n_contours == iso.n_loops > 50
    assert np.array_equal(ch.contour_level, iso.level)
    # control points are stored on the 1/64 grid
    assert np.array_equal(ch.points * QUANT, np.round(ch.points * QUANT))
    worst = -np.inf
    for k in range(iso.n_loops):
        d = chain_distance(ch.chain(k), iso.loop(k))
        tol = iso.tol[iso.offsets[k] : iso.offsets[k + 1]]
        worst = max(worst, float(np.max(d - tol)))
    assert worst <= 1e-9, worst


# ---------------------------------------------------------------------------------------
# hierarchy and caps
# ---------------------------------------------------------------------------------------


def rings():
    """Alternating rings: 128 + 100 cos(pi r / 8) out to r = 16, then down to 28 by r = 20."""
    yy, xx = centres(48, 48)
    r = np.hypot(xx - 23.7, yy - 24.2)
    return np.where(r <= 16, 128 + 100 * np.cos(np.pi * r / 8), np.maximum(228 - 50 * (r - 16), 28))


def test_nested_rings_parents():
    levels = np.array([77.5, 177.5])
    # analytic radii: cos(pi r / 8) = +-0.495, and 228 - 50 (r - 16) = L
    th_hi, th_lo = np.arccos(49.5 / 100), np.arccos(-50.5 / 100)
    expected = [  # (radius, level index, encloses higher values), from the outside in
        (16 + 150.5 / 50, 0, True),
        (16 + 50.5 / 50, 1, True),
        (8 * (2 * np.pi - th_hi) / np.pi, 1, False),
        (8 * (2 * np.pi - th_lo) / np.pi, 0, False),
        (8 * th_lo / np.pi, 0, True),
        (8 * th_hi / np.pi, 1, True),
    ]
    iso = isolines_of(rings(), levels)
    assert iso.n_loops == 6
    radius = np.array([np.hypot(iso.loop(i)[:, 0] - 23.7, iso.loop(i)[:, 1] - 24.2).mean() for i in range(6)])
    order = np.argsort(-radius)
    for (r_exp, lev, up), i in zip(expected, order):
        assert radius[i] == pytest.approx(r_exp, abs=0.1)
        assert iso.level[i] == lev
        assert (signed_area(iso.loop(i)) < 0) == up
    tree = build_hierarchy(iso, levels)
    # each loop's parent is the next larger ring
    assert tree.parent[order[0]] == -1
    for outer, inner in zip(order[:-1], order[1:]):
        assert tree.parent[inner] == outer
    vi = isophote.encode(rings(), levels_y=tuple(levels), preset="paper")
    assert np.array_equal(vi.channels[0].parent, tree.parent)
    assert np.array_equal(vi.channels[0].contour_level, iso.level)


def two_bumps(sign):
    yy, xx = centres(40, 56)
    z = 40 + 150 * np.exp(-((xx - 20.3) ** 2 + (yy - 20.2) ** 2) / 50)
    z = z + 150 * np.exp(-((xx - 36.2) ** 2 + (yy - 19.7) ** 2) / 50)
    return z if sign > 0 else 255.0 - z


@pytest.mark.parametrize("sign", [1, -1], ids=["peaks", "pits"])
def test_two_bumps_are_siblings_with_caps(sign):
    img = two_bumps(sign)
    levels = (100.5, 150.5) if sign > 0 else (104.5, 154.5)
    vi = isophote.encode(img, levels_y=levels, preset="paper")
    ch = vi.channels[0]
    inner = 1 if sign > 0 else 0  # the level around each bump alone
    outer = 1 - inner
    assert ch.n_contours == 3
    assert sorted(ch.contour_level.tolist()) == sorted([outer, inner, inner])
    big = int(np.flatnonzero(ch.contour_level == outer)[0])
    small = np.flatnonzero(ch.contour_level == inner)
    assert ch.parent[big] == -1
    assert ch.parent[small].tolist() == [big, big]  # siblings, one parent
    level = levels[inner]
    for centre in ((20.3, 20.2), (36.2, 19.7)):
        # the bump's extremum among the samples near it
        yy, xx = centres(*img.shape)
        near = np.hypot(xx - centre[0], yy - centre[1]) < 3
        extremum = img[near].max() if sign > 0 else img[near].min()
        k = np.flatnonzero(np.hypot(ch.cap_xy[:, 0] - centre[0], ch.cap_xy[:, 1] - centre[1]) < 1.0)
        assert len(k) == 1, ch.cap_xy
        k = int(k[0])
        assert ch.cap_band[k] == np.searchsorted(ch.levels, extremum, side="right")
        assert ch.cap_band[k] == (2 if sign > 0 else 0)
        assert ch.cap_contour[k] in small.tolist()
        # cap value: on the bump's side of its level, near its extremum
        assert sign * (ch.cap_value[k] - level) > 0
        assert abs(ch.cap_value[k] - extremum) <= 0.25 * abs(extremum - level), (ch.cap_value[k], extremum)
    # the two bumps' caps hang from different contours
    caps = [c for c in ch.cap_contour.tolist() if c in small.tolist()]
    assert sorted(caps) == sorted(small.tolist())


# ---------------------------------------------------------------------------------------
# determinism and validation
# ---------------------------------------------------------------------------------------


def test_encoding_is_deterministic():
    img = skimage.data.astronaut()[200:248, 180:228]
    a = dumps(isophote.encode(img, preset="paper"))
    b = dumps(isophote.encode(img.copy(), preset="paper"))
    assert a == b
    assert len(a) > 1000


@pytest.mark.parametrize(
    "bad",
    [
        np.full((4, 4), np.nan),
        np.full((4, 4), np.inf),
        np.zeros(5),
        np.zeros((2, 2, 2, 2)),
        np.zeros((4, 4, 5)),
        np.zeros((0, 4)),
        np.zeros((4, 0, 3)),
        np.full((4, 4), 255.5),
        np.full((4, 4), -0.5),
        np.array([["a", "b"]]),
    ],
    ids=["nan", "inf", "1-d", "4-d", "5-channels", "empty", "empty-rgb", "above-255", "negative",
         "strings"],
)
def test_bad_images_raise_input_error(bad):
    with pytest.raises(InputError):
        isophote.encode(bad)


@pytest.mark.parametrize(
    "options",
    [
        dict(preset="nope"),
        dict(y_step=0),
        dict(y_step=0.25),
        dict(uv_step=200),
        dict(alpha_step=-1),
        dict(noise=-1),
        dict(noise=100),
        dict(snap=90),
        dict(min_tolerance=0),
        dict(min_tolerance=1.0, max_tolerance=0.5),
        dict(carrato_scale=0),
        dict(levels_y=(10, 5)),
        dict(levels_y=(0, 5)),
        dict(levels_u=(5, 255)),
    ],
)
def test_bad_options_raise_option_error(options):
    with pytest.raises(OptionError):
        isophote.encode(np.zeros((4, 4), np.uint8), **options)


def test_input_depths_are_scaled():
    """uint16 is divided by 257 and bool is 0/255: the same picture, the same contours."""
    ramp8 = np.tile(np.arange(0, 256, 8, dtype=np.uint8), (6, 1))
    a = isophote.encode(ramp8, preset="paper")
    b = isophote.encode(ramp8.astype(np.uint16) * 257, preset="paper")
    assert b.source_depth == 16 and a.source_depth == 8
    assert np.array_equal(a.channels[0].contour_level, b.channels[0].contour_level)
    assert np.abs(a.channels[0].points - b.channels[0].points).max() <= 0.5
    mask = np.zeros((8, 8), bool)
    mask[2:6, 2:6] = True
    c = isophote.encode(mask, preset="paper")
    d = isophote.encode(mask.astype(np.uint8) * 255, preset="paper")
    assert c.channels[0].equals(d.channels[0])


# ---------------------------------------------------------------------------------------
# compiled stages against their plain twins (issue 6: the encoder's speed)
# ---------------------------------------------------------------------------------------


def test_cubic_base_interpolates_cubics_exactly():
    """With p = 0 the midpoints are the 4-point Lagrange (Catmull-Rom) midpoints at cubic = 1,
    exact for a cubic polynomial away from the ends, and the linear midpoints at cubic = 0."""
    x = np.arange(12, dtype=np.float64)
    f = lambda t: 0.05 * t**3 - 0.4 * t**2 + 3.0 * t + 20.0  # noqa: E731
    row = np.tile(f(x), (3, 1))
    g, ge = map_pixels(row, 0.5, 0.0, 64.0, 1.0)
    mids = g[3, 2:-2:2]  # between samples j and j + 1 (grid columns 2j + 2)
    np.testing.assert_allclose(mids[1:-1], f(x[1:-2] + 0.5), atol=1e-9)
    g0, ge0 = map_pixels(row, 0.5, 0.0, 64.0, 0.0)
    np.testing.assert_allclose(g0[3, 2:-2:2], 0.5 * (f(x[:-1]) + f(x[1:])), atol=1e-9)
    # the cubic term's error: (1/16)(2 eps + 2 eps) on top of the linear midpoint's eps
    assert ge[3, 6] == pytest.approx(ge0[3, 6] + 4 * 0.5 / 16)
    # at a step the cubic would ring; clamped, flat stays flat and no midpoint overshoots
    step = np.tile(np.repeat([50.0, 200.0], 6), (3, 1))
    gs, _ = map_pixels(step, 0.5, 0.5, 64.0, 1.0)
    assert gs.min() == 50.0 and gs.max() == 200.0
    assert np.all(gs[:, :11] == 50.0) and np.all(gs[:, -11:] == 200.0)


def test_map_pixels_matches_its_numpy_twin():
    from isophote.encoder.mapping_ref import map_pixels as map_pixels_ref

    rng = np.random.default_rng(11)
    for k in range(40):
        h, w = rng.integers(1, 25, size=2)
        v = rng.uniform(0, 255, (h, w)) if k % 3 else np.round(rng.uniform(0, 4, (h, w))) * 64.0
        eps = 0.5 if k % 2 else rng.uniform(0, 3, (h, w))
        p, scale = (0.5, 64.0) if k % 4 else (rng.uniform(0, 2), rng.uniform(1, 128))
        cubic = (1.0, 0.0, rng.uniform(0, 2))[k % 3]
        for a, b in zip(map_pixels(v, eps, p, scale, cubic), map_pixels_ref(v, eps, p, scale, cubic)):
            assert a.shape == b.shape == (2 * h + 1, 2 * w + 1)
            assert a.tobytes() == b.tobytes()  # equal to the bit, signed zeros included


def _fit_isolines_ref(iso, snap):
    """Plain twin of encoder.fit_isolines: every loop on its own, border runs in a Python
    loop (the implementation the vectorised one replaced)."""
    from isophote.encoder import _JOINT_ROUNDING, _ROUNDING, ANCHOR_GRID, HANDLE_SHIFT, _joint_reach
    from isophote.encoder.fit import fit_polyline

    tol = np.maximum(iso.tol - _ROUNDING, 0.25 * iso.tol)
    reach = np.minimum(_joint_reach(iso, tol), np.maximum(tol - _JOINT_ROUNDING, 0.0))
    chains, borders = [], []
    for i in range(iso.n_loops):
        o0, o1 = iso.offsets[i], iso.offsets[i + 1]
        pts, brd, tl, rc = iso.points[o0:o1], iso.border[o0:o1], tol[o0:o1], reach[o0:o1]
        n = len(pts)
        if not brd.any():
            ch = fit_polyline(pts, tl, True, snap, HANDLE_SHIFT, ANCHOR_GRID, rc)
            chains.append(ch)
            borders.append(np.zeros((len(ch) - 1) // 3, bool))
            continue
        k0 = int(np.flatnonzero(~brd & np.roll(brd, 1))[0])
        idx = (np.arange(n + 1) + k0) % n
        segb = brd[idx[:-1]]
        parts, flags = [], []
        start = 0
        while start < n:
            stop = start
            while stop < n and segb[stop] == segb[start]:
                stop += 1
            run = idx[start : stop + 1]
            if segb[start]:
                p = pts[run]
                p = p[np.concatenate([[True], np.any(p[1:] != p[:-1], axis=1)])]
                if len(p) >= 3:
                    d = np.diff(p, axis=0)
                    turn = np.abs(d[:-1, 0] * d[1:, 1] - d[:-1, 1] * d[1:, 0]) > 1e-12
                    p = p[np.concatenate([[True], turn, [True]])]
                out = [p[0]]
                for a, b in zip(p[:-1], p[1:]):
                    if not np.array_equal(a, b):
                        out += [a + (b - a) / 3.0, a + 2.0 * (b - a) / 3.0, b]
                ch = np.asarray(out)
                if len(ch) > 1:
                    parts.append(ch[1:] if parts else ch)
                    flags.append(np.ones((len(ch) - 1) // 3, bool))
            else:
                ch = fit_polyline(pts[run], tl[run], False, snap, HANDLE_SHIFT, ANCHOR_GRID, rc[run])
                parts.append(ch[1:] if parts else ch)
                flags.append(np.zeros((len(ch) - 1) // 3, bool))
            start = stop
        ch = np.vstack(parts)
        ch[-1] = ch[0]
        chains.append(ch)
        borders.append(np.concatenate(flags))
    offsets = np.concatenate([[0], np.cumsum([len(c) for c in chains])]).astype(np.int64)
    points = np.vstack(chains) if chains else np.zeros((0, 2))
    border = np.concatenate(borders) if borders else np.zeros(0, bool)
    return points, offsets, border


@pytest.mark.parametrize("which", ["astronaut", "camera", "noise", "ramp"])
def test_fit_isolines_matches_its_plain_twin(which):
    from isophote.encoder import fit_isolines

    rng = np.random.default_rng(3)
    img = {
        "astronaut": rgb_to_yuv(skimage.data.astronaut()[150:214, 190:250].astype(float))[..., 1],
        "camera": skimage.data.camera()[300:370, 0:64].astype(float),
        "noise": rng.uniform(0, 255, (23, 31)),
        "ramp": np.tile(np.linspace(0, 255, 40), (12, 1)),
    }[which]
    iso = isolines_of(img, preset_levels(10 if which != "astronaut" else 5))
    assert iso.border.any() and iso.n_loops > 3
    fast = fit_isolines(iso, 20.0)
    ref = _fit_isolines_ref(iso, 20.0)
    for a, b in zip(fast, ref):
        assert a.shape == b.shape and np.array_equal(a, b)


def _sample_joints(ch):
    """Per channel: the anchors lying on the 0.5 px sample grid, as {(2x, 2y): levels}."""
    lv = np.repeat(ch.contour_level, np.diff(ch.offsets))
    idx = np.arange(len(ch.points)) - np.repeat(ch.offsets[:-1], np.diff(ch.offsets))
    anchor = idx % 3 == 0
    p, lv = ch.points[anchor], lv[anchor]
    on = np.all(p * 2 == np.floor(p * 2), axis=1)
    out = {}
    for (x, y), level in zip((p[on] * 2).astype(np.int64).tolist(), lv[on].tolist()):
        out.setdefault((x, y), set()).add(level)
    return out


def test_joints_move_onto_samples_and_levels_never_meet_there(monkeypatch):
    """Joints move onto the 2x sample grid (encoder.ANCHOR_GRID): far more anchors lie on
    samples than without the move, and no sample gets joints of two levels that it did not
    have before (frame corners and border runs may share points anyway)."""
    import isophote.encoder as enc

    img = skimage.data.astronaut()[100:228, 150:278]
    moved = isophote.encode(img, preset="balanced")
    monkeypatch.setattr(enc, "ANCHOR_GRID", 0.0)
    plain = isophote.encode(img, preset="balanced")
    for a, b in zip(moved.channels, plain.channels):
        ja, jb = _sample_joints(a), _sample_joints(b)
        assert len(ja) > 4 * len(jb) + 100, (a.name, len(ja), len(jb))
        clash_a = {k for k, v in ja.items() if len(v) > 1}
        clash_b = {k for k, v in jb.items() if len(v) > 1}
        assert clash_a <= clash_b, (a.name, sorted(clash_a - clash_b)[:5])


@pytest.mark.parametrize("which", ["astronaut", "camera", "noise", "steps"])
def test_joint_reach_matches_its_twin(which):
    """The compiled rule (_kernels/anchors.py) equals its NumPy twin, and grants a move to
    a good share of the crossings of a photograph, never beyond 0.75 of a tolerance."""
    from isophote.encoder._kernels.anchors import joint_moves, joint_reach
    from isophote.encoder._kernels.anchors_ref import joint_reach as joint_reach_ref

    rng = np.random.default_rng(5)
    img = {
        "astronaut": rgb_to_yuv(skimage.data.astronaut()[150:214, 190:250].astype(float))[..., 0],
        "camera": skimage.data.camera()[300:370, 0:64].astype(float),
        "noise": rng.uniform(0, 255, (23, 31)),
        "steps": np.kron(rng.integers(0, 4, (6, 8)) * 60.0, np.ones((5, 5))),  # many crossings per edge
    }[which]
    iso = isolines_of(img, preset_levels(5))
    tol = iso.tol * rng.uniform(0.5, 1.0, iso.tol.shape)
    args = (iso.along, iso.below, iso.step, iso.band.ravel(), iso.offsets, iso.level, tol,
            iso.values.shape[1], 0.75)
    fast, ref = joint_reach(*args), joint_reach_ref(iso.points, iso.below, iso.above, *args[3:])
    assert np.array_equal(fast, ref)
    assert np.all((fast == 0) | (fast == 0.75 * tol))
    if which in ("astronaut", "camera"):
        assert np.mean(fast > 0) > 0.1, np.mean(fast > 0)
    # the kernel takes the samples a band of rows at a time: any band height, the same moves
    for rows, workers in ((1, 1), (2, 3), (3, 2), (7, 1), (7, 5), (1000, 2)):
        assert np.array_equal(joint_moves(*args, rows, workers=workers), ref > 0), (rows, workers)
    # and bands listed and decided a few candidates at a time (one band a run at least)
    for rows, workers, most in ((1, 1, 1), (2, 2, 5), (3, 1, 40), (7, 2, 0)):
        got = joint_moves(*args, rows, workers=workers, max_candidates=most)
        assert np.array_equal(got, ref > 0), (rows, workers, most)


def test_band_groups_cover_the_bands_in_runs_under_the_cap():
    from isophote.encoder._kernels.anchors import band_groups

    per_band = np.array([3, 0, 9, 2, 2, 2, 0, 0, 12, 1])
    assert band_groups(per_band) == [(0, 10)]
    assert band_groups(per_band, 6) == [(0, 2), (2, 3), (3, 8), (8, 9), (9, 10)]
    assert band_groups(per_band, 100) == [(0, 10)]
    # a band over the cap is a run alone; empty bands join the run before them
    assert band_groups(per_band, 0) == [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 6), (6, 8), (8, 9), (9, 10)]
    assert band_groups(np.zeros(0, np.int64), 5) == [(0, 0)]


def test_moved_joints_keep_every_loop_open_and_its_way_round(monkeypatch):
    """A photograph's small loops circle one sample or two, with all their crossings next to
    it. At most PER_LOOP of a loop's crossings move onto one sample (_kernels/anchors.py), so
    every loop keeps its orientation and at least a tenth of the area it has without the
    move (with four, small loops shrink to a point: area 0)."""
    import isophote.encoder as enc

    img = skimage.data.astronaut()[::2, ::2][60:188, 60:188]
    moved = isophote.encode(img, preset="paper")
    monkeypatch.setattr(enc, "ANCHOR_GRID", 0.0)
    plain = isophote.encode(img, preset="paper")
    for a, b in zip(moved.channels, plain.channels):
        assert a.n_contours == b.n_contours
        for k in range(a.n_contours):
            area_b = signed_area(sample_chain_closed(b.points[b.offsets[k] : b.offsets[k + 1]]))
            if abs(area_b) > 1e-3:
                area_a = signed_area(sample_chain_closed(a.points[a.offsets[k] : a.offsets[k + 1]]))
                assert area_a / area_b > 0.1, (a.name, k, area_a, area_b)


def sample_chain_closed(chain, per=32):
    """Points along a closed Bezier chain (its last point is its first)."""
    t = np.linspace(0, 1, per, endpoint=False)[:, None]
    out = []
    for i in range(0, len(chain) - 1, 3):
        p0, c0, c1, p1 = chain[i : i + 4]
        out.append((1 - t) ** 3 * p0 + 3 * (1 - t) ** 2 * t * c0 + 3 * (1 - t) * t * t * c1 + t**3 * p1)
    return np.vstack(out)


def test_cap_values_lie_on_half_the_input_error():
    """Cap values are rounded to half the input's error, on the file's 1/64 value grid:
    quarter levels for 8-bit samples, 1/64 for 16-bit ones, whatever a noise option says."""
    from isophote.encoder import QUANT, cap_value_step

    assert cap_value_step(0.5) == 0.25
    assert cap_value_step(0.5 / 257.0) == 1.0 / QUANT
    assert cap_value_step(1.3) == 41.0 / QUANT  # floor(0.65 * 64) / 64
    img = skimage.data.camera()[100:164, 200:264]
    for image, step in ((img, 0.25), (img.astype(np.uint16) * 257, 1.0 / QUANT)):
        ch = isophote.encode(image, preset="balanced").channels[0]
        assert len(ch.cap_value) > 10
        assert np.array_equal(ch.cap_value, np.round(ch.cap_value / step) * step)
        on_quarters = np.array_equal(ch.cap_value, np.round(ch.cap_value * 4) / 4)
        assert on_quarters == (step == 0.25)  # 16-bit caps keep their finer digits
    ch = isophote.encode(img, preset="balanced", noise=1.3).channels[0]
    assert np.allclose(ch.cap_value / (41.0 / QUANT), np.round(ch.cap_value / (41.0 / QUANT)))


def test_chain_rotation_kernel_matches_its_twin():
    """_kernels/rotate.py against its NumPy twin (a sort of every joint): chains of 1 to 9
    segments, joints tied in y, in x and in both (then the first), signed zeros."""
    from isophote.encoder._kernels.rotate import rotate_chains
    from isophote.encoder._kernels.rotate_ref import rotate_chains as rotate_chains_ref

    rng = np.random.default_rng(17)
    chains, borders = [], []
    for k in range(300):
        n = int(rng.integers(1, 10))
        body = rng.integers(-2, 3, (3 * n, 2)).astype(float) * 0.5  # coarse: many ties
        if k % 7 == 0:
            body[::3, 1] = -0.0 if k % 2 else 0.0
        chains.append(np.vstack([body, body[:1]]))
        borders.append(rng.random(n) < 0.3)
    points = np.vstack(chains)
    offsets = np.concatenate([[0], np.cumsum([c.shape[0] for c in chains])]).astype(np.int64)
    border = np.concatenate(borders)
    got, ref = rotate_chains(points, offsets, border), rotate_chains_ref(points, offsets, border)
    assert got[0].tobytes() == ref[0].tobytes() and np.array_equal(got[1], ref[1])
    moved = sum(not np.array_equal(got[0][offsets[i]], points[offsets[i]]) for i in range(300))
    assert moved > 100


def test_chains_start_at_their_first_joint_in_scan_order(monkeypatch):
    """encoder.start_at_first_joint: a hand-made square chain and its border flags rotate to
    start at the top-left joint; on a photograph every chain starts at its joint first in
    scan order, with the same segments as the fitter's order, and renders the same."""
    import isophote.encoder as enc

    sq = np.array([[4, 4], [4, 3], [4, 2], [4, 1], [3, 1], [2, 1], [1, 1], [1, 2], [1, 3], [1, 4],
                   [2, 4], [3, 4], [4, 4]], float)  # joints (4,4) (4,1) (1,1) (1,4)
    tri = np.array([[0, 5], [1, 5], [2, 5], [3, 5], [2, 6], [1, 7], [0, 5]], float)
    points = np.vstack([sq, tri])
    offsets = np.array([0, 13, 20])
    border = np.array([True, False, False, True, False, True])
    p, b = enc.start_at_first_joint(points, offsets, border)
    assert np.array_equal(p[:13], np.vstack([sq[6:12], sq[:7]]))  # from (1, 1)
    assert np.array_equal(b, [False, True, True, False, False, True])
    assert np.array_equal(p[13:], tri)  # already first
    img = skimage.data.astronaut()[::2, ::2][60:188, 60:188]
    vi = isophote.encode(img, preset="balanced")
    monkeypatch.setattr(enc, "start_at_first_joint", lambda p, o, b: (p, b))
    plain = isophote.encode(img, preset="balanced")
    rotated = 0
    for a, c in zip(vi.channels, plain.channels):
        seg_a = np.column_stack([segments(a)[0].reshape(-1, 8), segments(a)[1]])
        seg_c = np.column_stack([segments(c)[0].reshape(-1, 8), segments(c)[1]])
        for k in range(a.n_contours):
            ja = a.points[a.offsets[k] : a.offsets[k + 1] : 3]
            first = np.lexsort((ja[:, 0], ja[:, 1]))[0]
            assert first == 0, (a.name, k)
            rotated += not np.array_equal(a.points[a.offsets[k]], c.points[c.offsets[k]])
        assert np.array_equal(np.unique(seg_a, axis=0), np.unique(seg_c, axis=0))
    assert rotated > 100
    assert np.abs(render_float(vi) - render_float(plain)).max() < 0.05


def test_channels_one_at_a_time_when_memory_is_short(monkeypatch):
    """Two channels at a time unless their memory would not fit; the file is the same bytes
    either way (channels are independent)."""
    import isophote.encoder as E

    monkeypatch.setattr(E, "available_memory", lambda: 32 * 2**30)
    assert E.channel_workers(512 * 512) == 2
    assert E.channel_workers(40_000_000) == 2  # 18.8 GB for the pair against 25.8 GB usable
    assert E.channel_workers(60_000_000) == 1  # 28.2 GB
    monkeypatch.setattr(E, "available_memory", lambda: None)  # unknown: two
    assert E.channel_workers(100_000_000) == 2
    img = skimage.data.astronaut()[100:164, 150:230]
    both = dumps(isophote.encode(img, preset="paper"))
    seen = []
    real = E.threads.pool
    monkeypatch.setattr(E.threads, "pool", lambda n: seen.append(n) or real(n))
    monkeypatch.setattr(E, "available_memory", lambda: 1000)
    assert dumps(isophote.encode(img, preset="paper")) == both
    assert seen[0] == 1  # the channels' pool


def test_encode_pixels_held_empties_its_list_and_gives_the_same_image(monkeypatch):
    """The CLI hands its samples over (encode_pixels_held) so that the encoder can drop them
    once they are YUV planes: the same image as encode_pixels, the list emptied, and the
    samples gone (nothing refers to them) before the first channel is encoded."""
    import gc
    import weakref

    import isophote.encoder as enc
    from isophote.format.isoph import dumps
    from isophote.options import EncodeOptions

    opts = EncodeOptions(preset="balanced").resolved()
    px = skimage.data.astronaut()[100:164, 120:200].astype(np.float64)
    want = dumps(enc.encode_pixels(px.copy(), 8, opts))
    held = [px.copy()]
    ref = weakref.ref(held[0])
    alive = []
    real = enc.encode_channel

    def channel(*a, **k):
        gc.collect()
        alive.append(ref() is not None)
        return real(*a, **k)

    monkeypatch.setattr(enc, "encode_channel", channel)
    got = dumps(enc.encode_pixels_held(held, 8, opts))
    assert got == want and held == [] and alive == [False, False, False]
    with pytest.raises(ValueError):
        enc.encode_pixels_held([px, px], 8, opts)
