"""Histogram equalisation by level reassignment (paper §5, Fig. 10-11).

A pixel method can only move whole histogram bins: an 8-bit image equalised by pixels keeps
its 256 (or fewer) distinct values and leaves gaps between them. A vector image has no bins.
Its Y channel is a set of isolines at levels l_0 < ... < l_{L-1} and the renderer
interpolates between them, so giving the levels new values stretches every band of the
image continuously, and the rendered histogram can be made rectangular.

    equalise(vi)  ->  level_areas: the exact area above every level (Green's theorem)
                  ->  new level l_k = H^-1(fraction of the area below l_k)      (§5)
                  ->  cap values through the same map
                  ->  tone curve (optional): inside every band, the rendered values'
                      distribution mapped onto a uniform spread between the band's levels

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
    inside (0, 255), as the data model requires. This is the primary mechanism (the
    paper's): it fixes how much of the image every band holds, exactly and without
    rendering.

Caps and the ends
    Peaks and pits (model.py, Caps) are not between two levels: their profile runs from their
    level to their cap value. Cap values go through the same piecewise-linear map as the
    levels, anchored at the ends by the darkest and brightest value of the image going to
    0 and 255 (the ends of the value scale, so that distinct dark or bright caps stay
    distinct for the tone curve): the bands below the first and above the last level
    stretch to the ends of the scale.

Tone curve (``refine_render=True``, the default)
    Level reassignment gives every band its share of the image, but inside a band the
    double-diffusion fill is not uniform (more samples sit near the levels, the ramps of the
    many small caps crowd towards their plateaus), and a raster samples each band in a
    slightly different share than its exact area (by up to 0.005 at 1x), which leaves KS
    0.01-0.05 and 0.1-0.5 bit of entropy on the corpus. Channel.tone (model.py) is a
    monotone curve that the renderer applies to every sample: the channel with its new
    levels is rendered, and the cumulative distribution of the values found becomes the
    tone curve (``tone_curve`` with no levels: one curve over the whole scale). Contours do
    not move; the rendered value at a level becomes the curve's value there.

    The distribution is measured on the point samples of two renders pooled, at 1x and at 2x
    (``MEASURE_SCALES``), the native size weighing twice as much (``MEASURE_WEIGHTS``):
    enlargements evaluate the fill on a finer distance grid (two or three nodes per source
    pixel, render/__init__.py ``node_resolution``), while the 1x samples sit exactly on the
    source pixel centres, and the two distributions differ a little. Measured on the corpus with domes
    (benchmarks/apply.py; KS / entropy at 1x, and at 2x, means): per-band curves (every
    level a fixed knot) measured at 2x 0.0047 / 7.986 and 0.0008 / 7.999; per-band, pooled
    0.0041 / 7.995 and 0.0018 / 7.997; one curve, pooled 0.0026 / 7.996 and 0.0026 / 7.996;
    one curve, 1x weighing 2 (the default) 0.0018 / 7.998 and 0.0032 / 7.996 (worst photo,
    camera: 0.0034 and 0.0066); one curve from 1x alone 0.0003 / 8.000 and 0.0049 / 7.990
    (camera at 2x 0.0100).
    Large images are measured at reduced scales (about MEASURE_PIXELS samples at 1x).

    Domes: a cap's plateau is flat (model.py, CAP_RAMP), so a large cap (a clear sky, a
    black background) is a single value that holds a sizeable share of the image, and no
    monotone curve can spread it: an atom of mass m costs KS >= m / 2 wherever it goes (the
    curve keeps the order of all values; moving cap values independently could reorder
    plateaus, but would invert contrasts). So the equalised channel's caps become domes
    (cap_ramp DOME): the profile keeps rising (or falling) from the contour to the cap
    value at the region's farthest point, which breaks the plateau's tie by the distance
    to the contour, the order the diffusion itself gives (as exact histogram
    specification breaks ties by a secondary key). The regions that are still one value
    (no contour at all) and the extremes of the scale are atoms (ATOM, one bin's share, or
    more). Measured on the corpus at 1x (benchmarks/apply.py; KS / entropy, mean): plateaus
    0.0167 / 7.867 bits, domes 0.0047 / 7.986 (astronaut 0.0475 -> 0.0024, camera 0.0217
    -> 0.0090); the dark background behind astronaut's shuttle becomes a smooth dark
    gradient instead of one grey. An atom is put at its mid-rank (the middle of its share of the band), and the values on either
    side of it are stretched over a window as wide as the atom, so that its neighbours fill
    the bins around it rather than leaving them empty; when the window would have to be
    stretched more than STRETCH_MAX times (an atom with little beside it), the atom moves
    towards the thin side. An atom with nothing below it in the image stays at 0 (nothing
    above: 255): lifting it to its mid-rank would empty every bin below it.

    The dense curve (a knot every KNOT_STEP grey levels of output) is simplified (Ramer-
    Douglas-Peucker) within KNOT_TOLERANCE grey levels: 120-170 knots on the corpus.

Chroma
    U and V are left as they are: only luminance is equalised (as OpenCV's recipe of
    equalising Y of YCrCb), so a hue and its chroma stay the same. Colours that the new
    luminance puts outside the RGB cube are clipped by the renderer, as they are by the
    pixel recipe: on coffee and chelsea about 20 % of the pixels leave the cube by more than
    2 grey levels either way (OpenCV's recipe: the same share). A global chroma gain would
    be the only other choice the channels allow (they are independent, so chroma cannot
    follow each pixel's change of luminance), and it buys little: 0.8 still leaves 17 %.

References
    The paper §5; fontTools ``Lib/fontTools/pens/areaPen.py`` (the cubic area term).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import OptionError
from ..shared.grid import QUANT as VALUE_QUANT  # cap values are stored on the file's grid
from ..geometry.areas import segment_moments  # ∮ x dy along every segment, exactly
from ..model import DOME, Channel, VectorImage

LEVEL_GAP = 1e-3  # grey levels: the smallest gap between reassigned levels
LEVEL_MIN, LEVEL_MAX = 1e-3, 255.0 - 1e-3  # levels stay inside (0, 255)


# =============================================================================================
# Exact areas (Green's theorem on cubic Beziers)
# =============================================================================================


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


def _value_map(channel: Channel, new_levels: np.ndarray):
    """The piecewise-linear map old value -> new value through the levels, anchored at the
    ends of the channel's value range going to 0 and 255."""
    old = channel.levels
    # the darkest / brightest cap values are the ends of the image's range
    below = channel.cap_value[channel.cap_value < old[0]]
    above = channel.cap_value[channel.cap_value > old[-1]]
    lo = float(below.min()) if below.size else float(old[0]) - 1e-6
    hi = float(above.max()) if above.size else float(old[-1]) + 1e-6
    xs = np.concatenate([[lo], old, [hi]])
    ys = np.concatenate([[0.0], new_levels, [255.0]])
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
# Tone curve: the within-band distribution made uniform
# =============================================================================================


MEASURE_SCALES = (1.0, 2.0)  # the renders measured, pooled (see the module docstring)
MEASURE_WEIGHTS = (2.0, 1.0)  # their weights in the pool: the native size first
# larger images are measured as if they had this many pixels. At 1 MP the wide corpus's
# 1280 x 800 photographs were measured at 0.988x, off the 1x sample grid: Kite's Y at 1x
# KS 0.0019, measured at 1x 0.0010 (issue 26).
MEASURE_PIXELS = 2_100_000
# The measured renders are one window up to this many nodes (render/blocks.one_window: every
# 2x render of MEASURE_PIXELS, about 1 GB while it is made): a blocked 2x render's domes
# (this channel's caps) are a level or so off the one-window render near block borders, and
# the curve learnt from them left ColdRipple's equalised 1x at KS 0.0064 against 0.0042
# (benchmarks/results/quality_wide_balanced.md; the other wide photos the same to 4 digits).
MEASURE_WINDOW_NODES = 4 * MEASURE_PIXELS + 100_000  # the 2x render's nodes, and room for its sides' rounding
ATOM = 1.0 / 256.0  # a single value holding this share of the image (a bin) is an atom
STRETCH_MAX = 32.0  # the most the values beside an atom are spread thinner than uniform
KNOT_STEP = 0.5  # grey levels of output between the knots of the dense curve
KNOT_TOLERANCE = 0.05  # grey levels: how far the simplified curve may stray from the dense one


def _render_channel(channel: Channel, width: int, height: int, scale: float = 1.0,
                    sharpen: float = 0.0) -> np.ndarray:
    """(H, W) float64: one channel rendered alone (point samples, tone applied if any). The
    curve is measured on the fill itself, without the enlargement sharpening (sharpen 0):
    with the renderer's default the 2x render's histogram spreads, and the pooled curve
    left the 1x render further from flat (corpus mean KS at 1x 0.0036 against 0.0012)."""
    from ..render import render_float

    return render_float(VectorImage(width, height, "grey", (channel,)), scale=scale, sharpen=sharpen)[..., 0]


def measure_values(channel: Channel, width: int, height: int) -> np.ndarray:
    """(N,) float64: the channel's rendered values as the tone curve sees them (no tone
    applied): the point samples of its renders at MEASURE_SCALES (smaller for images of
    more than MEASURE_PIXELS pixels), each render repeated so that it weighs its
    MEASURE_WEIGHTS share."""
    from ..render.blocks import one_window

    reduce = min(1.0, float(np.sqrt(MEASURE_PIXELS / (float(width) * float(height)))))
    plain = replace(channel, tone=None)
    with one_window(MEASURE_WINDOW_NODES):  # the fields blocks approximate: a dome is measured whole
        parts = [_render_channel(plain, width, height, s * reduce).ravel() for s in MEASURE_SCALES]
    most, least = max(p.size for p in parts), min(MEASURE_WEIGHTS)
    return np.concatenate([np.repeat(p, max(1, round(w * most / (least * p.size))))
                           for p, w in zip(parts, MEASURE_WEIGHTS)])


def _simplify(x: np.ndarray, y: np.ndarray, tol: float) -> np.ndarray:
    """Indices of the knots kept by Ramer-Douglas-Peucker with a vertical tolerance (the
    piecewise-linear curve through the kept knots is within ``tol`` of every dropped one).
    The first and last knots are always kept."""
    keep = np.zeros(x.shape[0], bool)
    keep[[0, -1]] = True
    stack = [(0, x.shape[0] - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        t = (x[a + 1 : b] - x[a]) / (x[b] - x[a])
        err = np.abs(y[a + 1 : b] - (y[a] + t * (y[b] - y[a])))
        i = int(np.argmax(err))
        if err[i] > tol:
            m = a + 1 + i
            keep[m] = True
            stack += [(a, m), (m, b)]
    return np.flatnonzero(keep)


def _band_curve(v, lo_w, hi_w, share, xa, xb, ya, yb):
    """Knots (x, y) of the tone curve over one band: input [xa, xb] onto output [ya, yb].

    v : (n,) sorted distinct values found in the band, lo_w / hi_w : (n,) the share of the
    band's samples below each value and up to it (0 .. 1), share : the band's share of the
    image. Returns x (strictly increasing, xa first, xb last) and y (non-decreasing, ya
    first, yb last)."""
    span = yb - ya

    def lin(u):  # the uniform target: the sample of rank u goes to ya + span u
        return ya + span * u

    # rank -> output: the uniform line, bent through every atom (module docstring)
    atoms = np.flatnonzero((hi_w - lo_w) * share >= ATOM)
    bends = []  # (rank, output, value or nan)
    for j, i in enumerate(atoms):
        u0, u1 = lo_w[i], hi_w[i]
        m = u1 - u0
        prev_end = hi_w[atoms[j - 1]] if j else 0.0
        next_start = lo_w[atoms[j + 1]] if j + 1 < atoms.size else 1.0
        # windows as wide as the atom, sharing a gap with a neighbouring atom half and half
        wl = min(m, (u0 - prev_end) / (2.0 if j else 1.0))
        wh = min(m, (next_start - u1) / (2.0 if j + 1 < atoms.size else 1.0))
        # the mid-rank, unless a window would have to stretch more than STRETCH_MAX times;
        # squeezed from both sides, it goes where both windows stretch alike
        p = lin(0.5 * (u0 + u1))
        below_max = lin(u0 - wl) + STRETCH_MAX * span * wl
        above_min = lin(u1 + wh) - STRETCH_MAX * span * wh
        if above_min > below_max and wl + wh > 0.0:
            p = (lin(u0 - wl) * wh + lin(u1 + wh) * wl) / (wl + wh)
        else:
            p = min(max(p, above_min), below_max)
        if wl > 0.0:
            bends.append((u0 - wl, lin(u0 - wl), np.nan))
        bends.append((0.5 * (u0 + u1), p, v[i]))
        if wh > 0.0:
            bends.append((u1 + wh, lin(u1 + wh), np.nan))
    bu, by, bx = (np.array(c, np.float64) for c in zip(*bends)) if bends else (np.zeros(0),) * 3
    ranks = np.concatenate([[0.0], bu, [1.0]])
    outs = np.concatenate([[ya], by, [yb]])
    # the dense knots: a grid in rank (no rank inside an atom) and the windows' edges, at the
    # values the band's samples take there (its quantile function)
    steps = max(int(np.ceil(abs(span) / KNOT_STEP)), 1)
    grid = np.arange(1, steps) / steps
    for i in atoms:
        grid = grid[(grid <= lo_w[i]) | (grid >= hi_w[i])]
    gu = np.concatenate([grid, bu[np.isnan(bx)]])
    x = np.concatenate([np.interp(gu, 0.5 * (lo_w + hi_w), v), bx[~np.isnan(bx)]])
    y = np.concatenate([np.interp(gu, ranks, outs), by[~np.isnan(bx)]])
    order = np.argsort(x, kind="stable")
    x, y = x[order], y[order]
    inner = (x > xa) & (x < xb)
    x = np.concatenate([[xa], x[inner], [xb]])
    y = np.concatenate([[ya], y[inner], [yb]])
    # equal values (ties): one knot, at their mean output
    ux, inv = np.unique(x, return_inverse=True)
    uy = np.bincount(inv, weights=y) / np.bincount(inv)
    uy[0], uy[-1] = ya, yb
    return ux, np.maximum.accumulate(uy)


def tone_curve(values: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """The tone curve that makes a channel's rendered histogram rectangular, band by band
    (with no levels: one band, the whole scale).

    Parameters
    ----------
    values : (N,) float64
        Rendered values, 0..255 (see :func:`measure_values`).
    levels : (L,) float64
        The channel's levels, already reassigned: every level is a fixed point of the curve.

    Returns
    -------
    (K, 2) float64
        Knots (x, y) on 0..255 (model.py, Tone): x strictly increasing, y non-decreasing,
        (l, l) among them for every level l. Inside band k the curve is the cumulative
        distribution of the values found there, scaled onto [l_{k-1}, l_k] (onto
        [-0.5, l_0] and [l_{L-1}, 255.5] at the ends, clipped to 0..255), with the
        atoms of the module docstring.
    """
    v = np.clip(np.asarray(values, dtype=np.float64), 0.0, 255.0)
    uv, counts = np.unique(v, return_counts=True)
    uw = counts / max(v.shape[0], 1)
    levels = np.asarray(levels, dtype=np.float64)
    if levels.ndim != 1 or not np.all(np.diff(levels) > 0) or (levels.size and not 0 < levels[0] <= levels[-1] < 255):
        raise OptionError("levels must be strictly increasing inside (0, 255)")
    ext_x = np.concatenate([[0.0], levels, [255.0]])
    ext_y = np.concatenate([[-0.5], levels, [255.5]])
    # values in [l_{k-1}, l_k) belong to band k; the top band keeps 255 itself
    cut = np.searchsorted(uv, ext_x, side="left")
    cut[-1] = uv.shape[0]
    xs, ys = [], []
    n_bands = ext_x.shape[0] - 1
    for b in range(n_bands):
        xa, xb, ya, yb = ext_x[b], ext_x[b + 1], ext_y[b], ext_y[b + 1]
        bv, bw = uv[cut[b] : cut[b + 1]], uw[cut[b] : cut[b + 1]]
        total = bw.sum()
        if bv.size == 0 or total <= 0.0:
            x, y = np.array([xa, xb]), np.array([ya, yb])
        else:
            hi = np.cumsum(bw) / total
            x, y = _band_curve(bv, hi - bw / total, hi, total, xa, xb, ya, yb)
        keep = _simplify(x, np.clip(y, 0.0, 255.0), KNOT_TOLERANCE)
        x, y = x[keep], y[keep]
        if xs:
            x, y = x[1:], y[1:]  # the shared level knot
        xs.append(x)
        ys.append(y)
    return np.stack([np.concatenate(xs), np.clip(np.concatenate(ys), 0.0, 255.0)], axis=1)


def with_tone(channel: Channel, width: int, height: int) -> Channel:
    """The channel with the tone curve that makes its rendered histogram rectangular (see
    the module docstring); levels, caps and contours unchanged."""
    if channel.levels.shape[0] == 0:
        return replace(channel, tone=None)
    # one curve over the whole scale (no fixed level knots): see the module docstring
    return replace(channel, tone=tone_curve(measure_values(channel, width, height), np.zeros(0)))


# =============================================================================================
# The operation
# =============================================================================================


def equalise(vi: VectorImage, refine_render: bool = True, info: dict | None = None) -> VectorImage:
    """Histogram-equalise a vector image's luminance by level reassignment (§5).

    Parameters
    ----------
    vi : VectorImage
    refine_render : bool
        After the exact-area reassignment, make the Y channel's caps domes (cap_ramp DOME,
        model.py), render it (at 1x and 2x) and give it the tone curve that makes the
        rendered distribution uniform. With False only the exact areas are used:
        no rendering, instant, no tone curve, caps as they were.
    info : dict, optional
        Filled with ``area_above`` (fraction of the image >= each old level),
        ``old_levels``, ``new_levels``, ``tone_knots`` (0 without a tone curve) and, with
        refinement, ``measured``: :func:`histogram_stats` of the equalised Y channel
        rendered at 1x.

    Returns
    -------
    VectorImage
        Same contours; the Y channel's levels and cap values reassigned and (with
        refinement) its tone curve set; any earlier tone curve of Y is replaced. U, V and A
        as they were.
    """
    if not isinstance(vi, VectorImage):
        raise OptionError(f"expected a VectorImage, got {type(vi).__name__}")
    y = vi.channel("Y")
    w, h = vi.width, vi.height
    eq = replace(reassign_levels(y, w, h), tone=None)
    details = {
        "area_above": (level_areas(y, w, h) / (float(w) * float(h))).tolist(),
        "old_levels": y.levels.tolist(),
    }
    if refine_render and y.levels.shape[0]:
        eq = with_tone(replace(eq, cap_ramp=DOME), w, h)
        details["measured"] = histogram_stats(_render_channel(eq, w, h))
    details["new_levels"] = eq.levels.tolist()
    details["tone_knots"] = 0 if eq.tone is None else int(eq.tone.shape[0])
    if info is not None:
        info.update(details)
    channels = tuple(eq if ch.name == "Y" else ch for ch in vi.channels)
    meta = dict(vi.meta)
    meta["equalised"] = "levels+tone" if eq.tone is not None else "levels"
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
