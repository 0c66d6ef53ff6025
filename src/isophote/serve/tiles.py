"""Masters and their tiles: the one place the server renders.

Coordinates: source pixels of the master, x to the right, y down, origin at the top-left
corner; pixel (i, j) is the unit square [j, j+1) x [i, i+1), its sample at the centre. A tile
is a region (x, y, w, h) of the master rendered to (out_w, out_h) output pixels: exactly
``VectorImage.render(crop=region, width=out_w, height=out_h)``, which equals the same region
of the full render at that scale, so tiles of one level join seamlessly.

render_tile is the function to swap when a region-bounded renderer arrives (today a crop
still computes the distance grid over the whole canvas: benchmarks/results/serve_load.md).
"""

from __future__ import annotations

import hashlib
import os
import threading
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

FILLS = ("diffusion", "flat")
CONTOUR_RGB = (255.0, 64.0, 32.0)  # the Y contours over the image
CONTOUR_TOL = 0.05 / 64  # source pixels: fine enough for 1/20 output pixel at 64x


@dataclass
class Master:
    """One served .isoph file: loaded once, its preparation shared by every request."""

    id: str
    path: str
    vi: object
    etag: str  # of the file's bytes: tiles' ETags derive from it
    original: str | None = None  # a raster to show beside it
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)
    _contours: tuple | None = field(default=None, repr=False)

    @property
    def width(self) -> int:
        return int(self.vi.width)

    @property
    def height(self) -> int:
        return int(self.vi.height)

    def contour_edges(self):
        """The Y channel's isolines flattened once (x0, y0, x1, y1 arrays, source pixels)."""
        with self._lock:
            if self._contours is None:
                from ..geometry import EdgesPen

                pen = EdgesPen(CONTOUR_TOL)
                self.vi.channel("Y").draw(pen)
                x0, y0, x1, y1, source = pen.edges()
                self._contours = tuple(np.ascontiguousarray(v[source]) for v in (x0, y0, x1, y1))
            return self._contours


def load_master(path, original=None) -> Master:
    """Load one .isoph (InputError on a bad file); its id is the file's stem."""
    import isophote

    path = os.fspath(path)
    vi = isophote.load(path)
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    stem = os.path.splitext(os.path.basename(path))[0]
    return Master(stem, path, vi, h.hexdigest()[:16], original)


def find_masters(path) -> list:
    """The .isoph file PATH, or every .isoph in the folder PATH (sorted)."""
    path = os.fspath(path)
    if os.path.isdir(path):
        names = sorted(n for n in os.listdir(path) if n.endswith(".isoph"))
        if not names:
            raise InputError(f"{path}: no .isoph files in this folder")
        return [os.path.join(path, n) for n in names]
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file or folder")
    return [path]


NODE_CHANNEL_BYTES = 120  # peak bytes of one render: a distance node of one channel,
POINT_BYTES = 700  # and a control point of the master (the crossings its contours make)


def render_bytes(master: Master) -> int:
    """Peak bytes one render_tile of this master may take, whatever the tile: today the
    distance grid spans the canvas (up to max(NODE_BUDGET, w x h) nodes a channel, the
    channels' grids built at once), and the contours' crossings with it follow the master's
    points. Fitted on two masters, one render at a time: a 5.2 MP art crop (5.2 M nodes, 0.58 M
    points) 2.2 GB a render (4.4 GB peak RSS with two), the 16 MP mosaic (16.4 M nodes, 16.6 M
    points) 17.6 GB peak over tiles at 1:8, 1:1 and 8:1; this gives 2.8 and 17.8 GB."""
    from .. import render

    nodes = max(getattr(render, "NODE_BUDGET", 6_000_000), master.width * master.height)
    points = sum(len(c.points) for c in master.vi.channels)
    return nodes * NODE_CHANNEL_BYTES * len(master.vi.channels) + points * POINT_BYTES + (256 << 20)


def render_tile(master: Master, region, size, fill: str = "diffusion") -> np.ndarray:
    """(out_h, out_w, C) uint8: the region (x, y, w, h) rendered to size (out_w, out_h)."""
    w, h = size
    vi = master.vi
    # The renderer's memory estimate is checked against max_pixels (render/limits_render.py):
    # allow what this master needs; the output itself is bounded by iiif.MAX_AREA before this
    # is called. vi.tile renders through the master's preparation (render/prepare.py), so
    # tiles of one zoom share their levels' edges, regions and block fields.
    budget = max(100_000_000, 8 * 9 * vi.width * vi.height)
    a = vi.tile(tuple(float(v) for v in region), (int(w), int(h)), fill=fill, max_pixels=budget)
    return a[..., None] if a.ndim == 2 else a


def render_contours(master: Master, region, size) -> np.ndarray:
    """(out_h, out_w, 4) uint8: the Y contours of the region as lines on transparent ground."""
    from ..overlay import coverage

    x, y, w, h = region
    ow, oh = size
    kx, ky = ow / w, oh / h
    x0, y0, x1, y1 = master.contour_edges()
    mx, my = 2.0 / kx, 2.0 / ky  # a line reaches a pixel or so beyond its centre
    keep = ~(
        (np.maximum(x0, x1) < x - mx) | (np.minimum(x0, x1) > x + w + mx)
        | (np.maximum(y0, y1) < y - my) | (np.minimum(y0, y1) > y + h + my)
    )
    cov = coverage((oh, ow), (x0[keep] - x) * kx, (y0[keep] - y) * ky, (x1[keep] - x) * kx, (y1[keep] - y) * ky)
    out = np.empty((oh, ow, 4), np.uint8)
    out[..., :3] = np.asarray(CONTOUR_RGB, np.uint8)
    out[..., 3] = np.rint(cov * 255.0).astype(np.uint8)
    return out
