"""Tests of the Bezier chain fitter (encoder/fit.py, paper §3.3).

Error bounds are checked with chain_distance (dense sampling of the curve), never with the
fitter's own estimate.
"""

import math

import numpy as np
import pytest

from isophote.encoder._kernels.fit_ref import fit_polyline as fit_polyline_ref
from isophote.encoder.fit import chain_distance, fit_many, fit_polyline

# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------


def n_segments(chain):
    return (len(chain) - 1) // 3


def sample_chain(chain, per_segment=100):
    """(m, per_segment + 1, 2) points of each segment at uniform parameters."""
    m = n_segments(chain)
    t = np.linspace(0.0, 1.0, per_segment + 1)[None, :, None]
    b = np.stack([chain[3 * g : 3 * g + 4] for g in range(m)])[:, :, None, :]
    s = 1.0 - t
    return s**3 * b[:, 0] + 3 * s**2 * t * b[:, 1] + 3 * s * t**2 * b[:, 2] + t**3 * b[:, 3]


def polyline_distance(x, poly):
    """Distance from each point of x (k, 2) to the polyline poly (n, 2)."""
    a, b = poly[:-1], poly[1:]
    e = b - a
    ll = np.sum(e * e, axis=1)
    w = x[:, None, :] - a[None]
    h = np.clip(np.sum(w * e[None], axis=2) / np.where(ll > 0, ll, 1.0), 0.0, 1.0)
    d = w - h[..., None] * e[None]
    return np.sqrt(np.min(np.sum(d * d, axis=2), axis=1))


def joint_angles(chain, closed):
    """Angle in degrees between incoming and outgoing handle at each joint (nan if a
    handle has zero length); interior joints, then the closing one for closed chains."""
    m = n_segments(chain)
    idx = [3 * g for g in range(1, m)] + ([0] if closed else [])
    out = []
    for r in idx:
        p = chain[r]
        din = p - chain[r - 1] if r > 0 else p - chain[-2]
        dout = chain[r + 1] - p
        li, lo = np.hypot(*din), np.hypot(*dout)
        if li == 0 or lo == 0:
            out.append(np.nan)
            continue
        c = np.clip(din @ dout / (li * lo), -1.0, 1.0)
        out.append(math.degrees(math.acos(c)))
    return np.array(out)


def check_chain(points, tol, closed, chain, bulge_eps=1e-9, samples=200, joints=None):
    """The fitter's guarantees, checked independently (``samples``: chain_distance's, more
    for chains with very long segments, whose sparse samples overestimate distances;
    ``joints``: where each point goes when it is a joint, the points themselves if None)."""
    assert chain.dtype == np.float64 and chain.ndim == 2 and chain.shape[1] == 2
    assert (len(chain) - 1) % 3 == 0 and len(chain) >= 4
    assert np.all(np.isfinite(chain))
    joints = points if joints is None else joints
    if closed:
        assert np.array_equal(chain[-1], chain[0])
        s = int(np.flatnonzero(np.all(joints == chain[0], axis=1))[0])
        q = np.concatenate([np.roll(points, -s, axis=0), points[s : s + 1]])
        t = np.concatenate([np.roll(tol, -s), tol[s : s + 1]])
        qj = np.concatenate([np.roll(joints, -s, axis=0), joints[s : s + 1]])
    else:
        assert np.array_equal(chain[0], joints[0]) and np.array_equal(chain[-1], joints[-1])
        q, t, qj = points, tol, joints
    # every point within its tolerance of the curve
    d = chain_distance(chain, points, samples)
    assert np.all(d <= tol * (1 + 1e-9) + 1e-12), (d / tol).max()
    # joints are input points, in order; each segment's curve stays within the largest
    # tolerance of its span of the polyline. A joint on a run of repeated points may be any
    # of them: take the span over the runs.
    first, last = [0], [0]
    m = n_segments(chain)
    for g in range(1, m):
        hit = np.flatnonzero(np.all(qj[first[-1] + 1 : -1] == chain[3 * g], axis=1))
        assert len(hit), "joint is not an input point"
        a = b = first[-1] + 1 + int(hit[0])
        while b + 1 < len(q) - 1 and np.array_equal(qj[b + 1], qj[a]):
            b += 1
        first.append(a)
        last.append(b)
    assert np.array_equal(chain[-1], qj[-1])
    first.append(len(q) - 1)
    last.append(len(q) - 1)
    curve = sample_chain(chain)
    for g in range(m):
        i, j = first[g], last[g + 1]
        dd = polyline_distance(curve[g], q[i : j + 1])
        assert dd.max() <= t[i : j + 1].max() + bulge_eps, (g, dd.max(), t[i : j + 1].max())


def circle(r, spacing, centre=(50.0, 40.0)):
    n = int(round(2 * np.pi * r / spacing))
    th = np.arange(n) * (2 * np.pi / n)
    return np.stack([centre[0] + r * np.cos(th), centre[1] + r * np.sin(th)], axis=1)


def random_curve(rng, closed):
    """A smooth random curve sampled about every 0.5 px with a little noise, and smooth
    per-point tolerances in 0.05..0.5 (what the isoline tracer gives)."""
    n = int(rng.integers(5, 200))
    if closed:
        th = np.linspace(0, 2 * np.pi, n, endpoint=False)
        r = rng.uniform(1, 12) * (1 + sum(rng.normal(0, 0.15) * np.cos(k * th + rng.uniform(0, 6))
                                          for k in range(1, 5)))
        pts = np.stack([r * np.cos(th), r * np.sin(th)], axis=1)
    else:
        turn = np.cumsum(rng.normal(0, 0.15, n))
        step = rng.uniform(0.2, 0.8, n)
        pts = np.cumsum(np.stack([step * np.cos(turn), step * np.sin(turn)], axis=1), axis=0)
    pts = pts + rng.normal(0, 0.02, pts.shape) + rng.uniform(0, 100, 2)
    tol = np.clip(0.05 + 0.45 * np.abs(np.sin(np.linspace(0, rng.uniform(0, 6), n)
                                              + rng.uniform(0, 6))) ** 3, 0.05, 0.5)
    return pts, tol


# ---------------------------------------------------------------------------------------
# known answers
# ---------------------------------------------------------------------------------------


def test_circle_gives_few_segments_within_tolerance():
    pts = circle(20.0, 0.5)
    tol = np.full(len(pts), 0.05)
    chain = fit_polyline(pts, tol, closed=True)
    assert 3 <= n_segments(chain) <= 8  # a cubic spans 120 degrees of it within 0.03
    check_chain(pts, tol, True, chain)
    r = np.hypot(*(sample_chain(chain, 400).reshape(-1, 2) - (50.0, 40.0)).T)
    assert np.all(np.abs(r - 20.0) <= 0.05 + 1e-3)


def test_straight_line_is_one_segment():
    pts = np.stack([np.linspace(3, 40, 100), np.linspace(-2, 7, 100)], axis=1)
    tol = np.full(100, 0.05)
    chain = fit_polyline(pts, tol, closed=False)
    assert n_segments(chain) == 1
    check_chain(pts, tol, False, chain)


def test_exact_cubic_is_one_segment():
    b = np.array([[0.0, 0.0], [10.0, 25.0], [30.0, -10.0], [40.0, 10.0]])
    t = np.linspace(0, 1, 120)[:, None] ** 1.3  # not chord-length spaced
    pts = (1 - t) ** 3 * b[0] + 3 * (1 - t) ** 2 * t * b[1] + 3 * (1 - t) * t**2 * b[2] + t**3 * b[3]
    tol = np.full(len(pts), 0.05)
    chain = fit_polyline(pts, tol, closed=False)
    assert n_segments(chain) == 1
    check_chain(pts, tol, False, chain)


def test_two_points_give_the_straight_segment():
    pts = np.array([[1.0, 2.0], [4.0, 8.0]])
    chain = fit_polyline(pts, np.array([0.1, 0.1]), closed=False)
    np.testing.assert_allclose(chain, [[1, 2], [2, 4], [3, 6], [4, 8]], rtol=0, atol=1e-12)
    assert np.array_equal(chain[0], pts[0]) and np.array_equal(chain[-1], pts[1])


def test_noisy_circle_more_tolerance_fewer_segments():
    rng = np.random.default_rng(7)
    pts = circle(15.0, 0.5)
    pts = pts + rng.uniform(-0.04, 0.04, pts.shape)
    counts = []
    for t in (0.05, 0.2, 0.5, 1.0):
        tol = np.full(len(pts), t)
        chain = fit_polyline(pts, tol, closed=True)
        check_chain(pts, tol, True, chain)
        counts.append(n_segments(chain))
    assert all(a >= b for a, b in zip(counts, counts[1:])), counts
    assert counts[0] > counts[-1]


# ---------------------------------------------------------------------------------------
# degenerate input
# ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("closed", [False, True])
def test_duplicate_points_stay_finite(closed):
    pts = np.array([[0, 0], [0, 0], [1, 0], [1, 0], [1, 0], [2, 1], [2, 1], [1, 2], [1, 2.0]])
    tol = np.full(len(pts), 0.1)
    chain = fit_polyline(pts, tol, closed)
    check_chain(pts, tol, closed, chain)
    same = np.zeros((6, 2)) + 3.0
    chain = fit_polyline(same, np.full(6, 0.1), closed)
    assert np.all(np.isfinite(chain))
    np.testing.assert_allclose(chain, 3.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("pts", [
    [[10.5, 10.0], [11.0, 10.5], [10.5, 11.0]],
    [[10.5, 10.0], [11.0, 10.5], [10.5, 11.0], [10.0, 10.5]],
    [[10.5, 10.2], [10.8, 10.5], [10.5, 10.8], [10.2, 10.5]],
])
def test_tiny_closed_loops(pts):
    pts = np.array(pts)
    for t in (0.05, 0.5):
        tol = np.full(len(pts), t)
        check_chain(pts, tol, True, fit_polyline(pts, tol, True))


def test_bad_arguments_raise():
    with pytest.raises(ValueError):
        fit_polyline(np.zeros((2, 2)), np.ones(2), closed=True)
    with pytest.raises(ValueError):
        fit_polyline(np.zeros((1, 2)), np.ones(1), closed=False)
    with pytest.raises(ValueError):
        fit_polyline(np.zeros((3, 2)), np.array([1.0, 0.0, 1.0]), closed=False)
    with pytest.raises(ValueError):
        fit_polyline(np.array([[0, 0], [np.nan, 1]]), np.ones(2), closed=False)
    with pytest.raises(ValueError):
        fit_polyline(np.zeros((3, 2)), np.ones(3), closed=False, snap=90)
    with pytest.raises(ValueError):
        fit_many(np.zeros((4, 2)), np.ones(4), [0, 2, 3], [False, False])
    with pytest.raises(ValueError):
        fit_many(np.zeros((4, 2)), np.ones(4), [0, 4], [False, False])


# ---------------------------------------------------------------------------------------
# guarantees on random curves
# ---------------------------------------------------------------------------------------


def random_batch(seed, count):
    rng = np.random.default_rng(seed)
    polys = []
    for _ in range(count):
        closed = bool(rng.integers(0, 2))
        pts, tol = random_curve(rng, closed)
        polys.append((pts, tol, closed))
    return polys


@pytest.mark.parametrize("snap", [0.0, 20.0, 45.0])
def test_random_curves_within_ribbon(snap):
    for pts, tol, closed in random_batch(1, 40):
        check_chain(pts, tol, closed, fit_polyline(pts, tol, closed, snap=snap))


def test_coarse_handles_stay_in_the_ribbon_and_on_their_grids():
    """coarsen = 5: the handles move onto the file's coarse grids (the residual against the
    straight segment's thirds, in the chord's frame, a multiple of 2**sh / 64 px, sh <= 5,
    the anchors rounded to 1/64 px) where the segment still fits, the chain keeps every
    guarantee and its joints, most segments get a coarse grid, and the kernel equals its
    twin."""
    from isophote.format._coder.entropy_ref import chord_frame, rnd3, to_frame

    shifts = []
    for pts, tol, closed in random_batch(11, 40):
        pts = np.round(pts * 64) / 64  # anchors on the 1/64 grid, as the encoder's rounding leaves them
        chain = fit_polyline(pts, tol, closed, coarsen=5)
        check_chain(pts, tol, closed, chain, samples=2000)  # batch 11 has a loop-long segment
        ref = fit_polyline_ref(pts, tol, closed, math.cos(math.radians(20.0)), coarsen=5)
        np.testing.assert_allclose(chain, ref, rtol=1e-9, atol=1e-9)
        assert n_segments(chain) == n_segments(fit_polyline(pts, tol, closed))  # the same joints
        p = np.rint(chain * 64).astype(np.int64)  # as the encoder rounds (a segment no
        # coarse grid fits keeps its handles, rounded to 1/64 px there)
        for g in range(n_segments(chain)):
            a, ca, cb, b = (p[3 * g + k] for k in range(4))
            d = b - a
            fr = chord_frame(int(d[0]), int(d[1]))
            h = to_frame(fr, int(ca[0] - a[0] - rnd3(int(d[0]))), int(ca[1] - a[1] - rnd3(int(d[1]))))
            r = to_frame(fr, int(cb[0] - b[0] + rnd3(int(d[0]))), int(cb[1] - b[1] + rnd3(int(d[1]))))
            low = h[0] | h[1] | r[0] | r[1]
            shifts.append(min(5, (low & -low).bit_length() - 1) if low else 5)
    shifts = np.array(shifts)
    assert np.mean(shifts >= 3) > 0.5, np.bincount(shifts)


def handles_on_file_grid(chain):
    """(segments,) bool: both handles of each segment lie on the 1/64 px grid."""
    handles = np.delete(chain, np.s_[::3], axis=0).reshape(-1, 2, 2)
    return np.all(handles * 64 == np.floor(handles * 64), axis=(1, 2))


def test_file_grid_keeps_the_whole_ribbon():
    """coarsen > 0 on points off the 1/64 px grid: every joint is its point rounded to that
    grid, nearly every segment's handles lie on it too (found there by the fitter, which
    checks them, rather than rounded afterwards), the chain keeps every guarantee with the
    tolerances as given (the encoder no longer shrinks them by the rounding), and the
    kernel equals its twin."""
    segments = off_grid = 0
    for pts, tol, closed in random_batch(12, 40):
        chain = fit_polyline(pts, tol, closed, coarsen=5)
        joints = np.floor(pts * 64 + 0.5) / 64
        check_chain(pts, tol, closed, chain, samples=2000, joints=joints)
        ref = fit_polyline_ref(pts, tol, closed, math.cos(math.radians(20.0)), coarsen=5)
        np.testing.assert_allclose(chain, ref, rtol=1e-9, atol=1e-9)
        assert np.array_equal(chain[::3] * 64, np.floor(chain[::3] * 64))
        on = handles_on_file_grid(chain)
        segments += on.size
        off_grid += int(np.sum(~on))
        if on.all():  # the file's rounding changes nothing: the stored chain is this one
            assert np.array_equal(np.round(chain * 64) / 64, chain)
    assert off_grid <= 0.01 * segments, (off_grid, segments)
    assert segments > 200


def test_file_grid_on_narrow_ribbons_matches_its_twin():
    """Ribbons of 0.015-0.15 px, where rounding to 1/64 px often takes a segment out of its
    ribbon, so the other roundings and the segments that keep their handles are exercised:
    the kernel still equals its twin, the chains keep every guarantee, and few segments
    are left off the grid."""
    segments = off_grid = 0
    for pts, tol, closed in random_batch(31, 40):
        tol = 0.3 * tol
        chain = fit_polyline(pts, tol, closed, coarsen=5)
        check_chain(pts, tol, closed, chain, samples=2000, joints=np.floor(pts * 64 + 0.5) / 64)
        ref = fit_polyline_ref(pts, tol, closed, math.cos(math.radians(20.0)), coarsen=5)
        np.testing.assert_allclose(chain, ref, rtol=1e-9, atol=1e-9)
        on = handles_on_file_grid(chain)
        segments += on.size
        off_grid += int(np.sum(~on))
    assert 0 < off_grid <= 0.02 * segments, (off_grid, segments)


def grid_joints(pts, tol, closed, grid, reach=0.75):
    """Where the anchor grid rule puts each point as a joint, written out point by point:
    x onto the nearest multiple of grid if that is within reach * tol, then y if the move
    in both stays within it; the ends of an open polyline stay."""
    out = pts.copy()
    for k in range(len(pts)):
        if not closed and k in (0, len(pts) - 1):
            continue
        lim = reach * tol[k]
        gx = np.floor(pts[k, 0] / grid + 0.5) * grid
        gy = np.floor(pts[k, 1] / grid + 0.5) * grid
        dx = gx - pts[k, 0] if abs(gx - pts[k, 0]) <= lim else 0.0
        if dx:
            out[k, 0] = gx
        if math.hypot(dx, gy - pts[k, 1]) <= lim:
            out[k, 1] = gy
    return out


def crossings_batch(seed, count):
    """Random curves as the isoline tracer gives them: every point on a line of the 0.5 px
    sample grid in one coordinate (the curve's crossings of those lines), ribbons 0.05-0.5."""
    out = []
    for pts, tol, closed in random_batch(seed, count):
        k = np.arange(len(pts)) % 2
        pts[np.arange(len(pts)), k] = np.round(pts[np.arange(len(pts)), k] * 2) / 2
        out.append((pts, tol, closed))
    return out


def test_joints_move_onto_the_anchor_grid_within_reach():
    """anchor_grid = 0.5: each joint is its point moved onto the grid in the coordinates
    within 0.75 of its tolerance of it (the ends of open polylines stay), the chain keeps
    every guarantee with those joints, joints on the sample grid in both coordinates become
    common, and the kernel equals its twin."""
    on_grid = [0, 0]
    for pts, tol, closed in crossings_batch(21, 40):
        joints = grid_joints(pts, tol, closed, 0.5)
        moved = np.hypot(*(joints - pts).T)
        assert np.all(moved <= 0.75 * tol + 1e-12)
        for which, grid in enumerate((0.0, 0.5)):
            chain = fit_polyline(pts, tol, closed, anchor_grid=grid)
            check_chain(pts, tol, closed, chain, samples=2000, joints=joints if grid else None)
            a = chain[:-1:3]
            on_grid[which] += int(np.sum(np.all(a * 2 == np.floor(a * 2), axis=1)))
            if grid:
                ref = fit_polyline_ref(pts, tol, closed, math.cos(math.radians(20.0)), anchor_grid=grid,
                                       reach=0.75 * tol)
                np.testing.assert_allclose(chain, ref, rtol=1e-9, atol=1e-9)
    assert on_grid[1] > 4 * on_grid[0] + 50, on_grid
    with pytest.raises(ValueError):
        fit_polyline(pts, tol, closed, anchor_grid=-0.5)
    with pytest.raises(ValueError):
        fit_many(pts, tol, [0, len(pts)], [closed], anchor_grid=float("nan"))
    for bad in (1.5 * tol, -0.1 * tol, tol[:-1]):
        with pytest.raises(ValueError):
            fit_polyline(pts, tol, closed, anchor_grid=0.5, reach=bad)


def wild_polyline(rng):
    """Points with no smooth curve behind them: uniform in a box (on a coarse grid, so
    with collinear runs) or a rough random walk, sometimes with a repeated point. Like
    isolines, they never come back to an earlier position."""
    closed = bool(rng.integers(0, 2))
    while True:
        n = int(rng.integers(3 if closed else 2, 14))
        if rng.random() < 0.6:
            pts = np.round(rng.uniform(0, 10 ** rng.uniform(-1, 1.5), (n, 2)), 2)
        else:
            pts = np.cumsum(rng.normal(0, 0.5, (n, 2)), axis=0)
        if n > 2 and rng.random() < 0.2:
            k = int(rng.integers(1, n))
            pts[k] = pts[k - 1]
        # keep only polylines whose repeated positions are consecutive (cyclically if closed)
        key = [tuple(p) for p in pts]
        runs = [key[0]] + [b for a, b in zip(key, key[1:]) if a != b]
        if closed and len(runs) > 1 and runs[0] == runs[-1]:
            runs.pop()
        if len(set(runs)) == len(runs):
            break
    tol = rng.uniform(0.01, 1.0, n) if rng.random() < 0.5 else np.full(n, rng.uniform(0.01, 1))
    return pts, tol, closed


def test_wild_polylines_within_ribbon():
    rng = np.random.default_rng(6)
    for _ in range(150):
        pts, tol, closed = wild_polyline(rng)
        snap = float(rng.choice([0.0, 20.0, 60.0]))
        check_chain(pts, tol, closed, fit_polyline(pts, tol, closed, snap=snap))


def test_snapping_aligns_joints_and_keeps_tolerance():
    snapped = 0
    # 80 curves: the no-backtracking rule declines some snaps, so the sample is larger
    for pts, tol, closed in random_batch(2, 80):
        raw = fit_polyline(pts, tol, closed, snap=0.0)
        chain = fit_polyline(pts, tol, closed, snap=20.0)
        check_chain(pts, tol, closed, chain)
        # snapping moves handles, never joints
        assert chain.shape == raw.shape and np.array_equal(chain[::3], raw[::3])
        a0, a1 = joint_angles(raw, closed), joint_angles(chain, closed)
        for before, after in zip(a0, a1):
            if before < 20.0 and not after == before:
                assert after < 1e-5  # acos of a rounded 1.0
                snapped += 1
            elif not before < 20.0:
                assert after == before or np.isnan(before)
    assert snapped > 10


def test_fit_many_equals_fit_polyline():
    polys = random_batch(3, 30)
    pts = np.concatenate([p for p, _, _ in polys])
    tol = np.concatenate([t for _, t, _ in polys])
    offsets = np.concatenate([[0], np.cumsum([len(p) for p, _, _ in polys])])
    closed = np.array([c for _, _, c in polys])
    chains, co = fit_many(pts, tol, offsets, closed)
    assert co.dtype == np.int64 and co.shape == (len(polys) + 1,) and co[-1] == len(chains)
    for k, (p, t, c) in enumerate(polys):
        assert np.array_equal(chains[co[k] : co[k + 1]], fit_polyline(p, t, c))
    empty, eo = fit_many(np.zeros((0, 2)), np.zeros(0), [0], np.zeros(0, bool))
    assert empty.shape == (0, 2) and np.array_equal(eo, [0])


def test_deterministic():
    polys = random_batch(4, 10)
    for p, t, c in polys:
        assert fit_polyline(p, t, c).tobytes() == fit_polyline(p.copy(), t.copy(), c).tobytes()


@pytest.mark.parametrize("workers", [1, 2, 3, 8])
def test_fit_many_same_bytes_on_any_number_of_threads(monkeypatch, workers):
    """Large batches are fitted in groups on threads; the output does not depend on them."""
    import isophote.encoder.fit as fit_mod

    polys = random_batch(6, 200)
    pts = np.concatenate([p for p, _, _ in polys])
    tol = np.concatenate([t for _, t, _ in polys])
    offsets = np.concatenate([[0], np.cumsum([len(p) for p, _, _ in polys])])
    closed = np.array([c for _, _, c in polys])
    monkeypatch.setattr(fit_mod, "PARALLEL_POINTS", len(pts) + 1)
    serial = fit_many(pts, tol, offsets, closed)
    monkeypatch.setattr(fit_mod, "PARALLEL_POINTS", 0)
    monkeypatch.setattr(fit_mod, "_workers", lambda: workers)
    chains, co = fit_many(pts, tol, offsets, closed)
    assert chains.tobytes() == serial[0].tobytes() and np.array_equal(co, serial[1])
    assert co.dtype == np.int64
    for k in (0, 57, 199):
        p, t, c = polys[k]
        assert np.array_equal(chains[co[k] : co[k + 1]], fit_polyline(p, t, c))


@pytest.mark.parametrize("snap", [0.0, 20.0])
def test_kernel_matches_reference(snap):
    cos_snap = math.cos(math.radians(snap)) if snap > 0 else 1.0
    rng = np.random.default_rng(8)
    polys = random_batch(5, 12) + [wild_polyline(rng) for _ in range(30)]
    for p, t, c in polys:
        fast = fit_polyline(p, t, c, snap=snap)
        ref = fit_polyline_ref(p, t, c, cos_snap)
        assert fast.shape == ref.shape
        np.testing.assert_allclose(fast, ref, rtol=1e-9, atol=1e-9)


# ---------------------------------------------------------------------------------------
# chain_distance
# ---------------------------------------------------------------------------------------


def test_chain_distance_known_values():
    line = np.array([[0.0, 0.0], [10 / 3, 0.0], [20 / 3, 0.0], [10.0, 0.0]])
    d = chain_distance(line, [[5.0, 3.0], [-4.0, 3.0], [10.0, 0.0], [2.345, -0.5]])
    np.testing.assert_allclose(d, [3.0, 5.0, 0.0, 0.5], atol=1e-9)
    # quarter circles (kappa = 0.5523) approximate radius 10 within 0.03 %
    k = 0.5522847498 * 10
    quarter = np.array([[10, 0], [10, k], [k, 10], [0, 10.0]])
    th = np.linspace(0, np.pi / 2, 50)
    on = np.stack([10 * np.cos(th), 10 * np.sin(th)], axis=1)
    assert chain_distance(quarter, on).max() < 10 * 3e-4
    np.testing.assert_allclose(chain_distance(quarter, 2 * on), 10.0, atol=10 * 3e-4)
