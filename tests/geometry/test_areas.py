"""Exact areas (geometry/areas.py) of shapes whose areas are known."""

import numpy as np
import pytest

from conftest import circle, square
from isophote.geometry import polyline_areas, segment_moments, signed_areas
from isophote.geometry.bezier import evaluate_grid
from isophote.geometry.chains import chain_segments

# The 4-cubic circle with handles K = 4/3 (sqrt 2 - 1) never lies inside the circle and strays
# at most 2.7253e-4 r outside it (Goldapp 1991), so its area lies in [pi r^2, pi r^2 (1 + 2e)].
RADIAL_ERROR = 2.7253e-4


def offsets(*chains):
    return np.concatenate([[0], np.cumsum([len(c) for c in chains])]).astype(np.int64)


@pytest.mark.parametrize("r", [1.0, 5.0, 123.25])
def test_circle_of_four_cubics(r):
    c = circle(40.0, -7.0, r)
    a = signed_areas(c, offsets(c))[0]
    assert np.pi * r * r <= a <= np.pi * r * r * (1 + 2 * RADIAL_ERROR) * (1 + 1e-12)
    assert a - np.pi * r * r > 1e-5 * np.pi * r * r  # the approximation is measurably outside


def test_circle_matches_a_dense_polygon():
    c = circle(3.0, 4.0, 10.0)
    segs, _ = chain_segments(c, offsets(c))
    dense = evaluate_grid(segs, np.linspace(0, 1, 4001)[:-1]).reshape(-1, 2)
    poly = polyline_areas(dense, np.array([0, len(dense)]))[0]
    assert signed_areas(c, offsets(c))[0] == pytest.approx(poly, rel=1e-7)


def test_square_and_orientation_signs():
    cw, ccw = square(2.0, 3.0, 7.0), square(2.0, 3.0, 7.0, clockwise=False)
    # y down: clockwise on screen is positive (the shoelace sum of model.py coordinates)
    assert np.array_equal(signed_areas(np.concatenate([cw, ccw]), offsets(cw, ccw)), [49.0, -49.0])
    c1, c2 = circle(0, 0, 2.0), circle(0, 0, 2.0, clockwise=False)
    a = signed_areas(np.concatenate([c1, c2]), offsets(c1, c2))
    assert a[0] > 0 and a[1] == pytest.approx(-a[0], rel=1e-15)


def test_moments_add_up_to_the_signed_areas():
    rng = np.random.default_rng(3)
    chains = [circle(*rng.uniform(-50, 50, 2), rng.uniform(1, 9)) + rng.normal(0, 0.3, (13, 2)) for _ in range(6)]
    for c in chains:
        c[-1] = c[0]
    pts, off = np.concatenate(chains), offsets(*chains)
    m = segment_moments(pts, off)
    per_chain = np.add.reduceat(m, np.arange(0, 24, 4))
    assert np.allclose(per_chain, signed_areas(pts, off), rtol=1e-12, atol=1e-9)


def test_empty_chains():
    assert signed_areas(np.zeros((0, 2)), np.zeros(1, np.int64)).shape == (0,)
    assert segment_moments(np.zeros((0, 2)), np.zeros(1, np.int64)).shape == (0,)


def test_polyline_areas_known_shapes():
    tri = np.array([[0, 0], [4, 0], [0, 3]], float)  # right, then down-left: clockwise on screen
    sq = np.array([[0, 0], [0, 2], [2, 2], [2, 0]], float)  # down first: counter-clockwise
    a = polyline_areas(np.concatenate([tri, sq]), np.array([0, 3, 7]))
    assert np.array_equal(a, [6.0, -4.0])


def test_polyline_areas_are_the_shoelace_sums_to_the_bit():
    """polyline_areas (two arrays a point) gives the bits of the plain formula (every point's
    successor gathered, the cross products summed in one running sum) on many loops, the
    hierarchy's tie-breaks depend on it."""
    rng = np.random.default_rng(9)
    sizes = rng.integers(1, 40, 300)
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    pts = rng.uniform(-500, 3000, (int(offsets[-1]), 2))
    nxt = np.arange(1, pts.shape[0] + 1)
    nxt[offsets[1:] - 1] = offsets[:-1]
    cross = pts[:, 0] * pts[nxt, 1] - pts[nxt, 0] * pts[:, 1]
    cs = np.concatenate([[0.0], np.cumsum(cross)])
    plain = 0.5 * (cs[offsets[1:]] - cs[offsets[:-1]])
    got = polyline_areas(pts, offsets)
    assert got.tobytes() == plain.tobytes()
    one = pts[offsets[7] : offsets[8]]
    assert got[7] == pytest.approx(0.5 * float(np.dot(one[:, 0], np.roll(one[:, 1], -1))
                                             - np.dot(np.roll(one[:, 0], -1), one[:, 1])), rel=1e-9, abs=1e-6)


def test_polyline_areas_kernel_is_its_numpy_twin_to_the_bit():
    from isophote.geometry import areas_ref

    rng = np.random.default_rng(11)
    for n_loops, top in ((1, 2), (1, 50), (500, 60)):
        sizes = rng.integers(1, top, n_loops)  # one-point loops included
        offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        pts = rng.uniform(-500, 3000, (int(offsets[-1]), 2))
        on_grid = rng.random(pts.shape[0]) < 0.3  # half-pixel points, as the march's are
        pts[on_grid] = np.round(pts[on_grid] * 2) / 2
        got = polyline_areas(pts, offsets)
        assert got.tobytes() == areas_ref.polyline_areas(pts, offsets).tobytes()
        xy = (np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1]))
        assert polyline_areas(xy, offsets).tobytes() == got.tobytes()
