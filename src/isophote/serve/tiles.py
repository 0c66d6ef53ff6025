"""Masters and their tiles: the one place the server renders.

Coordinates: source pixels of the master, x to the right, y down, origin at the top-left
corner; pixel (i, j) is the unit square [j, j+1) x [i, i+1), its sample at the centre. A tile
is a region (x, y, w, h) of the master rendered to (out_w, out_h) output pixels: exactly
``VectorImage.render(crop=region, width=out_w, height=out_h)``, which equals the same region
of the full render at that scale, so tiles of one level join seamlessly.

A tile reads the master's preparation (render/prepare.py): prepare_master makes it for
every level of the viewer's pyramid at once (the server does at start, off the event loop),
after which a tile costs its own blocks' fields and samples (benchmarks/results/serve_load.md).
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
    vi = isophote.load(path, compact=True)  # only rendered, and its contours drawn in float64
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


def level_zooms(master: Master, zoom: int) -> list:
    """Output pixels per source pixel of the viewer pyramid's levels (dzi.py), top first,
    down to 1:64 or further while a level is larger than one tile (those below cost nothing)."""
    from . import dzi

    top = dzi.top_level(master.width, master.height, zoom)
    out = []
    for level in range(top, -1, -1):
        lw, lh = dzi.level_size(master.width, master.height, zoom, level)
        m = zoom / 2 ** (top - level)
        if m < 1 / 64 and max(lw, lh) <= dzi.TILE:
            break
        out.append(m)
    return out


def render_bytes(master: Master, zoom: int = 16) -> int:
    """Peak bytes one render_tile of this master may take: the renderer's own estimate
    (render/limits_render.py, the one it checks before it starts) for a full 256-px tile at
    each level of the viewer's pyramid, the largest, with the master's preparation counted
    in (its regions and kept blocks); plus 64 MiB for the encode and the request."""
    from .. import render
    from ..options import RenderOptions
    from ..render.limits_render import render_bytes as estimate
    from . import dzi

    vi = master.vi
    worst = 0
    for m in level_zooms(master, zoom):
        w, h = min(master.width, dzi.TILE / m), min(master.height, dzi.TILE / m)
        opts = RenderOptions(crop=(0.0, 0.0, w, h), width=max(1, round(w * m)), height=max(1, round(h * m)),
                             max_pixels=2**62)
        vp = render.viewport(vi, opts)
        levels = [render.channel_state(vi, ch, vp, opts, plan_only=True)[0] for ch in vi.channels]
        worst = max(worst, estimate(vi, vp, levels, 8, True))
    return worst + (64 << 20)


def prepare_master(master: Master, zoom: int = 16) -> float:
    """Prepare every level of the viewer's pyramid (render/prepare.py: segment indexes,
    canvas-wide regions, crop windings), so that no tile request pays for its level's;
    returns the seconds it took. Tiles asked for meanwhile wait for their level's part."""
    import time

    t = time.perf_counter()
    master.vi.prepare(level_zooms(master, zoom))
    return time.perf_counter() - t


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


def is_copy(master: Master, region, size, fill: str = "diffusion") -> bool:
    """Whether render_tile(master, region, size, fill) copies its samples from the master's
    preparation (1x and the reductions, render/prepare.py): about a millisecond, so the
    server runs it in its copy lane rather than behind the renders (app.Renderer)."""
    from ..render import copies_prepared_samples

    w, h = size
    return copies_prepared_samples(master.vi, width=int(w), height=int(h), crop=tuple(float(v) for v in region),
                                   fill=fill, max_pixels=2**62)


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
