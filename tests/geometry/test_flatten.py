"""Flattening of Bezier chains (geometry/flatten.py): the kernel against its NumPy twin, and the
chord error bound of Wang's formula measured independently."""

import numpy as np

from isophote.geometry import flatten, flatten_ref


def random_segments(rng, n):
    p0 = rng.uniform(0, 50, (n, 2))
    return np.stack([p0 + rng.normal(0, 6, (n, 2)) * k for k in (0, 1, 2, 3)], axis=1)


def test_kernel_matches_numpy_twin():
    rng = np.random.default_rng(1)
    segs = random_segments(rng, 300)
    border = rng.random(300) < 0.2
    for tol in (0.01, 0.1, 1.0):
        a, b = flatten(segs, border, tol), flatten_ref(segs, border, tol)
        for x, y in zip(a, b):
            assert x.shape == y.shape
            assert np.allclose(x, y, rtol=0, atol=1e-12)


def test_chords_stay_within_tolerance():
    rng = np.random.default_rng(2)
    segs = random_segments(rng, 50)
    tol = 0.05
    x0, y0, x1, y1, _ = flatten(segs, np.zeros(50, bool), tol)
    # every curve point lies within tol of the chord covering its parameter range
    edges = np.stack([x0, y0, x1, y1], axis=1)
    start = 0
    for s in segs:
        t = np.linspace(0, 1, 2001)
        u = 1 - t
        pts = (u**3)[:, None] * s[0] + (3 * u * u * t)[:, None] * s[1] + (3 * u * t * t)[:, None] * s[2] + (t**3)[:, None] * s[3]
        # edges of this segment: those whose start chain continues from s[0] to s[3]
        n = 1
        while not np.allclose(edges[start + n - 1, 2:], s[3], atol=0):
            n += 1
        e = edges[start : start + n]
        start += n
        a, b = e[:, :2], e[:, 2:]
        d = b - a
        ll = np.maximum((d * d).sum(1), 1e-300)
        h = np.clip(((pts[:, None, :] - a[None]) * d[None]).sum(-1) / ll, 0, 1)
        dist = np.linalg.norm(a[None] + h[..., None] * d[None] - pts[:, None, :], axis=-1).min(axis=1)
        assert dist.max() <= tol * 1.0001


def test_border_segments_are_single_chords_and_not_sources():
    segs = np.array([[[0, 0], [0, 1], [0, 2], [0, 3]], [[0, 3], [1, 5], [2, 1], [3, 3]]], float)
    x0, y0, x1, y1, src = flatten(segs, np.array([True, False]), 0.01)
    assert src[0] == False and src[1:].all()  # noqa: E712
    assert (x0[0], y0[0], x1[0], y1[0]) == (0, 0, 0, 3)
    assert (x1[-1], y1[-1]) == (3, 3)


def test_twin_names_each_edges_segment():
    from isophote.geometry.flatten import contour_edges

    from conftest import channel_of, circle, square

    rng = np.random.default_rng(5)
    segs = random_segments(rng, 40)
    border = rng.random(40) < 0.3
    x0, y0, x1, y1, src, seg = flatten_ref(segs, border, 0.05, with_segment=True)
    assert np.array_equal(src, ~border[seg]) and np.all(np.diff(seg) >= 0)
    first = np.r_[True, seg[1:] != seg[:-1]]
    assert np.array_equal(np.column_stack([x0, y0])[first], segs[:, 0])
    # contour_edges: every segment cut by Wang's formula, each edge tagged with its contour
    ch = channel_of([circle(10.0, 10.0, 5.0)], [square(20.0, 2.0, 4.0)])
    e = contour_edges(ch, 0.05)
    assert np.all(np.diff(e[4]) >= 0) and set(e[4].tolist()) == {0, 1}
    assert np.sum(e[4] == 1) == 4  # the square's sides are straight: one chord each
