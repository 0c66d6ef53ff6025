"""The preview of an isophote SVG: every channel's regions painted flat with their band's
value, as isophote's flat-fill render (``render(fill="flat")``) shows them, and the SVG
filter that composes the Y, U and V layers into RGB.

A region's value is the flat fill's: the middle of its band's two levels (render/_kernels/
diffuse.py's ``_mid``), through the channel's tone curve. The band of a contour's region is
its parent region's band plus the contour's winding (model.py: the >= side lies on the
left, so a chain with positive shoelace area, clockwise on screen, has the lower band
inside); the root region's band is ``base_band``. No render is needed.

Composition (yuv images): each of the Y, U and V layers paints its regions as one colour
component (Y in red, U in green, V in blue: ``#yy0000``, ``#00uu00``, ``#0000vv``) over a
rectangle in its root region's value; the U and V layers are blended onto Y with
``mix-blend-mode:lighten`` (the component-wise maximum: each layer is zero in the other
two components, so the result is (Y, U, V) exactly, anti-aliased edges included, since
each component only ever mixes values of its own channel). An ``feColorMatrix`` on the
group then applies colour.py's YUV -> RGB matrix, the offsets of U and V around 128
folded into its constant column. ``color-interpolation-filters="sRGB"`` keeps the filter on
the stored values (no linearRGB round trip). Intermediate layers hold 8 bits per component
in browsers, so the painted values are rounded to integers, after a per-layer offset that
the matrix adds back (layer_offset: band mids are often all half-integers, painted exactly
so): at most 0.5 off in Y, U and V, at most 1.4 in R, G, B after the matrix (resvg and Chromium show region interiors within 2
levels of the flat render: tests/format/test_svg_preview.py). A grey image is its Y layer
painted grey, with no filter.
"""

from __future__ import annotations

import numpy as np

from ...colour import YUV_OFFSET, YUV_TO_RGB
from ...geometry import signed_areas
from ...model import Channel

FILTER_ID = "isophote-yuv"
PREVIEW_ID = "isophote-preview"  # the group of the preview's polylines (to_svg's lines=True)
COMPONENT = {"Y": 0, "U": 1, "V": 2}  # the colour component each chroma layer paints


def band_mids(levels: np.ndarray, bands: np.ndarray) -> np.ndarray:
    """The flat fill's value of every band in ``bands``: the middle of its two levels, a band
    beyond the extreme levels extending the nearest step (as the renderer's ``_mid``)."""
    levels = np.asarray(levels, np.float64)
    nl = levels.shape[0]
    b = np.clip(np.asarray(bands, np.int64), 0, nl)
    if nl == 0:
        return np.full(b.shape, 127.5)
    step_lo = levels[1] - levels[0] if nl > 1 else 10.0
    step_hi = levels[-1] - levels[-2] if nl > 1 else 10.0
    ext = np.concatenate([[levels[0] - step_lo], levels, [levels[-1] + step_hi]])
    return 0.5 * (ext[b] + ext[b + 1])


def region_bands(ch: Channel) -> np.ndarray:
    """(C,) the band inside each contour's own region (its footprint less its children's)."""
    c = ch.n_contours
    if c == 0:
        return np.zeros(0, np.int64)
    wind = -np.sign(signed_areas(ch.points, ch.offsets)).astype(np.int64)  # clockwise: lower band inside
    parent = ch.parent.astype(np.int64).tolist()
    band = [None] * c
    w = wind.tolist()
    base = int(ch.base_band)
    for k in range(c):
        path = []
        j = k
        while j >= 0 and band[j] is None and len(path) <= c:
            path.append(j)
            j = parent[j]
        b = base if j < 0 or band[j] is None else band[j]  # a cycle (never valid) starts from the base
        for j in reversed(path):
            b += w[j]
            band[j] = b
    return np.asarray(band, np.int64)


def region_values(ch: Channel):
    """(root value, (C,) contour region values): the flat fill of every region, float64 on 0..255."""
    bands = np.concatenate([[int(ch.base_band)], region_bands(ch)])
    vals = ch.apply_tone(band_mids(ch.levels, bands))
    return float(vals[0]), vals[1:]


def region_areas(ch: Channel, width: int, height: int) -> np.ndarray:
    """(C + 1,) the area (px²) of the root region and of every contour's own region (its
    footprint less its children's), from the chains' exact areas."""
    a = np.abs(signed_areas(ch.points, ch.offsets)) if ch.n_contours else np.zeros(0)
    par = ch.parent.astype(np.int64)
    inner = np.bincount(par[par >= 0], weights=a[par >= 0], minlength=a.shape[0]) if a.size else a
    return np.maximum(np.concatenate([[width * height - a[par < 0].sum()], a - inner]), 0.0)


OFFSET_STEPS = 16  # the layer offsets tried: multiples of 1/16 in [-1/2, 1/2)


def layer_offset(ch: Channel, width: int, height: int) -> float:
    """The offset o (levels, in [-1/2, 1/2)) that the channel's layer is painted below its
    values, rint(v - o), and that the filter adds back (colour_matrix's ``offsets``): the o
    with the least area-weighted rounding error. Band mids are often all half-integers
    (levels every 6 on half-integers): painted as they are, each band's rounding is half a
    level, one way over a whole smooth sky; o = 1/2 paints them exactly."""
    root, vals = region_values(ch)
    v = np.concatenate([[root], vals])
    w = region_areas(ch, width, height)
    cands = np.arange(-OFFSET_STEPS // 2, OFFSET_STEPS // 2) / OFFSET_STEPS
    err = [(w * (v - o - np.rint(v - o)) ** 2).sum() for o in cands]
    best = int(np.argmin(err))
    return 0.0 if err[best] >= err[OFFSET_STEPS // 2] - 1e-9 * max(1.0, err[OFFSET_STEPS // 2]) else float(cands[best])


def paints(ch: Channel, colour: str, offset: float = 0.0):
    """(root fill, (C,) list of fills): the paint of each region of ``ch`` in the preview,
    its value less ``offset`` (layer_offset) rounded to 8 bits, as grey (grey images) or as
    the channel's component."""
    root, vals = region_values(ch)
    q = np.clip(np.rint(np.concatenate([[root], vals]) - offset), 0, 255).astype(np.int64).tolist()
    if colour == "grey":
        texts = [f"#{v:02x}{v:02x}{v:02x}" for v in q]
    else:
        pos = COMPONENT[ch.name]
        texts = ["#" + "00" * pos + f"{v:02x}" + "00" * (2 - pos) for v in q]
    return texts[0], texts[1:]


# What the filter adds to R, G and B (0..255) before the viewer stores them in 8 bits: Chromium
# rounds there, resvg truncates (measured: tests/format/test_svg_preview.py), so that the exact
# matrix shows in resvg half a level dark on average (0.44 dB off the flat render's PSNR on
# EveningGlow). A quarter level between the two: both within 0.75 of the exact value, with
# mean errors of +-0.25 (benchmarks/results/svg_preview.md).
STORE_OFFSET = 0.25


def colour_matrix(to_srgb=None, offsets=(0.0, 0.0, 0.0)) -> np.ndarray:
    """(4, 5) feColorMatrix rows taking (Y, U, V, 1) on 0..1 to (R, G, B, 1): colour.py's
    YUV -> RGB matrix with U and V's offsets of 128 in the constant column, followed by
    ``to_srgb`` ((3, 4) affine map on 0..255 RGB, icc_affine) when given, plus STORE_OFFSET.
    ``offsets``: what the Y, U and V layers were painted below their values (layer_offset),
    added back before the matrix."""
    lin = YUV_TO_RGB
    const = -(YUV_TO_RGB @ (YUV_OFFSET - np.asarray(offsets, np.float64)))
    if to_srgb is not None:
        a = np.asarray(to_srgb, np.float64)
        lin, const = a[:, :3] @ lin, a[:, :3] @ const + a[:, 3]
    const = const + STORE_OFFSET
    m = np.zeros((4, 5))
    m[:3, :3] = lin
    m[:3, 4] = const / 255.0
    m[3, 3] = 1.0
    return m


ICC_FIT_PIXELS = 65536  # the flat render the ICC fit samples (a 320 x 200 thumbnail of a 1280 x 800)


def icc_affine(vi):
    """(3, 4) affine map A on 0..255 (sRGB ~ A @ (R, G, B, 1)) taking a yuv image's coded
    colours from the ICC profile its meta carries (icc.py) to sRGB, fitted by least squares
    to LittleCMS's conversion of the image's own colours (a flat render of at most
    ICC_FIT_PIXELS); None when the image has no profile other than sRGB, or is grey.

    An SVG filter cannot apply the profile's curves exactly (browsers and resvg keep 8 bits
    between filter primitives, so a linear-light stage would band the shadows), but one
    affine map folds into the YUV -> RGB matrix for free; fitted on the image's colours it
    comes close to LittleCMS, far closer than showing the coded values as sRGB; a fit over
    the whole RGB cube would be worse than nothing, since no single affine map follows the
    gamut's corners (measured: benchmarks/results/design_choices.md#svg-icc-affine)."""
    from ... import icc

    prof = icc.profile_of(vi.meta)
    if prof is None or vi.colour != "yuv" or icc.is_srgb(prof):
        return None
    from ...render import render_float

    scale = min(1.0, float(np.sqrt(ICC_FIT_PIXELS / (vi.width * vi.height))))
    rgb = render_float(vi, fill="flat", scale=scale)[..., :3].reshape(-1, 3)
    try:
        ref = icc.to_srgb(rgb[:, None, :], prof).reshape(-1, 3)
    except ValueError:  # unreadable profile: shown as sRGB
        return None
    x = np.concatenate([rgb, np.ones((rgb.shape[0], 1))], axis=1)
    a, *_ = np.linalg.lstsq(x, ref, rcond=None)
    return a.T


def compose(yuv8: np.ndarray, to_srgb=None, offsets=(0.0, 0.0, 0.0)) -> np.ndarray:
    """What the filter computes for (..., 3) Y, U, V components on 0..255 (8-bit layers):
    the matrix on 0..1 (STORE_OFFSET included), clamped (as feColorMatrix clamps), back on
    0..255, before the viewer's 8-bit store (Chromium rounds it, resvg truncates it)."""
    m = colour_matrix(to_srgb, offsets)
    x = np.asarray(yuv8, np.float64) / 255.0
    rgb = x @ m[:3, :3].T + m[:3, 4]
    return np.clip(rgb, 0.0, 1.0) * 255.0


def filter_def(width: int, height: int, to_srgb=None, offsets=(0.0, 0.0, 0.0)) -> str:
    """The <filter> element composing the Y, U, V group (painted ``offsets`` below their
    values) into RGB (then sRGB: ``to_srgb``)."""
    vals = " ".join(f"{v:.7g}" for v in colour_matrix(to_srgb, offsets).reshape(-1))
    return (f'<filter id="{FILTER_ID}" filterUnits="userSpaceOnUse" x="0" y="0" width="{width}" '
            f'height="{height}" color-interpolation-filters="sRGB">'
            f'<feColorMatrix type="matrix" values="{vals}"/></filter>\n')
