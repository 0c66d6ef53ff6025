"""The decoder's heart against its NumPy twins (render/_kernels/diffuse.py and diffuse_ref.py):
seed, region_caps, band_widths and evaluate on random small channels, every fill and distance
mode, at the nodes and at enlarged, shifted sample grids. Integers and infinities must agree
exactly, fill values within 1e-9 (float32 outputs: that is to the bit)."""

from __future__ import annotations

import numpy as np
import pytest

from isophote.render._kernels import diffuse, diffuse_ref
from isophote.render._kernels.diffuse import D, MODE_EUCLIDEAN, MODE_GEODESIC, MODE_MANHATTAN, SX, V
from isophote.render._kernels.raster import rasterise
from isophote.render._kernels.sharpen import correction

MODES = [MODE_EUCLIDEAN, MODE_MANHATTAN, MODE_GEODESIC]
MODE_IDS = ["euclidean", "manhattan", "geodesic"]


def random_channel(seed):
    """Wobbly loops of both orientations (peaks, pits, nested bands) on a small node grid:
    the edges, the node bands and crossings, levels and cap annotations."""
    rng = np.random.default_rng(seed)
    nr, nc = (int(v) for v in rng.integers(8, 20, size=2))
    loops = []
    for _ in range(int(rng.integers(2, 6))):
        k = int(rng.integers(5, 14))
        ang = np.sort(rng.uniform(0, 2 * np.pi, k))
        if rng.random() < 0.5:
            ang = ang[::-1]
        rad = rng.uniform(1.5, 0.6 * min(nr, nc), 1) * rng.uniform(0.6, 1.0, k)
        cx, cy = rng.uniform(0, nc), rng.uniform(0, nr)
        loops.append(np.column_stack([cx + rad * np.cos(ang), cy + rad * np.sin(ang)]))
    p = np.concatenate(loops)
    q = np.concatenate([np.roll(lp, -1, axis=0) for lp in loops])
    edges = (p[:, 0], p[:, 1], q[:, 0], q[:, 1])
    src = np.ones(len(p), bool)
    band, *h = rasterise(*edges, src, 0, 0, nr, nc, True)
    _, *v = rasterise(edges[1], edges[0], edges[3], edges[2], src, 0, 0, nc, nr, True, True)
    base = -int(band.min())
    band = (band + base).astype(np.int16)
    nl = int(band.max()) + int(rng.integers(0, 2))
    levels = np.sort(rng.uniform(0, 255, nl)) if nl else np.zeros(0)
    n_caps = int(rng.integers(0, 6))
    cap_x, cap_y = rng.uniform(0, nc, n_caps), rng.uniform(0, nr, n_caps)
    cap_band = band[np.floor(cap_y).astype(int), np.floor(cap_x).astype(int)].astype(np.int64)
    cap_value = rng.uniform(0, 255, n_caps)
    return dict(rng=rng, edges=edges, src=src, base=base, band=band, h=tuple(h), v=tuple(v), levels=levels,
                caps=(cap_x, cap_y, cap_band, cap_value), ramp=float(rng.choice([2.5, 6.0, np.inf])))


def assert_same(a, b):
    assert a.dtype == b.dtype and a.shape == b.shape
    assert np.array_equal(a, b, equal_nan=True), np.argwhere(~((a == b) | (np.isnan(a) & np.isnan(b))))[:5]


def node_fields(ch, mode):
    F = diffuse.seed(ch["band"], ch["h"], ch["v"], ch["levels"], mode)
    diffuse.propagate(F, ch["band"], diffuse.offsets(mode), mode, 1)
    labels, m = diffuse.label_nodes(ch["band"])
    dmax, capv = diffuse.region_caps(F, ch["band"], labels, m, *ch["caps"])
    bw = diffuse.band_widths(F, ch["band"], labels, dmax, capv, ch["ramp"])
    return F, labels, m, dmax, capv, bw


@pytest.mark.parametrize("seed", range(8))
@pytest.mark.parametrize("mode", MODES, ids=MODE_IDS)
def test_seed_matches_its_twin(seed, mode):
    ch = random_channel(100 + seed)
    fast = diffuse.seed(ch["band"], ch["h"], ch["v"], ch["levels"], mode)
    ref = diffuse_ref.seed(ch["band"], ch["h"], ch["v"], ch["levels"], mode)
    assert np.isfinite(fast[:, D]).any()
    assert_same(np.ascontiguousarray(fast), np.ascontiguousarray(ref))


@pytest.mark.parametrize("seed", range(8))
def test_region_caps_and_band_widths_match_their_twins(seed):
    ch = random_channel(200 + seed)
    F, labels, m, dmax, capv, bw = node_fields(ch, MODE_MANHATTAN)
    dmax_r, capv_r = diffuse_ref.region_caps(F, ch["band"], labels, m, *ch["caps"])
    assert_same(dmax, dmax_r)
    assert_same(capv, capv_r)
    assert_same(bw, diffuse_ref.band_widths(F, ch["band"], labels, dmax, capv, ch["ramp"]))


def test_region_caps_first_cap_of_a_region_wins():
    band = np.zeros((4, 4), np.int16)
    F = diffuse_ref.empty_fields(4, 4)
    F[0, D, 1, 1] = 2.5
    labels, m = diffuse.label_nodes(band)
    caps = (np.array([1.2, 2.7]), np.array([1.2, 2.7]), np.array([0, 0]), np.array([40.0, 90.0]))
    for fn in (diffuse.region_caps, diffuse_ref.region_caps):
        dmax, capv = fn(F, band, labels, m, *caps)
        assert dmax.tolist() == [[2.5, 0.0]] and capv.tolist() == [40.0]


def evaluate_both(ch, F, labels, dmax, capv, bw, tband, xs, ys, mode, flat, nv, smooth, corr):
    outs = []
    for fn in (diffuse.evaluate, diffuse_ref.evaluate):
        out = np.full(tband.shape, np.nan, np.float32)
        fn(F, ch["band"], labels, dmax, capv, ch["ramp"], tband, xs, ys, ch["levels"], mode, flat, nv, out,
           smooth, bw if smooth else np.zeros((0, 0, 2), np.float32), corr)
        outs.append(out)
    assert not np.isnan(outs[0]).any()
    np.testing.assert_allclose(outs[0], outs[1], rtol=0, atol=1e-9)
    return outs[0]


NONE = np.empty((0, 0), np.float32)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("mode", MODES, ids=MODE_IDS)
@pytest.mark.parametrize("smooth", [True, False], ids=["diffusion", "linear"])
def test_evaluate_matches_its_twin_at_the_nodes(seed, mode, smooth):
    ch = random_channel(300 + seed)
    F, labels, m, dmax, capv, bw = node_fields(ch, mode)
    nr, nc = ch["band"].shape
    evaluate_both(ch, F, labels, dmax, capv, bw, ch["band"], np.arange(nc) + 0.5, np.arange(nr) + 0.5, mode,
                  False, NONE, smooth, NONE)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("mode", MODES, ids=MODE_IDS)
@pytest.mark.parametrize("smooth", [True, False], ids=["diffusion", "linear"])
@pytest.mark.parametrize("sharpen", [False, True], ids=["plain", "sharpened"])
def test_evaluate_matches_its_twin_on_enlarged_shifted_samples(seed, mode, smooth, sharpen):
    """Samples k times finer than the nodes, shifted by a fraction of a sample: nodes, cells of
    one band (bilinear in nv), the frame's half-node rim and exact evaluation all occur."""
    ch = random_channel(400 + seed)
    F, labels, m, dmax, capv, bw = node_fields(ch, mode)
    band = ch["band"]
    nr, nc = band.shape
    nv = np.empty((nr, nc), np.float32)
    diffuse.evaluate(F, band, labels, dmax, capv, ch["ramp"], band, np.arange(nc) + 0.5, np.arange(nr) + 0.5,
                     ch["levels"], mode, False, NONE, nv, smooth, bw if smooth else np.zeros((0, 0, 2), np.float32),
                     NONE)
    corr = NONE
    if sharpen:
        corr, nv = correction(nv, 1, 0.4, 0.3)
    rng = ch["rng"]
    k = int(rng.integers(2, 5))
    off = float(rng.choice([0.0, 0.5 / k, 0.37]))
    x0, y0, x1, y1 = (e * k for e in ch["edges"])
    tband, *_ = rasterise(x0 - off * k, y0, x1 - off * k, y1, ch["src"], 0, 0, nr * k, nc * k, False)
    tband = tband + np.int16(ch["base"])
    xs = (np.arange(nc * k) + 0.5) / k + off
    ys = (np.arange(nr * k) + 0.5) / k
    evaluate_both(ch, F, labels, dmax, capv, bw, tband, xs, ys, mode, False, nv, smooth, corr)


def test_evaluate_flat_matches_its_twin_and_is_the_band_middle():
    ch = random_channel(7)
    F, labels, m, dmax, capv, bw = node_fields(ch, MODE_MANHATTAN)
    nr, nc = ch["band"].shape
    out = evaluate_both(ch, F, labels, dmax, capv, bw, ch["band"], np.arange(nc) + 0.5, np.arange(nr) + 0.5,
                        MODE_MANHATTAN, True, NONE, False, NONE)
    lv = ch["levels"]
    inner = (ch["band"] >= 1) & (ch["band"] < len(lv))
    b = ch["band"][inner].astype(int)
    assert np.allclose(out[inner], 0.5 * (lv[b - 1] + lv[b]))


def _coarse_fields(ch, k, mode):
    """The channel's fields rasterised at 1/k of its nodes a side (its edges scaled), with
    its own bands' base and levels: what blocks.ChannelLevel.coarse_field gives a level."""
    nr, nc = ch["band"].shape
    nrc, ncc = -(-nr // k), -(-nc // k)
    x0, y0, x1, y1 = (e / k for e in ch["edges"])
    band, *h = rasterise(x0, y0, x1, y1, ch["src"], 0, 0, nrc, ncc, True)
    _, *v = rasterise(y0, x0, y1, x1, ch["src"], 0, 0, ncc, nrc, True, True)
    band = (band + ch["base"]).astype(np.int16)
    Fc = diffuse.seed(band, tuple(h), tuple(v), ch["levels"], mode)
    diffuse.propagate(Fc, band, diffuse.offsets(mode), mode, 1)
    return Fc


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("mode", MODES, ids=MODE_IDS)
def test_offer_coarse_matches_its_twin_and_only_shortens(seed, mode):
    """A window (rows i0.., columns j0.. of a level) offered a coarse field's sources on its
    cut edges: kernel and twin agree exactly; only nodes on cut edges change, each to a
    nearer source of the same side, at the level that side has in the node's band."""
    ch = random_channel(300 + seed)
    rng = ch["rng"]
    k = int(rng.choice([2, 4]))
    Fc = _coarse_fields(ch, k, mode)
    i0, j0 = int(rng.integers(0, 4)), int(rng.integers(0, 4))
    band = np.ascontiguousarray(ch["band"][i0:, j0:])
    # the level's seeded fields, cut to the window (node-major storage, as seed makes them)
    full = diffuse.seed(ch["band"], ch["h"], ch["v"], ch["levels"], mode).transpose((2, 3, 0, 1))
    F = np.ascontiguousarray(full[i0:, j0:]).transpose((2, 3, 0, 1))
    before = F.copy()
    cuts = np.array([1, 1, 1, 1]) if seed % 2 else rng.integers(0, 2, 4)
    ref = diffuse_ref.offer_coarse(F, band, ch["levels"], Fc, k, i0, j0, cuts, mode)
    diffuse.offer_coarse(F, band, ch["levels"], Fc, k, i0, j0, cuts, mode)
    assert_same(np.ascontiguousarray(F), np.ascontiguousarray(ref))
    changed = (F[:, D] != before[:, D])
    assert (F[:, D] <= before[:, D]).all()
    edge = np.zeros(band.shape, bool)
    for c, sl in zip(cuts, ((0, slice(None)), (-1, slice(None)), (slice(None), 0), (slice(None), -1))):
        if c:
            edge[sl] = True
    assert not (changed & ~edge).any()
    nl = len(ch["levels"])
    for s in range(2):
        i, j = np.nonzero(changed[s])
        lv = band[i, j].astype(int) - 1 + s
        assert ((lv >= 0) & (lv < nl)).all() and np.array_equal(F[s, V, i, j], ch["levels"][lv].astype(np.float32))
    # fields with no source yet take every coarse source offered them: on the cut edges,
    # exactly the nodes whose coarse node has one at the level of that side of their band
    empty = diffuse_ref.empty_fields(*band.shape)
    diffuse.offer_coarse(empty, band, ch["levels"], Fc, k, i0, j0, cuts, mode)
    ii, jj = np.indices(band.shape)
    ci = np.minimum((i0 + ii + 0.5) // k, Fc.shape[2] - 1).astype(int)
    cj = np.minimum((j0 + jj + 0.5) // k, Fc.shape[3] - 1).astype(int)
    for s in range(2):
        lv = band.astype(int) - 1 + s
        fit = (lv >= 0) & (lv < nl)
        want = np.where(fit, ch["levels"][np.clip(lv, 0, max(nl - 1, 0))] if nl else 0, np.nan).astype(np.float32)
        expect = edge & fit & np.isfinite(Fc[s, D, ci, cj]) & (Fc[s, V, ci, cj] == want)
        assert np.array_equal(np.isfinite(empty[s, D]), expect)
        assert np.allclose(empty[s, SX][expect], Fc[s, SX, ci, cj][expect] * k - j0)
