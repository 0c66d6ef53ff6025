"""The contours figure (the paper's Fig. 2): one channel's contours over a grey render of it.

Three layers are drawn over the channel's own plane (rendered with the diffusion fill and
shown dimmed, as grey):

- red: the unsmoothed polyline through each chain's on-curve joints (``points[::3]``);
- green: the fitted cubic Bezier chains, flattened to within 1/50 output pixel;
- blue: the stretches that run along the image border (``Channel.border``), which close the
  contours but are not isolines.

Lines are anti-aliased by a small NumPy rasteriser (no Pillow outside imageio.py): each edge
is sampled every quarter of an output pixel and each sample's length is splatted bilinearly
onto the four nearest pixel centres; the accumulated length per pixel is the line's coverage.
"""

from __future__ import annotations

import numpy as np

from .errors import OptionError

DEFAULT_SCALE = 2.0  # output pixels per source pixel: 1-pixel lines need room to be told apart

RED = (225.0, 35.0, 35.0)
GREEN = (30.0, 190.0, 60.0)
BLUE = (50.0, 110.0, 255.0)

BACKGROUND_GAIN = 0.55  # the plane is dimmed into [BACKGROUND_BASE, BASE + 0.55 * 255] so
BACKGROUND_BASE = 60.0  # that red, green and blue lines stand out on it

_STEP = 0.25  # output pixels between samples along a line
_GAIN = 1.3  # coverage of a one-pixel-wide line: sample length per pixel x gain, clipped to 1
_CHUNK = 1 << 22  # samples per batch (bounds memory)


def draw_contours(vi, channel: str = "Y", scale: float = DEFAULT_SCALE, crop=None) -> np.ndarray:
    """Draw one channel's contours over its plane.

    Parameters
    ----------
    vi : VectorImage
    channel : str
        "Y", "U", "V" or "A"; it must be one of ``vi``'s channels.
    scale : float
        Output pixels per source pixel.
    crop : (x, y, w, h) or None
        The rectangle to draw, in source pixels (the whole image by default).

    Returns
    -------
    (H, W, 3) float64 ndarray on 0..255
        RGB; write it with :func:`isophote.imageio.write_image`.
    """
    from dataclasses import replace

    from .model import VectorImage
    from .options import RenderOptions
    from .render import render_float, viewport
    from .geometry import EdgesPen

    names = [c.name for c in vi.channels]
    if channel not in names:
        raise OptionError(f"no channel {channel!r} in this image (it has {', '.join(names)})")
    ch = vi.channel(channel)
    opts = RenderOptions(scale=float(scale), crop=None if crop is None else tuple(crop))
    opts.validate()
    vp = viewport(vi, opts)

    # The channel's own plane: the channel alone, rendered as a grey image.
    alone = VectorImage(width=vi.width, height=vi.height, colour="grey",
                        channels=(replace(ch, name="Y"),), source_depth=vi.source_depth)
    plane = render_float(alone, scale=opts.scale, crop=opts.crop)[..., 0]
    grey = BACKGROUND_BASE + BACKGROUND_GAIN * plane
    out = np.repeat(grey[..., None], 3, axis=2)

    def to_output(x, y):
        # source pixels -> output pixels (the render's sample lattice, see render.Viewport)
        return x * vp.kx - vp.col0 - vp.offx, y * vp.ky - vp.row0 - vp.offy

    pen = EdgesPen(0.02 / max(vp.kx, vp.ky))
    ch.draw(pen)
    segs, iso = pen.segments, ~pen.border
    # red: joint to joint, isoline segments only
    x0, y0 = to_output(segs[iso, 0, 0], segs[iso, 0, 1])
    x1, y1 = to_output(segs[iso, 3, 0], segs[iso, 3, 1])
    _blend(out, coverage(out.shape[:2], x0, y0, x1, y1), RED)
    # green and blue: the curves themselves
    ex0, ey0, ex1, ey1, source = pen.edges()
    x0, y0 = to_output(ex0, ey0)
    x1, y1 = to_output(ex1, ey1)
    _blend(out, coverage(out.shape[:2], x0[source], y0[source], x1[source], y1[source]), GREEN)
    _blend(out, coverage(out.shape[:2], x0[~source], y0[~source], x1[~source], y1[~source]), BLUE)
    return out


def _blend(out: np.ndarray, alpha: np.ndarray, colour) -> None:
    a = alpha[..., None]
    out *= 1.0 - a
    out += a * np.asarray(colour)


def coverage(shape, x0, y0, x1, y1) -> np.ndarray:
    """Anti-aliased coverage in [0, 1] of one-pixel-wide lines.

    Parameters
    ----------
    shape : (H, W)
    x0, y0, x1, y1 : (E,) ndarray
        Edge end points in output pixels (pixel (i, j) is [j, j+1) x [i, i+1), its centre at
        (j + 0.5, i + 0.5)).

    Returns
    -------
    (H, W) float64 ndarray
    """
    h, w = shape
    acc = np.zeros(h * w)
    x0, y0, x1, y1 = (np.asarray(v, dtype=np.float64) for v in (x0, y0, x1, y1))
    # edges wholly outside the picture cost nothing
    keep = ~(
        (np.maximum(x0, x1) < -1) | (np.minimum(x0, x1) > w + 1)
        | (np.maximum(y0, y1) < -1) | (np.minimum(y0, y1) > h + 1)
    )
    x0, y0, x1, y1 = x0[keep], y0[keep], x1[keep], y1[keep]
    length = np.hypot(x1 - x0, y1 - y0)
    n = np.maximum(1, np.ceil(length / _STEP)).astype(np.int64)
    ends = np.cumsum(n)
    start = 0
    while start < len(n):
        # a batch of whole edges holding about _CHUNK samples
        stop = max(start + 1, int(np.searchsorted(ends, ends[start] - n[start] + _CHUNK, side="right")))
        _splat(acc, w, h, x0[start:stop], y0[start:stop], x1[start:stop], y1[start:stop],
               length[start:stop], n[start:stop])
        start = stop
    return np.clip(acc.reshape(h, w) * _GAIN, 0.0, 1.0)


def _splat(acc, w, h, x0, y0, x1, y1, length, n) -> None:
    edge = np.repeat(np.arange(len(n)), n)
    k = np.arange(edge.size) - np.repeat(np.cumsum(n) - n, n)
    t = (k + 0.5) / n[edge]
    # sample positions relative to the pixel-centre lattice
    px = x0[edge] + t * (x1 - x0)[edge] - 0.5
    py = y0[edge] + t * (y1 - y0)[edge] - 0.5
    weight = (length / n)[edge]
    ix, iy = np.floor(px).astype(np.int64), np.floor(py).astype(np.int64)
    fx, fy = px - ix, py - iy
    for dx, dy, wgt in (
        (0, 0, (1 - fx) * (1 - fy)),
        (1, 0, fx * (1 - fy)),
        (0, 1, (1 - fx) * fy),
        (1, 1, fx * fy),
    ):
        cx, cy = ix + dx, iy + dy
        ok = (cx >= 0) & (cx < w) & (cy >= 0) & (cy < h)
        acc += np.bincount(cy[ok] * w + cx[ok], weights=(weight * wgt)[ok], minlength=h * w)
