"""The peers isophote is measured against, each run in the same process as isophote.

- vtracer (``vtracer`` on PyPI, visioncortex) traced with settings for photographs and
  rendered back with resvg (``resvg-py``): the other raster-to-vector codec.
- PNG, JPEG and WebP through Pillow: what a photograph is normally stored as.
- bilinear, bicubic and Lanczos resizing through Pillow: what upscaling normally is.

Every function takes an (H, W, 3) or (H, W) uint8 array and returns arrays of the same
shape (uint8), so that isophote.metrics can compare them with the original directly.
Times are wall-clock seconds of the codec call alone (array <-> codec-input conversions
are left out, file encoding inside a library call is not), the best of ``repeat`` calls:
single calls of a millisecond codec are too noisy to divide by.
"""

from __future__ import annotations

import gzip
import io
import math
import time

import numpy as np

JPEG_QUALITIES = (50, 70, 80, 90, 95)
WEBP_QUALITIES = (50, 70, 80, 90, 95)

# vtracer's colour settings for photographs: its documented defaults, but for
# path_precision 2 instead of 8 (two decimals are plenty at pixel scale; more digits only
# inflate the SVG). The report prints this dict as it was used.
VTRACER_SETTINGS = dict(
    colormode="color",
    hierarchical="stacked",
    mode="spline",
    filter_speckle=4,
    color_precision=6,
    layer_difference=16,
    corner_threshold=60,
    length_threshold=4.0,
    max_iterations=10,
    splice_threshold=45,
    path_precision=2,
)

# The vtracer settings measured: name -> overrides of VTRACER_SETTINGS, from the base
# settings to finer colour, so that vtracer gets a rate-distortion curve like JPEG's.
# color_precision is the number of significant bits kept per RGB channel (6 posterises a
# photograph to about 23-25 dB PSNR), layer_difference the colour step between stacked
# layers.
VTRACER_PRESETS = {
    "cp6-ld16": {},
    "cp8-ld16": dict(color_precision=8),
    "cp8-ld4": dict(color_precision=8, layer_difference=4),
}


def _rgb(img: np.ndarray) -> np.ndarray:
    return np.repeat(img[..., None], 3, axis=2) if img.ndim == 2 else img


def match_channels(decoded, img: np.ndarray) -> np.ndarray:
    """A decoded (H, W) or (H, W, 1, 3 or 4) array, on 0..255, as uint8 with ``img``'s channels.

    Samples are rounded (what an 8-bit file would hold). Alpha is composited over mid-grey
    (never present in practice: vtracer's stacked mode starts with a full-frame rectangle);
    grey is recovered as the mean of R, G, B, which is exact for R = G = B.
    """
    a = np.asarray(decoded, dtype=np.float64)
    if a.ndim == 2:
        a = a[..., None]
    if a.shape[2] in (2, 4):
        alpha = a[..., -1:] / 255.0
        a = a[..., :-1] * alpha + 127.5 * (1.0 - alpha)
    if img.ndim == 2:
        a = a.mean(axis=2)
    elif a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    return np.clip(np.rint(a), 0, 255).astype(np.uint8)


def best_of(fn, repeat: int = 1):
    """(result of the last call, least seconds) over ``repeat`` calls of ``fn()``."""
    best, out = math.inf, None
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


# --------------------------------------------------------------------------- vtracer


def vtracer_peer(img: np.ndarray, repeat: int = 1, **settings) -> dict:
    """Trace ``img`` with vtracer, render it back at the same size with resvg.

    Returns
    -------
    dict
        bytes_svg : size of the SVG text (UTF-8).
        bytes_svgz : size of the gzipped SVG (level 9, mtime 0: deterministic).
        encode_s : seconds in ``vtracer.convert_pixels_to_svg``.
        render_s : seconds in ``resvg_py.svg_to_bytes`` (rasterise and PNG-encode) plus
            the PNG decode.
        render : decoded pixels, same shape and dtype as ``img``.
        svg : the SVG text.
    """
    import resvg_py
    import vtracer
    from PIL import Image

    options = {**VTRACER_SETTINGS, **settings}
    h, w = img.shape[:2]
    rgba = np.dstack([_rgb(img), np.full((h, w), 255, np.uint8)])
    pixels = [tuple(p) for p in rgba.reshape(-1, 4).tolist()]

    svg, encode_s = best_of(
        lambda: vtracer.convert_pixels_to_svg(pixels, size=(w, h), **options), repeat
    )

    def render():
        png = resvg_py.svg_to_bytes(svg_string=svg, width=w, height=h)
        with Image.open(io.BytesIO(bytes(png))) as im:
            return np.asarray(im.convert("RGBA"))

    decoded, render_s = best_of(render, repeat)

    data = svg.encode("utf-8")
    return dict(
        bytes_svg=len(data),
        bytes_svgz=len(gzip.compress(data, compresslevel=9, mtime=0)),
        encode_s=encode_s,
        render_s=render_s,
        render=match_channels(decoded, img),
        svg=svg,
    )


# --------------------------------------------------------------------------- rasters


def _pillow_roundtrip(img: np.ndarray, fmt: str, repeat: int, **kwargs):
    from PIL import Image

    im = Image.fromarray(np.ascontiguousarray(img))

    def encode():
        buf = io.BytesIO()
        im.save(buf, format=fmt, **kwargs)
        return buf.getvalue()

    def decode():
        with Image.open(io.BytesIO(data)) as out:
            out.load()
            return np.asarray(out)

    data, enc = best_of(encode, repeat)
    decoded, dec = best_of(decode, repeat)
    return data, decoded, enc, dec


def raster_peers(img: np.ndarray, jpeg=JPEG_QUALITIES, webp=WEBP_QUALITIES, repeat: int = 3) -> list:
    """PNG (lossless, optimize), JPEG and WebP (lossy) round trips through Pillow.

    JPEG uses Pillow's defaults besides quality (4:2:0 chroma subsampling for colour,
    baseline); WebP is lossy at Pillow's default method 4.

    Returns
    -------
    list of dict
        codec, quality (None for PNG), bytes, encode_s, decode_s, decoded (same shape and
        dtype as ``img``).
    """
    rows = []
    runs = [("PNG", None, dict(optimize=True))]
    runs += [("JPEG", q, dict(quality=q)) for q in jpeg]
    runs += [("WebP", q, dict(quality=q)) for q in webp]
    for codec, q, kwargs in runs:
        fmt = "WEBP" if codec == "WebP" else codec
        data, decoded, enc, dec = _pillow_roundtrip(img, fmt, repeat, **kwargs)
        rows.append(
            dict(codec=codec, quality=q, bytes=len(data), encode_s=enc, decode_s=dec,
                 decoded=match_channels(decoded, img))
        )
    return rows


# --------------------------------------------------------------------------- upscaling


UPSCALERS = ("bilinear", "bicubic", "lanczos")


def upscale_peers(small: np.ndarray, factor: float, repeat: int = 3) -> dict:
    """Upscale by ``factor`` with Pillow's bilinear, bicubic and Lanczos filters.

    The output is ``round(W * factor) x round(H * factor)``.

    Returns
    -------
    dict
        filter name -> uint8 array; ``"<name>_s"`` -> seconds for that resize.
    """
    from PIL import Image

    h, w = small.shape[:2]
    size = (max(1, round(w * factor)), max(1, round(h * factor)))
    im = Image.fromarray(np.ascontiguousarray(small))
    filters = {
        "bilinear": Image.Resampling.BILINEAR,
        "bicubic": Image.Resampling.BICUBIC,
        "lanczos": Image.Resampling.LANCZOS,
    }
    out = {}
    for name, f in filters.items():
        big, out[name + "_s"] = best_of(lambda: im.resize(size, f), repeat)  # noqa: B023
        out[name] = np.asarray(big)
    return out


def downscale(img: np.ndarray, factor: int) -> np.ndarray:
    """Area (box) downscale by an integer factor, cropping the remainder: the small image
    the upscalers start from."""
    h, w = img.shape[:2]
    hh, ww = h // factor, w // factor
    a = img[: hh * factor, : ww * factor].astype(np.float64)
    a = a.reshape(hh, factor, ww, factor, *img.shape[2:]).mean(axis=(1, 3))
    return np.clip(np.rint(a), 0, 255).astype(np.uint8)
