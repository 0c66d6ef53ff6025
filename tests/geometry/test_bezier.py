"""Evaluation and de Casteljau subdivision (geometry/bezier.py)."""

import numpy as np

from isophote.geometry import evaluate, evaluate_grid, map_cubics, split, subsegment


def random_cubics(n, seed=0):
    return np.random.default_rng(seed).uniform(-20, 20, (n, 4, 2))


def test_evaluate_ends_and_grid():
    s = random_cubics(30)
    assert np.array_equal(evaluate(s, np.zeros(30)), s[:, 0])
    assert np.array_equal(evaluate(s, np.ones(30)), s[:, 3])
    ts = np.linspace(0, 1, 9)
    grid = evaluate_grid(s, ts)
    for j, t in enumerate(ts):
        assert np.allclose(grid[:, j], evaluate(s, np.full(30, t)), atol=1e-12)
    # the midpoint by hand: (P0 + 3 P1 + 3 P2 + P3) / 8
    assert np.allclose(evaluate(s, np.full(30, 0.5)), (s[:, 0] + 3 * s[:, 1] + 3 * s[:, 2] + s[:, 3]) / 8)


def test_split_reproduces_the_curve():
    s = random_cubics(40, 1)
    t = np.random.default_rng(2).uniform(0.05, 0.95, 40)
    left, right = split(s, t)
    assert np.allclose(left[:, 3], right[:, 0], atol=1e-12)
    for u in np.linspace(0, 1, 11):
        uu = np.full(40, u)
        assert np.allclose(evaluate(left, uu), evaluate(s, t * u), atol=1e-11)
        assert np.allclose(evaluate(right, uu), evaluate(s, t + (1 - t) * u), atol=1e-11)


def test_subsegment_of_the_whole_is_the_curve():
    s = random_cubics(10, 3)
    assert np.allclose(subsegment(s, np.zeros(10), np.ones(10)), s, atol=1e-12)
    piece = subsegment(s, np.full(10, 0.2), np.full(10, 0.7))
    for u in (0.0, 0.3, 1.0):
        assert np.allclose(evaluate(piece, np.full(10, u)), evaluate(s, np.full(10, 0.2 + 0.5 * u)), atol=1e-11)


def test_map_cubics_affine_is_exact_and_bent_maps_subdivide():
    s = random_cubics(20, 4)
    border = np.zeros(20, bool)
    m = np.array([[1.5, 0.2], [-0.3, 0.8]])

    def affine(p):
        return p @ m.T + 1.0

    def jac(p):
        return np.broadcast_to(m, (len(p), 2, 2))

    new, nb, src = map_cubics(s, border, affine, jac, 1e-9, 18)
    assert np.array_equal(src, np.arange(20))  # one piece each: the Hermite image is exact
    assert np.allclose(new, affine(s.reshape(-1, 2)).reshape(-1, 4, 2), atol=1e-9)

    def bend(p):
        return np.column_stack([p[:, 0], p[:, 1] + 0.01 * p[:, 0] ** 2])

    def bend_jac(p):
        j = np.zeros((len(p), 2, 2))
        j[:, 0, 0] = j[:, 1, 1] = 1.0
        j[:, 1, 0] = 0.02 * p[:, 0]
        return j

    new, nb, src = map_cubics(s, border, bend, bend_jac, 0.01, 18)
    assert len(new) > 20 and np.all(np.diff(src) >= 0)
    for k in range(20):
        pieces = new[src == k]
        assert np.allclose(pieces[1:, 0], pieces[:-1, 3])  # joined, in order
        # every piece within the tolerance of the mapped curve, between the probes too
        exact = bend(evaluate(np.repeat(s[k][None], 4000, 0), np.linspace(0, 1, 4000)))
        step = np.hypot(*np.diff(exact, axis=0).T).max()
        got = evaluate(pieces, np.full(len(pieces), 0.375))
        d = np.sqrt(((got[:, None] - exact[None]) ** 2).sum(-1)).min(axis=1)
        assert d.max() <= 0.01 + step / 2, (k, d.max(), step)
