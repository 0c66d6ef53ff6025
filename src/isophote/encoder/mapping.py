"""Pixel mapping (§3.2): the Carrato 2x grid the contour finder works on.

Grid layout
    Grid sample (r, c) sits at image position (x, y) = (c / 2, r / 2): every pixel centre
    (j + 0.5, i + 0.5) is grid sample (2i + 1, 2j + 1), the samples between two pixel
    centres are Carrato interpolants, and the outermost ring (x = 0, x = W, y = 0, y = H)
    repeats its neighbours so that the grid covers the whole image [0, W] x [0, H].
    A W x H image gives a (2H + 1, 2W + 1) grid; each pixel's 2 x 2 "map" of §3.2 is the
    four cells around its centre.

Carrato formula (Carrato, Ramponi, Marsi 1996), in x (y likewise)::

    phi[x + 1/2] = phi[x] + (k1 + 1) / (k2 + 2) * D[x]
    k1 = p * D[x - 1]**2,   k2 = p * (D[x - 1]**2 + D[x + 1]**2),   D[x] = phi[x + 1] - phi[x]

The weight tends to 1 (the new sample takes its right neighbour's value) when the left
difference dominates, and to 0 when the right one does: transitions are pushed towards the
side with the edge, which sharpens edges and resolves the centre ambiguity of marching squares.

Intensity scale
    The k are dimensionless only once D is measured in some unit. We measure D in units of
    ``scale`` grey levels (default 64, so D = 1 is a 64-level step): p = 0.5 then leaves
    smooth gradients (D << 1) interpolated linearly and bends only strong edges. The default
    was chosen by prediction error (benchmarks/carrato_scale.py): decimate the five corpus
    photographs 2x, predict the dropped samples, compare. Mean RMS error: linear 9.19,
    unit 1 11.12, unit 16 9.81, unit 32 9.36, unit 64 9.16 (best), unit 255 9.17 grey levels
    (on the linear base; on the cubic base below: p = 0 9.14, unit 64 9.05).
    Smaller units (the raw 0..255 scale, where p = 0.5 saturates on every texture) over-sharpen.

Cubic base (our change to §3.2)
    The formula above bends the LINEAR midpoint phi[x] + D[x] / 2. We add the cubic term of
    Catmull-Rom interpolation, - cubic * (D[x + 1] - D[x - 1]) / 16, so that at cubic = 1 a
    smooth signal gets the cubic midpoint (-phi[x-1] + 9 phi[x] + 9 phi[x+1] - phi[x+2]) / 16
    and an edge still gets Carrato's push; the result is then clamped between phi[x] and
    phi[x + 1], as Carrato's own formula always is, so the grid has no extremum the pixels do
    not have (no new loops, and pruning stays effective). Where the contours run between the
    samples decides how renders look between them. Astronaut, paper preset, 1x (PSNR /
    SSIMULACRA2 / FLIP, .isoph bytes): linear base 39.83 / 77.39 / 0.0435, 910,289; clamped
    cubic 40.08 / 77.63 / 0.0424, 875,279 (4 % fewer segments). Unclamped, the overshoot
    sharpened photographs further (40.35 / 77.90 / 0.0416) but rang round hard edges: the
    flat surround of a synthetic disc came back 2.4 grey levels off. carrato_cubic = 0 gives
    the paper's formula exactly.

    The default weight is 2: the midpoint of Keys' cubic with a = -1,
    (-phi[x-1] + 5 phi[x] + 5 phi[x+1] - phi[x+2]) / 8, a sharper kernel than Catmull-Rom's
    a = -0.5 (weight 1; 1.5 is a = -0.75). A camera's pixels average the light over their
    area, and against that model the sharper kernel does better between the samples: on the
    corpus box-downsampled 4x, encoded with high and rendered back at 4x, weight 1 gives
    26.92 dB / SSIMULACRA2 20.8 and weight 2 gives 27.06 / 23.7; the warps of
    benchmarks/apply.py gain 0.2 dB (high: rotation 36.31 -> 36.55, perspective
    36.89 -> 37.10, swirl 38.21 -> 38.42). At 1x it is neutral (corpus, balanced: 41.67 and
    41.64 dB, SSIMULACRA2 82.46 and 82.48, bytes within 0.1 %). Predicting the samples that
    point decimation drops (benchmarks/carrato_scale.py, which has no area averaging) prefers
    weight 1 slightly: 9.05 against 9.17 grey levels RMS.

Errors (§3.2)
    Each original sample has error eps. An interpolant's error is half the spread of the
    formula over the limiting inputs: the differences D +- (|eps_a| + |eps_b|) and phi[x] +- eps;
    the cubic term adds cubic / 16 times the error bounds of D[x - 1] and D[x + 1].
"""

from __future__ import annotations

import itertools

import numpy as np
from numba import njit

CUBIC = 2.0  # weight of the cubic term (module docstring); EncodeOptions.carrato_cubic


def carrato_midpoints(v, eps, p, scale, axis, cubic=CUBIC):
    """Interpolate midpoints between consecutive samples along ``axis``.

    Parameters
    ----------
    v, eps : (M, N) float64 ndarray
        Samples and their errors.
    Returns
    -------
    mid, mid_eps : ndarrays with shape[axis] reduced by one.
    """
    v = np.moveaxis(np.asarray(v, np.float64), axis, 0)
    e = np.moveaxis(np.asarray(eps, np.float64), axis, 0)
    n = v.shape[0]
    if n < 2:
        shape = (0,) + v.shape[1:]
        return np.moveaxis(np.zeros(shape), 0, axis), np.moveaxis(np.zeros(shape), 0, axis)
    d = np.diff(v, axis=0)  # D[x], x = 0..n-2
    de = np.abs(e[:-1]) + np.abs(e[1:])  # error bound of each difference
    zero = np.zeros_like(d[:1])
    # replicate padding: the difference outside the image is 0 (error 0)
    dl = np.concatenate([zero, d[:-1]], axis=0)  # D[x-1]
    dr = np.concatenate([d[1:], zero], axis=0)  # D[x+1]
    del_ = np.concatenate([zero, de[:-1]], axis=0)
    der = np.concatenate([de[1:], zero], axis=0)
    base, base_e = v[:-1], e[:-1]

    def weight(dl_, dr_):
        sl = (dl_ / scale) ** 2
        sr = (dr_ / scale) ** 2
        return (p * sl + 1.0) / (p * (sl + sr) + 2.0)

    mid = base + weight(dl, dr) * d
    mid = mid - cubic * (dr - dl) / 16.0
    nxt = base + d  # the cubic term may not leave [phi[x], phi[x + 1]]: no overshoot
    mid = np.maximum(np.minimum(mid, np.maximum(base, nxt)), np.minimum(base, nxt))
    # The formula is base + w(D[x-1], D[x+1]) * D[x]: the base error adds +-eps as it is, and
    # w * D[x] takes its extremes at the corners of the box of limiting differences (w > 0).
    lo = np.full_like(mid, np.inf)
    hi = np.full_like(mid, -np.inf)
    for sl_, sr_ in itertools.product((-1.0, 1.0), repeat=2):
        w = weight(dl + sl_ * del_, dr + sr_ * der)
        for sd in (-1.0, 1.0):
            val = w * (d + sd * de)
            np.minimum(lo, val, out=lo)
            np.maximum(hi, val, out=hi)
    hi += base_e
    lo -= base_e
    mid_eps = 0.5 * (hi - lo)
    mid_eps = mid_eps + cubic * (del_ + der) / 16.0
    return np.moveaxis(mid, 0, axis), np.moveaxis(mid_eps, 0, axis)


def _interleave(v, mid, axis):
    """Samples and midpoints interleaved along axis: v0, m0, v1, m1, ..., v_{n-1}."""
    v = np.moveaxis(v, axis, 0)
    mid = np.moveaxis(mid, axis, 0)
    n = v.shape[0]
    out = np.empty((2 * n - 1,) + v.shape[1:], dtype=np.float64)
    out[0::2] = v
    out[1::2] = mid
    return np.moveaxis(out, 0, axis)


def map_pixels(channel, eps, p=0.5, scale=64.0, cubic=CUBIC):
    """The Carrato 2x grid of one channel, with the border ring.

    Parameters
    ----------
    channel : (H, W) float64 ndarray on the 0..255 scale
    eps : float or (H, W) ndarray, the per-sample error
    Returns
    -------
    grid, grid_eps : (2H + 1, 2W + 1) float64 ndarrays (layout in the module docstring)

    Notes
    -----
    Computed by a compiled kernel that fuses both passes and the padding (map_rows, which
    also computes any range of rows alone);
    mapping_ref.map_pixels is its NumPy twin (same floating-point expressions, same result).
    """
    v = np.ascontiguousarray(channel, dtype=np.float64)
    e = np.ascontiguousarray(np.broadcast_to(np.asarray(eps, dtype=np.float64), v.shape))
    return map_rows(v, e, float(p), float(scale), float(cubic), 0, 2 * v.shape[0] + 1)


# ---------------------------------------------------------------------------------------
# The compiled kernel: the expressions of carrato_midpoints, sample by sample (the min and
# max keep np.minimum's and np.maximum's choice between equal values).
# ---------------------------------------------------------------------------------------


@njit(cache=True, nogil=True, error_model="numpy")
def _weight(dl, dr, p, scale):
    sl = dl / scale
    sl = sl * sl
    sr = dr / scale
    sr = sr * sr
    return (p * sl + 1.0) / (p * (sl + sr) + 2.0)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _mid_value(base, d, dl, dr, p, scale, cubic):
    """The Carrato midpoint after ``base`` (difference d to the next sample, dl and dr the
    differences before and after), clamped between its two samples."""
    mid = base + _weight(dl, dr, p, scale) * d
    mid = mid - cubic * (dr - dl) / 16.0
    nxt = base + d
    return max(min(mid, max(base, nxt)), min(base, nxt))


@njit(cache=True, nogil=True, error_model="numpy")
def _midpoint(base, base_e, d, de, dl, dle, dr, dre, p, scale, cubic):
    """Carrato midpoint after ``base`` (difference d to the next sample, dl and dr the
    differences before and after, de, dle, dre their error bounds) and its error."""
    mid = _mid_value(base, d, dl, dr, p, scale, cubic)
    lo = np.inf
    hi = -np.inf
    for sl in (-1.0, 1.0):
        for sr in (-1.0, 1.0):
            w = _weight(dl + sl * dle, dr + sr * dre, p, scale)
            for sd in (-1.0, 1.0):
                val = w * (d + sd * de)
                lo = lo if lo < val else val
                hi = hi if hi > val else val
    hi += base_e
    lo -= base_e
    return mid, 0.5 * (hi - lo) + cubic * (dle + dre) / 16.0


# ---------------------------------------------------------------------------------------
# Grid rows: one pass along x per pixel row; a midpoint row between pixel rows i and i + 1
# reads rows i - 1 .. i + 2. map_rows computes any range of rows alone (the encoder marches
# strips of rows: encoder/strips.py), the same bits as the whole grid's.
# ---------------------------------------------------------------------------------------


@njit(cache=True, nogil=True, error_model="numpy")
def _x_pass(v, e, p, scale, cubic, g, ge, errors):
    """Row 2i + 1 of the grid (pixel row i and the midpoints along x) into g, ge (columns
    1 .. 2w - 1; the ring columns are left), v and e: pixel row i's values and errors, (1,
    w) each; errors False: the values alone (ge and e unused)."""
    w = v.shape[1]
    for j in range(w):
        g[2 * j + 1] = v[0, j]
        if errors:
            ge[2 * j + 1] = e[0, j]
    for j in range(w - 1):
        d = v[0, j + 1] - v[0, j]
        dl = 0.0
        dr = 0.0
        if j > 0:
            dl = v[0, j] - v[0, j - 1]
        if j + 2 < w:
            dr = v[0, j + 2] - v[0, j + 1]
        if not errors:
            g[2 * j + 2] = _mid_value(v[0, j], d, dl, dr, p, scale, cubic)
            continue
        de = abs(e[0, j]) + abs(e[0, j + 1])
        dle = 0.0
        dre = 0.0
        if j > 0:
            dle = abs(e[0, j - 1]) + abs(e[0, j])
        if j + 2 < w:
            dre = abs(e[0, j + 1]) + abs(e[0, j + 2])
        g[2 * j + 2], ge[2 * j + 2] = _midpoint(v[0, j], e[0, j], d, de, dl, dle, dr, dre, p, scale, cubic)


def map_rows(v, e, p, scale, cubic, g0, g1):
    """Rows [g0, g1) of map_pixels(v, e, ...)'s grid and errors, (g1 - g0, 2W + 1) each,
    bit for bit: v, e are the whole (H, W) plane and its errors (float64, contiguous)."""
    h, w = v.shape
    n = max(g1 - g0, 0)
    g = np.empty((n, 2 * w + 1))
    ge = np.empty((n, 2 * w + 1))
    rows = x_pass_rows(h, g0, g1)
    map_rows_into(v, e, p, scale, cubic, g0, g1, g, ge,
                  np.empty((rows, 2 * w + 1)), np.empty((rows, 2 * w + 1)))
    return g, ge


@njit(cache=True, nogil=True)
def x_rows(h, g0, g1):
    lo_eff = min(max(g0, 1), 2 * h - 1)
    hi_eff = min(max(g1 - 1, 1), 2 * h - 1)
    i_lo = max(0, (lo_eff - 1) // 2 - 1)
    i_hi = min(h, hi_eff // 2 + 2)
    return i_lo, i_hi


def x_pass_rows(h: int, g0: int, g1: int) -> int:
    """Rows of x-pass scratch map_rows_into needs for grid rows [g0, g1) of an h-row plane."""
    if g1 <= g0:
        return 0
    i_lo, i_hi = x_rows(h, g0, g1)
    return i_hi - i_lo


@njit(cache=True, nogil=True, error_model="numpy")
def map_rows_into(v, e, p, scale, cubic, g0, g1, g, ge, xs, xe, errors=True, e0=0, v0=0, h=-1):
    """map_rows into g, ge (g1 - g0 rows of 2W + 1, views allowed), with xs, xe as the x
    pass's scratch (x_pass_rows(H, g0, g1) rows of 2W + 1 each, or more); e: the errors'
    pixel rows from e0 on (the whole plane's, or at least its rows x_rows(H, g0, g1): the
    encoder's strips compute those alone, noise.error_rows); v likewise, its pixel rows
    from v0 on of a plane of h rows (h -1: v is the whole plane); errors False:
    the values alone, the same bits (ge, xe and e unused: the encoder's caps read the grid's
    values again, encoder/strips.py GridRows)."""
    if h < 0:
        h = v.shape[0]
    w = v.shape[1]
    w1 = 2 * w - 1
    n = g1 - g0
    if n <= 0:
        return
    i_lo, i_hi = x_rows(h, g0, g1)
    for i in range(i_lo, i_hi):
        er = e[i - e0 : i - e0 + 1] if errors else e[:1]
        _x_pass(v[i - v0 : i - v0 + 1], er, p, scale, cubic, xs[i - i_lo], xe[i - i_lo] if errors else xe[0], errors)
    for k in range(n):
        gr = min(max(g0 + k, 1), 2 * h - 1)  # the ring rows repeat their neighbours
        if gr % 2 == 1:
            a = (gr - 1) // 2 - i_lo
            for c in range(1, w1 + 1):
                g[k, c] = xs[a, c]
                if errors:
                    ge[k, c] = xe[a, c]
        else:
            i = gr // 2 - 1
            a = i - i_lo
            for c in range(1, w1 + 1):
                d = xs[a + 1, c] - xs[a, c]
                dl = 0.0
                dr = 0.0
                if i > 0:
                    dl = xs[a, c] - xs[a - 1, c]
                if i + 2 < h:
                    dr = xs[a + 2, c] - xs[a + 1, c]
                if not errors:
                    g[k, c] = _mid_value(xs[a, c], d, dl, dr, p, scale, cubic)
                    continue
                de = abs(xe[a, c]) + abs(xe[a + 1, c])
                dle = 0.0
                dre = 0.0
                if i > 0:
                    dle = abs(xe[a - 1, c]) + abs(xe[a, c])
                if i + 2 < h:
                    dre = abs(xe[a + 1, c]) + abs(xe[a + 2, c])
                g[k, c], ge[k, c] = _midpoint(xs[a, c], xe[a, c], d, de, dl, dle, dr, dre, p, scale, cubic)
        g[k, 0] = g[k, 1]
        g[k, w1 + 1] = g[k, w1]
        if errors:
            ge[k, 0] = ge[k, 1]
            ge[k, w1 + 1] = ge[k, w1]
