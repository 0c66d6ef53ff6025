"""Delivery sizes and how a master's aspect is reconciled with theirs (``--fit``).

A delivery is a name and an exact output size: the paper's list (its §1: SD, HD, internet,
phone) and today's, or any ``WxH``. Every output has exactly the delivery's size; the fit
says what happens when the master's aspect differs:

- ``pad`` (the default): the whole picture, scaled to fit inside, centred on a canvas of the
  pad colour (letterbox or pillarbox). Nothing is lost and nothing is distorted.
- ``crop``: the picture scaled to cover the canvas and its centre kept: the master's source
  region of the delivery's aspect, centred, rendered at exactly W x H. Nothing is
  distorted; the edges are lost.
- ``stretch``: the whole picture rendered at W x H, distorted when the aspects differ.

Because the master is a vector image, each delivery is rendered at its own size from the
contours (no resampling of another raster).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import OptionError

NAMED = {
    "sd": (768, 576),
    "hd": (1920, 1080),
    "uhd": (3840, 2160),
    "phone": (384, 256),
}
FITS = ("pad", "crop", "stretch")
DEFAULT_FIT = "pad"
MAX_SIDE = 65_536


@dataclass(frozen=True)
class Delivery:
    """A named output size: its folder under OUTDIR is ``name``."""

    name: str
    width: int
    height: int


def parse_size(text: str) -> tuple[int, int] | None:
    """``'1280x720'`` -> (1280, 720); None when ``text`` is not of that form."""
    parts = text.strip().lower().replace("*", "x").split("x")
    if len(parts) != 2 or not all(p.isdigit() for p in parts):
        return None
    return int(parts[0]), int(parts[1])


def parse_deliveries(text) -> tuple[Delivery, ...]:
    """``'sd,hd,640x480'`` (or a list of such names) -> Deliveries, in the order given,
    without repeats. OptionError for an unknown name or a size out of range."""
    names = text.split(",") if isinstance(text, str) else list(text)
    out, seen = [], set()
    for raw in names:
        name = str(raw).strip().lower()
        if not name:
            continue
        if name in NAMED:
            w, h = NAMED[name]
        else:
            size = parse_size(name)
            if size is None:
                raise OptionError(f"unknown delivery {raw!r} (use {', '.join(NAMED)} or WxH, e.g. 1280x720)")
            w, h = size
            name = f"{w}x{h}"
        if not (1 <= w <= MAX_SIDE and 1 <= h <= MAX_SIDE):
            raise OptionError(f"delivery {name} is out of range (sides 1..{MAX_SIDE})")
        if name not in seen:
            seen.add(name)
            out.append(Delivery(name, w, h))
    if not out:
        raise OptionError("no delivery given (use e.g. --deliver sd,hd,uhd,phone)")
    return tuple(out)


@dataclass(frozen=True)
class Placement:
    """How one delivery is made from a master: render ``crop`` (source pixels; None = the
    whole image) at ``render_w`` x ``render_h``, and place it at (``x``, ``y``) on a
    ``width`` x ``height`` canvas (pad only: otherwise the render is the canvas)."""

    width: int
    height: int
    render_w: int
    render_h: int
    x: int = 0
    y: int = 0
    crop: tuple | None = None


def placement(src_w: int, src_h: int, width: int, height: int, fit: str = DEFAULT_FIT) -> Placement:
    """The render and placement that give exactly ``width`` x ``height`` from a
    ``src_w`` x ``src_h`` master under ``fit``."""
    if fit not in FITS:
        raise OptionError(f"fit must be one of {', '.join(FITS)}, got {fit!r}")
    if fit == "stretch" or src_w * height == src_h * width:
        return Placement(width, height, width, height)
    if fit == "pad":
        k = min(width / src_w, height / src_h)
        rw = min(width, max(1, round(src_w * k)))
        rh = min(height, max(1, round(src_h * k)))
        return Placement(width, height, rw, rh, (width - rw) // 2, (height - rh) // 2)
    # crop: the centred source region of the delivery's aspect
    k = max(width / src_w, height / src_h)
    cw, ch = min(src_w, width / k), min(src_h, height / k)
    crop = ((src_w - cw) / 2.0, (src_h - ch) / 2.0, cw, ch)
    return Placement(width, height, width, height, crop=crop)


def pad_samples(pad: tuple, channels: int, depth: int) -> np.ndarray:
    """The pad colour (R, G, B on 0..255) as one output pixel of ``channels`` samples at
    ``depth`` bits: grey images get its Rec. 601 luma; alpha is opaque."""
    r, g, b = (float(v) for v in pad)
    colour = [0.299 * r + 0.587 * g + 0.114 * b] if channels in (1, 2) else [r, g, b]
    colour += [255.0] if channels in (2, 4) else []
    scale, top, dtype = (257.0, 65535, np.uint16) if depth == 16 else (1.0, 255, np.uint8)
    return np.clip(np.rint(np.array(colour) * scale), 0, top).astype(dtype)


def render_delivery(vi, where: Placement, depth: int = 8, pad=(0, 0, 0)) -> np.ndarray:
    """The delivery raster: (height, width, C) uint8 or uint16 (C = the master's samples:
    1 grey, 2 grey+alpha, 3 RGB, 4 RGBA)."""
    kw = {} if where.crop is None else {"crop": where.crop}
    img = vi.render(width=where.render_w, height=where.render_h, depth=depth, **kw)
    if img.ndim == 2:
        img = img[..., None]
    if (where.render_w, where.render_h) == (where.width, where.height):
        return img
    canvas = np.empty((where.height, where.width, img.shape[2]), img.dtype)
    canvas[...] = pad_samples(pad, img.shape[2], depth)
    canvas[where.y : where.y + where.render_h, where.x : where.x + where.render_w] = img
    return canvas
