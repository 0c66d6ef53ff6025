"""Histogram equalisation by level reassignment (paper §5, Fig. 10-11).

A pixel method can only move whole histogram bins: an 8-bit image equalised by pixels keeps
its 256 (or fewer) distinct values and leaves gaps between them. A vector image has no bins.
Its Y channel is a set of isolines at levels l_0 < ... < l_{L-1} and the renderer
interpolates between them, so giving the levels new values stretches every band of the
image continuously, and the rendered histogram can be made rectangular.

    equalise(vi)  ->  level_areas: the exact area above every level (Green's theorem)
                  ->  new level l_k = H^-1(fraction of the area below l_k)      (§5)
                  ->  cap values through the same map
                  ->  refine (optional): measure the render, reassign levels and caps

Areas (exact)
    The area where the channel is >= l_k is the frame (when the root band is above l_k)
    plus the signed areas enclosed by the contours of level k. With y down and the >= side
    on the left (model.py), a contour's signed area is -∮ x dy, and for a cubic Bezier
    segment ∮ x dy has a closed form in its control points (the one fontTools'
    ``AreaPen`` uses). Contours are unchanged; only numbers move.

The inverse map (the paper's H^-1)
    Rendered 8-bit values are round(v); a rectangular histogram of 256 bins is v uniform on
    [-0.5, 255.5]. So the level below which a fraction p of the image lies goes to
    256 p - 0.5. Levels are kept strictly increasing (gaps of at least LEVEL_GAP) and
    inside (0, 255), as the data model requires.

Caps and the ends
    Peaks and pits (model.py, Caps) are not between two levels: their profile runs from their
    level to their cap value. Cap values go through the same piecewise-linear map as the
    levels, anchored at the ends by the darkest and brightest value of the image going to
    -0.5 and 255.5 (then clipped to [0, 255]): the bands below the first and above the last
    level stretch to the ends of the scale.

Refinement (``refine=True``, the default)
    Level reassignment alone makes every band hold the right share of the image, but inside
    a band the renderer's values are not uniform (more pixels sit near the levels: the ramps
    of the many small caps), which costs ~0.05 bit of entropy and KS ~0.01 on photographs.
    The render is linear in the levels and cap values (double diffusion interpolates the two
    levels of a band with weights set by distances alone; a cap's profile is
    L + (cap - L) f with f set by distances alone), so three renders of the channel measure
    every pixel's weights (``_pixel_model``), and the levels and the cap values are then
    fitted, by alternating least squares, to the values of exact histogram specification
    (every pixel sent to the uniform quantile of its rank). Caps stay inside their band and
    levels stay increasing, so the equalised image keeps every contour and every ordering
    between bands; what moves is where inside its band a cap's plateau sits. The result is
    checked against a real render (``info["measured"]``).

Chroma
    U and V are left as they are: only luminance is equalised (as OpenCV's recipe of
    equalising Y of YCrCb). A hue and its saturation stay the same; colours that the new
    luminance puts outside the RGB cube are clipped by the renderer.

References
    The paper §5; fontTools ``Lib/fontTools/pens/areaPen.py`` (the cubic area term).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import OptionError
from ..model import Channel, VectorImage

LEVEL_GAP = 1e-3  # grey levels: the smallest gap between reassigned levels
LEVEL_MIN, LEVEL_MAX = 1e-3, 255.0 - 1e-3  # levels stay inside (0, 255)
VALUE_QUANT = 64  # cap values are stored in 1/64 grey level (format/isoph.py)


# =============================================================================================
# Exact areas (Green's theorem on cubic Beziers)
# =============================================================================================


def segment_moments(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """∮ x dy along every cubic segment of a channel's chains, exactly.

    Parameters
    ----------
    points : (P, 2) float64, offsets : (C + 1,) int64
        A channel's concatenated chains (model.py layout).

    Returns
    -------
    (S,) float64
        For segment P0, P1, P2, P3: the integral of x dy along it. Over a closed chain they
        add up to the enclosed area counted positively for a chain that runs clockwise on
        screen (y down), i.e. minus the area on the chain's left.
    """
    counts = (np.diff(offsets) - 1) // 3
    if counts.sum() == 0:
        return np.zeros(0)
    within = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    first = np.repeat(offsets[:-1], counts) + 3 * within
    p0, p1, p2, p3 = (points[first + i] for i in range(4))
    x0 = p0[:, 0]
    x1, y1 = (p1 - p0).T
    x2, y2 = (p2 - p0).T
    x3, y3 = (p3 - p0).T
    # ∫ x dy = ∫ (x0 + X) dY = x0 Y3 + ∫ X dY with X, Y relative to P0, and
    # ∫ X dY = X3 Y3 - ∫ Y dX = X3 Y3 / 2 - 3/20 (X1 (-Y2 - Y3) + X2 (Y1 - 2 Y3) + X3 (Y1 + 2 Y2))
    # (the bracket is 20/3 of the area between the curve and its chord: AreaPen's term).
    chord = 0.5 * x3 * y3
    bulge = -0.15 * (x1 * (-y2 - y3) + x2 * (y1 - 2.0 * y3) + x3 * (y1 + 2.0 * y2))
    return x0 * y3 + chord + bulge


def contour_areas(channel: Channel) -> np.ndarray:
    """(C,) float64: area on the >= side of each contour (positive for a peak's outline,
    negative for a hole), exact for the Bezier chains."""
    m = segment_moments(channel.points, channel.offsets)
    so = channel.segment_offsets()
    cs = np.concatenate([[0.0], np.cumsum(m)])
    return -(cs[so[1:]] - cs[so[:-1]])


def level_areas(channel: Channel, width: int, height: int) -> np.ndarray:
    """(L,) float64: the area (in source pixels) where the channel is >= each level.

    Exact for the chains (no rasterisation): the frame for the levels below ``base_band``
    plus the signed areas of the level's contours. The differences of consecutive entries
    are the band areas.
    """
    n = channel.levels.shape[0]
    a = np.bincount(channel.contour_level, weights=contour_areas(channel), minlength=n)[:n]
    a = a + np.where(np.arange(n) < channel.base_band, float(width) * float(height), 0.0)
    return np.clip(a, 0.0, float(width) * float(height))


# =============================================================================================
# Level reassignment (§5)
# =============================================================================================


def uniform_levels(fraction_below: np.ndarray) -> np.ndarray:
    """H^-1: the level value below which ``fraction_below`` of a rectangular histogram lies,
    on the 8-bit rendering scale ([-0.5, 255.5] holds 256 bins of width 1), made strictly
    increasing and kept inside (0, 255)."""
    return monotone_levels(256.0 * np.asarray(fraction_below, dtype=np.float64) - 0.5)


def monotone_levels(levels: np.ndarray) -> np.ndarray:
    """Clip into [LEVEL_MIN, LEVEL_MAX] and open gaps of at least LEVEL_GAP, moving as
    little as possible (from both ends towards the middle)."""
    v = np.clip(np.asarray(levels, dtype=np.float64), LEVEL_MIN, LEVEL_MAX).copy()
    n = v.shape[0]
    if n == 0:
        return v
    # the highest value the k-th level may take so that the ones above still fit, and the lowest
    hi = LEVEL_MAX - LEVEL_GAP * (n - 1 - np.arange(n))
    lo = LEVEL_MIN + LEVEL_GAP * np.arange(n)
    v = np.clip(v, lo, hi)
    for k in range(1, n):
        v[k] = max(v[k], v[k - 1] + LEVEL_GAP)
    return v


def _cap_levels(channel: Channel) -> np.ndarray:
    """(K,) int64: index of the level that bounds each cap region (its profile starts there),
    -1 for a region with no contour at all (flat at its cap value)."""
    k = channel.cap_band.shape[0]
    out = np.full(k, -1, np.int64)
    if channel.n_contours == 0 or k == 0:
        return out
    cc = channel.cap_contour.astype(np.int64)
    has = cc >= 0
    out[has] = channel.contour_level[cc[has]]
    roots = np.flatnonzero(channel.parent == -1)
    if roots.size and (~has).any():
        # the root region is bounded by the frame's children, all of one level for a cap
        out[~has] = channel.contour_level[roots[0]]
    return out


def _value_map(channel: Channel, new_levels: np.ndarray):
    """The piecewise-linear map old value -> new value through the levels, anchored at the
    ends of the channel's value range."""
    old = channel.levels
    # the darkest / brightest cap values are the ends of the image's range
    below = channel.cap_value[channel.cap_value < old[0]]
    above = channel.cap_value[channel.cap_value > old[-1]]
    lo = float(below.min()) if below.size else float(old[0]) - 1e-6
    hi = float(above.max()) if above.size else float(old[-1]) + 1e-6
    xs = np.concatenate([[lo], old, [hi]])
    ys = np.concatenate([[-0.5], new_levels, [255.5]])
    return lambda v: np.interp(v, xs, ys)


def _quantise_values(v: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(v, dtype=np.float64) * VALUE_QUANT) / VALUE_QUANT


def reassign_levels(channel: Channel, width: int, height: int) -> Channel:
    """The channel with its levels moved to H^-1 of the exact area fractions (§5), cap values
    mapped the same way. Contours, bands and caps' positions are unchanged."""
    if channel.levels.shape[0] == 0:
        return channel
    below = 1.0 - level_areas(channel, width, height) / (float(width) * float(height))
    new = uniform_levels(below)
    g = _value_map(channel, new)
    caps = np.clip(_quantise_values(g(channel.cap_value)), 0.0, 255.0)
    return replace(channel, levels=new, cap_value=caps)


# =============================================================================================
# Refinement: exact histogram specification on the levels and caps
# =============================================================================================


def _render_channel(channel: Channel, width: int, height: int) -> np.ndarray:
    from ..render import render_float

    return render_float(VectorImage(width, height, "grey", (channel,)))[..., 0]


PROBE_SHIFT = 50.0  # grey levels a probe moves a cap (towards mid-scale, so nothing clips)
PROBE_CODE_SPAN = 1.5  # probe 2 multiplies the shift by 1 .. 1 + span, one factor per cap
F_MIN = 1e-3  # pixels whose cap weight is below this are treated as lying on the level
LEVEL_RIDGE = 1.0  # pixels: weight of a level's current value in the least-squares refit


class _PixelModel:
    """Every pixel's rendered value as a function of the levels and cap values:
    v = wl * levels[il] + wr * levels[ir] + wc * caps[ic] + const (unused terms have weight 0,
    index 0)."""

    def __init__(self, n, L, K):
        self.il = np.zeros(n, np.int64)
        self.ir = np.zeros(n, np.int64)
        self.ic = np.zeros(n, np.int64)
        self.wl = np.zeros(n)
        self.wr = np.zeros(n)
        self.wc = np.zeros(n)
        self.const = np.zeros(n)
        self.L, self.K = L, K

    def predict(self, levels, caps):
        caps = caps if caps.size else np.zeros(1)
        return self.wl * levels[self.il] + self.wr * levels[self.ir] + self.wc * caps[self.ic] + self.const


def _pixel_model(channel: Channel, width: int, height: int, r0: np.ndarray) -> _PixelModel:
    """Measure every pixel's weights with two probe renders (caps moved by known amounts).

    Probe 1 moves every cap by +-PROBE_SHIFT: a pixel that moves by PROBE_SHIFT * f is in a
    cap region with profile weight f. Probe 2 moves cap c by PROBE_SHIFT * code_c with a
    distinct code per cap: the ratio of the two moves names the pixel's cap. Pixels in no cap
    lie in a band between two levels, and their weight follows from their value in r0.
    """
    lev = channel.levels
    L, K = lev.shape[0], channel.cap_value.shape[0]
    v0 = r0.ravel().astype(np.float64)
    n = v0.shape[0]
    model = _PixelModel(n, L, K)
    cap_pixel = np.zeros(n, bool)
    if K:
        sign = np.where(channel.cap_value < 127.5, 1.0, -1.0)
        code = 1.0 + PROBE_CODE_SPAN * (np.arange(K) + 0.5) / K
        r1 = _render_channel(replace(channel, cap_value=channel.cap_value + sign * PROBE_SHIFT), width, height)
        r2 = _render_channel(replace(channel, cap_value=channel.cap_value + sign * PROBE_SHIFT * code),
                             width, height)
        d1 = r1.ravel() - v0
        d2 = r2.ravel() - v0
        f = np.abs(d1) / PROBE_SHIFT
        cap_pixel = f > F_MIN
        ratio = np.where(cap_pixel, d2 / np.where(cap_pixel, d1, 1.0), 1.0)
        c = np.clip(np.rint((ratio - 1.0) / PROBE_CODE_SPAN * K - 0.5), 0, K - 1).astype(np.int64)
        f = np.clip(f, 0.0, 1.0)
        cl = _cap_levels(channel)
        idx = np.flatnonzero(cap_pixel)
        ci = c[idx]
        model.ic[idx] = ci
        model.wc[idx] = f[idx]
        has_level = cl[ci] >= 0
        model.il[idx[has_level]] = cl[ci[has_level]]
        model.wl[idx[has_level]] = 1.0 - f[idx[has_level]]
        # a cap region with no contour at all: flat at its value (f == 1), nothing else
        model.const[idx[~has_level]] = 0.0
    # band pixels: between levels b - 1 and b, with b the number of levels <= v
    rest = np.flatnonzero(~cap_pixel)
    if L and rest.size:
        v = v0[rest]
        b = np.searchsorted(lev, v, side="right")
        inner = (b >= 1) & (b <= L - 1)
        i_in = rest[inner]
        bi = b[inner]
        lo, hi = lev[bi - 1], lev[bi]
        w = np.clip((v[inner] - lo) / (hi - lo), 0.0, 1.0)
        model.il[i_in], model.ir[i_in] = bi - 1, bi
        model.wl[i_in], model.wr[i_in] = 1.0 - w, w
        # outside every level (regions without annotation): a fixed offset from the end level
        out_ = rest[~inner]
        end = np.where(b[~inner] == 0, 0, L - 1)
        model.il[out_] = end
        model.wl[out_] = 1.0
        model.const[out_] = v[~inner] - lev[end]
    elif rest.size:
        model.const[rest] = v0[rest]
    return model


def _targets(v: np.ndarray) -> np.ndarray:
    """Exact histogram specification: pixel of rank r (ties by position) goes to the centre
    of the r-th of n equal slices of [-0.5, 255.5]."""
    n = v.shape[0]
    order = np.argsort(v, kind="stable")
    t = np.empty(n)
    t[order] = (np.arange(n) + 0.5) * (256.0 / n) - 0.5
    return t


def _cap_bounds(channel: Channel, levels: np.ndarray):
    """(K,) lower and upper bound of each cap value: its band's two levels (the scale's ends
    for the bands below the first and above the last level)."""
    b = channel.cap_band.astype(np.int64)
    ext = np.concatenate([[0.0], levels, [255.0]])
    return ext[b], ext[b + 1]


def _caps_in_bands(caps, channel: Channel, levels) -> np.ndarray:
    """Cap values on the 1/64 grid of the file format, inside their bands where the band is
    wider than one grid step (else the nearest grid value)."""
    lo, hi = _cap_bounds(channel, levels)
    lo, hi = np.minimum(lo, hi), np.maximum(lo, hi)
    q = _quantise_values(np.clip(caps, lo, hi))
    qlo, qhi = np.ceil(lo * VALUE_QUANT) / VALUE_QUANT, np.floor(hi * VALUE_QUANT) / VALUE_QUANT
    room = qlo <= qhi
    q = np.where(room, np.clip(q, qlo, qhi), q)
    return np.clip(q, 0.0, 255.0)


def _fit(model: _PixelModel, channel: Channel, levels, caps, iterations: int):
    """Alternating least squares of the model's values against the rank targets."""
    L, K = model.L, model.K
    for _ in range(iterations):
        t = _targets(model.predict(levels, caps))
        if K:
            # caps, levels fixed: one independent 1-D least squares per cap
            rest = t - model.wl * levels[model.il] - model.wr * levels[model.ir] - model.const
            num = np.bincount(model.ic, weights=model.wc * rest, minlength=K)
            den = np.bincount(model.ic, weights=model.wc * model.wc, minlength=K)
            lo, hi = _cap_bounds(channel, levels)
            fitted = np.where(den > 1e-9, num / np.maximum(den, 1e-12), caps)
            caps = np.clip(fitted, np.minimum(lo, hi), np.maximum(lo, hi))
        if L:
            # levels, caps fixed: normal equations of a sparse (L x L) system
            rhs_t = t - model.wc * (caps[model.ic] if K else 0.0) - model.const
            A = np.zeros((L, L))
            rhs = np.zeros(L)
            for ia, wa in ((model.il, model.wl), (model.ir, model.wr)):
                rhs += np.bincount(ia, weights=wa * rhs_t, minlength=L)
                for ib, wb in ((model.il, model.wl), (model.ir, model.wr)):
                    A += np.bincount(ia * L + ib, weights=wa * wb, minlength=L * L).reshape(L, L)
            # a ridge towards the current levels (LEVEL_RIDGE pixels' worth): a level that few
            # pixels depend on must not fly off; then each level stays between its neighbours
            A[np.diag_indices(L)] += LEVEL_RIDGE
            rhs += LEVEL_RIDGE * levels
            new = np.linalg.solve(A, rhs)
            ext = np.concatenate([[LEVEL_MIN], levels, [LEVEL_MAX]])
            new = np.clip(new, ext[:-2], ext[2:])
            levels = monotone_levels(new)
    return levels, caps


def refine(channel: Channel, width: int, height: int, iterations: int = 8):
    """Refit levels and cap values so that the rendered channel's histogram is as close to
    rectangular as the contours allow (see the module docstring). Returns (channel, info)."""
    r0 = _render_channel(channel, width, height)
    model = _pixel_model(channel, width, height, r0)
    err = float(np.abs(model.predict(channel.levels, channel.cap_value) - r0.ravel()).max())
    levels, caps = _fit(model, channel, channel.levels.copy(), channel.cap_value.copy(), iterations)
    out = replace(channel, levels=levels, cap_value=_caps_in_bands(caps, channel, levels))
    measured = histogram_stats(_render_channel(out, width, height))
    return out, {"model_error": err, "measured": measured}


# =============================================================================================
# The operation
# =============================================================================================


def equalise(vi: VectorImage, refine_render: bool = True, iterations: int = 8, info: dict | None = None) -> VectorImage:
    """Histogram-equalise a vector image's luminance by level reassignment (§5).

    Parameters
    ----------
    vi : VectorImage
    refine_render : bool
        After the exact-area reassignment, measure the rendered channel and refit levels and
        cap values to a rectangular histogram (three renders of Y, plus one to check). With
        False only the areas are used: no rendering, instant.
    iterations : int
        Alternating least-squares rounds of the refinement.
    info : dict, optional
        Filled with ``areas`` (fraction of the image >= each old level), ``levels`` (old and
        new) and, with refinement, ``model_error`` (largest difference in grey levels between
        the measured pixel model and the render) and ``measured``: :func:`histogram_stats` of
        the equalised Y channel rendered at 1x.

    Returns
    -------
    VectorImage
        Same contours; the Y channel's levels and cap values reassigned. U, V and A as they
        were.
    """
    if not isinstance(vi, VectorImage):
        raise OptionError(f"expected a VectorImage, got {type(vi).__name__}")
    y = vi.channel("Y")
    w, h = vi.width, vi.height
    eq = reassign_levels(y, w, h)
    details = {
        "area_above": (level_areas(y, w, h) / (float(w) * float(h))).tolist(),
        "old_levels": y.levels.tolist(),
    }
    if refine_render and y.levels.shape[0]:
        eq, extra = refine(eq, w, h, iterations)
        details.update(extra)
    details["new_levels"] = eq.levels.tolist()
    if info is not None:
        info.update(details)
    channels = tuple(eq if ch.name == "Y" else ch for ch in vi.channels)
    meta = dict(vi.meta)
    meta["equalised"] = "levels+caps" if refine_render else "levels"
    return replace(vi, channels=channels, meta=meta)


def histogram_stats(values) -> dict:
    """Rectangularity of an 8-bit histogram.

    Parameters
    ----------
    values : array of integers in 0..255 (a rendered 8-bit plane)

    Returns
    -------
    dict
        ``empty`` bins (of 256), ``ks`` (largest distance between the cumulative histogram and
        the uniform one), ``entropy`` in bits (8 for a perfectly flat histogram).
    """
    q = np.asarray(values).ravel()
    if q.size == 0:
        raise OptionError("no samples")
    q = np.clip(np.rint(q), 0, 255).astype(np.int64)
    hist = np.bincount(q, minlength=256).astype(np.float64)
    p = hist / hist.sum()
    ks = float(np.abs(np.cumsum(p) - np.arange(1, 257) / 256.0).max())
    nz = p[p > 0]
    return {"empty": int((hist == 0).sum()), "ks": ks, "entropy": float(-(nz * np.log2(nz)).sum())}


def equalise_pixels(plane: np.ndarray) -> np.ndarray:
    """The pixel way, for comparison: classic histogram equalisation of an 8-bit plane
    (the cumulative histogram as a lookup table, as OpenCV's ``equalizeHist``)."""
    q = np.clip(np.rint(np.asarray(plane, dtype=np.float64)), 0, 255).astype(np.int64)
    hist = np.bincount(q.ravel(), minlength=256)
    cdf = np.cumsum(hist)
    nz = cdf[cdf > 0][0]
    if cdf[-1] == nz:
        return q.astype(np.uint8)
    lut = np.clip(np.rint((cdf - nz) * 255.0 / (cdf[-1] - nz)), 0, 255).astype(np.uint8)
    return lut[q]
