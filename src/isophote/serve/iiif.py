"""IIIF Image API 3.0 request parsing and info.json, as pure functions.

A tile URL is ``{region}/{size}/{rotation}/{quality}.{format}``
(https://iiif.io/api/image/3.0/#4-image-requests). Coordinates are the master's source
pixels: x to the right, y down, origin at the top-left corner of the image.

Supported (compliance level 1, plus):
- region: ``full``, ``square`` (the centred square of the shorter side), ``x,y,w,h``,
  ``pct:x,y,w,h``. A region partly outside the image is cut to it; wholly outside is a 400.
- size: ``max``, ``w,``, ``,h``, ``w,h``, ``!w,h``, ``pct:n``, and each with a leading ``^``,
  which allows sizes above the region's (a vector master renders them natively).
- rotation ``0``; quality ``default`` or ``color``; format ``png`` or ``jpg``.

Every output is limited to MAX_AREA pixels and MAX_SIDE pixels a side (declared in
info.json as maxArea, maxWidth, maxHeight); ``max`` and ``^max`` are scaled down to fit them,
and any explicit size above them is a 400 naming the limit.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

MAX_AREA = 4096 * 1024  # output pixels of one request (4 MP: 16 MB of RGB samples)
MAX_SIDE = 8192  # output pixels on either side
TILE = 512  # the tile size info.json declares
FORMATS = {"png": "image/png", "jpg": "image/jpeg"}
QUALITIES = ("default", "color")
CONTEXT = "http://iiif.io/api/image/3/context.json"


class RequestError(ValueError):
    """A malformed or unsatisfiable request: the server answers 400 with this message."""


@dataclass(frozen=True)
class TileRequest:
    region: tuple  # (x, y, w, h) in source pixels, integers, inside the image
    size: tuple  # (width, height) of the output in pixels
    quality: str
    format: str

    @property
    def media_type(self) -> str:
        return FORMATS[self.format]


_INT = r"\d+"
_NUM = r"\d+(?:\.\d+)?|\.\d+"


def parse_region(text: str, width: int, height: int) -> tuple:
    """The region of the request as (x, y, w, h) integers inside the width x height image."""
    if text == "full":
        return 0, 0, width, height
    if text == "square":
        side = min(width, height)
        return (width - side) // 2, (height - side) // 2, side, side
    if text.startswith("pct:"):
        m = re.fullmatch(rf"({_NUM}),({_NUM}),({_NUM}),({_NUM})", text[4:])
        if not m:
            raise RequestError(f"region {text!r}: pct: needs four numbers x,y,w,h")
        px, py, pw, ph = (float(v) for v in m.groups())
        if pw <= 0 or ph <= 0:
            raise RequestError(f"region {text!r}: width and height must be positive")
        x, y = math.floor(px * width / 100), math.floor(py * height / 100)
        w = max(1, round(pw * width / 100))
        h = max(1, round(ph * height / 100))
    else:
        m = re.fullmatch(rf"(-?{_INT}),(-?{_INT}),(-?{_INT}),(-?{_INT})", text)
        if not m:
            raise RequestError(f"region {text!r}: expected full, square, x,y,w,h or pct:x,y,w,h")
        x, y, w, h = (int(v) for v in m.groups())
        if x < 0 or y < 0:
            raise RequestError(f"region {text!r}: x and y must not be negative")
        if w <= 0 or h <= 0:
            raise RequestError(f"region {text!r}: width and height must be positive")
    if x >= width or y >= height:
        raise RequestError(f"region {text!r} lies outside the {width}x{height} image")
    return x, y, min(w, width - x), min(h, height - y)


def _fit_limits(w: float, h: float) -> tuple:
    """Scale (w, h) down, keeping its aspect, to within MAX_SIDE and MAX_AREA."""
    k = min(1.0, MAX_SIDE / w, MAX_SIDE / h, math.sqrt(MAX_AREA / (w * h)))
    return max(1, math.floor(w * k)), max(1, math.floor(h * k))


def parse_size(text: str, rw: int, rh: int) -> tuple:
    """The output (width, height) for a region of rw x rh source pixels."""
    up = text.startswith("^")
    body = text[1:] if up else text
    if body == "max":
        if up:  # as large as the limits allow
            return _fit_limits(rw * MAX_SIDE, rh * MAX_SIDE)
        return _fit_limits(rw, rh)
    if body.startswith("pct:"):
        if not re.fullmatch(_NUM, body[4:]):
            raise RequestError(f"size {text!r}: pct: needs a number")
        n = float(body[4:])
        if n <= 0:
            raise RequestError(f"size {text!r}: must be positive")
        if n > 100 and not up:
            raise RequestError(f"size {text!r}: above 100% needs the ^ form (^pct:n)")
        w, h = max(1, round(rw * n / 100)), max(1, round(rh * n / 100))
    else:
        confined = body.startswith("!")
        m = re.fullmatch(r"(-?\d*),(-?\d*)", body[1:] if confined else body)
        if not m or (m.group(1) == "" and m.group(2) == "") or (confined and "" in m.groups()):
            raise RequestError(f"size {text!r}: expected max, w,, ,h, w,h, !w,h or pct:n (each may start with ^)")
        gw, gh = (int(v) if v else None for v in m.groups())
        if (gw is not None and gw <= 0) or (gh is not None and gh <= 0):
            raise RequestError(f"size {text!r}: width and height must be positive")
        if confined:
            k = min(gw / rw, gh / rh)
            w, h = max(1, math.floor(rw * k + 1e-9)), max(1, math.floor(rh * k + 1e-9))
        elif gh is None:  # the height keeps the aspect, rounded as the renderer rounds it
            w, h = gw, max(1, round(rh * gw / rw))
        elif gw is None:
            w, h = max(1, round(rw * gh / rh)), gh
        else:
            w, h = gw, gh
        if not up and (w > rw or h > rh):
            raise RequestError(
                f"size {text!r}: {w}x{h} is larger than the {rw}x{rh} region; use the ^ form to enlarge"
            )
    if w > MAX_SIDE or h > MAX_SIDE or w * h > MAX_AREA:
        raise RequestError(
            f"size {text!r}: {w}x{h} exceeds the limit of {MAX_AREA} pixels ({MAX_SIDE} a side) a request"
        )
    return w, h


def parse_request(region: str, size: str, rotation: str, quality_format: str, width: int, height: int) -> TileRequest:
    """Parse the four path segments after the id into a TileRequest (RequestError if bad)."""
    quality, dot, fmt = quality_format.rpartition(".")
    if not dot or not quality:
        raise RequestError(f"{quality_format!r}: expected {{quality}}.{{format}}, e.g. default.png")
    if quality not in QUALITIES:
        raise RequestError(f"quality {quality!r} is not supported (only {', '.join(QUALITIES)})")
    if fmt not in FORMATS:
        raise RequestError(f"format {fmt!r} is not supported (only {', '.join(FORMATS)})")
    if rotation not in ("0", "0.0"):
        raise RequestError(f"rotation {rotation!r} is not supported (only 0)")
    x, y, w, h = parse_region(region, width, height)
    return TileRequest((x, y, w, h), parse_size(size, w, h), quality, fmt)


def scale_factors(width: int, height: int, tile: int = TILE) -> list:
    """1, 2, 4, ... up to the factor at which the whole image fits one tile."""
    out, f = [1], 1
    while max(width, height) / f > tile:
        f *= 2
        out.append(f)
    return out


def info(image_id: str, width: int, height: int, tile: int = TILE) -> dict:
    """The info.json document: the master's own size, its tiles, and what it can serve."""
    return {
        "@context": CONTEXT,
        "id": image_id,
        "type": "ImageService3",
        "protocol": "http://iiif.io/api/image",
        "profile": "level1",
        "width": int(width),
        "height": int(height),
        "maxWidth": MAX_SIDE,
        "maxHeight": MAX_SIDE,
        "maxArea": MAX_AREA,
        "tiles": [{"width": tile, "height": tile, "scaleFactors": scale_factors(width, height, tile)}],
        "extraFormats": ["png"],
        "extraQualities": ["color"],
        "extraFeatures": ["sizeUpscaling", "regionByPct", "sizeByPct", "sizeByConfinedWh"],
    }
