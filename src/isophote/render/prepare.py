"""The per-master preparation that tiles share (VectorImage.prepare, render/tiles.py).

Without it every render builds what it needs and lets it go. With it (``prepare(vi)``,
kept with the VectorImage until it is collected) renders and tiles reuse, per channel:
- each segment's first control point in the chains (4 bytes a segment);
- each level's ChannelLevel (one per zoom): its segment index (segment_index.py: the
  segments that cross its node rows or columns or its sample rows, as a list of their ids
  per block, about 4 bytes a kept segment; their boxes are computed where tested) and for
  a blocked level the canvas-wide regions (6 bytes a node: 96 MB a channel at 1x for 16 MP). Making one costs a pass over
  the channel's segments, flattened and rasterised on the level's node rows (no crossings)
  and a labelling of the level: about a fifth of a render's geometry at that zoom;
- for a blocked level that crops read, the windings of every sample row left of each
  128-column bin (4 bytes a row and bin: 0.5 MB a channel at 1x for 16 MP, 33 MB at 8:1;
  one more pass over the segments), so that a tile rasterises its own columns only, and
  its coarse field (blocks.ChannelLevel.coarse_field: at most COARSE_NODES = 500,000 nodes,
  48 bytes each; the fields of a one-window level at a node every k; one a channel for the
  levels that share its grid, as 1x, 2x, 4x and 8x do: 12 MB a channel for Kite's 2560 x
  1600), which every window's cut edges read;
- for a one-window level, its edges by buckets of the canvas's sample rows
  (strips.canvas_buckets: 8 bytes an edge and bucket it reaches), so that a crop maps and
  rasterises the edges of its own rows only;
- for 1x and a reduction prepared with ``prepare(vi, zooms)`` (a zoom at or below 1 whose
  samples are at most one a source pixel: render.plane_lattice), each channel's samples over
  the whole canvas at its lattice (render.make_plane: float32, so at most 4 bytes a canvas
  pixel and channel a lattice; 1x's and those of 1:2, 1:4, 1:8, ... add to at most 28/3
  bytes a pixel and channel; 1:2 and 1:4 share one, every source pixel's centre, as 1x's
  does on a level of its own): a tile there is a copy of its samples and the box filter
  (the same bytes, a crop being the same region of the full render). Making one costs the
  level's block fields once (let go after) and the samples of the whole canvas at that
  lattice: at 1x, a 1x render's work (Kite, 2560 x 1600: 3.7 s); a cold 1x tile then
  costs about 1 ms, not 90 (benchmarks/results/serve_load.md);
- the block fields, least recently used first out, within ``field_bytes`` for every channel
  and zoom together (strips.FieldBudget; WINDOW_BYTES a node of a window). Until 2026-12 it
  was field_bytes a zoom: a 4 MP master served at its nine zooms peaked at 2.4 GB. A render
  lets go of the blocks it read whole (strips.covered_blocks: a tile on its grid above 1x);
- none of the allocator's settings: every render of a prepared master sets the tiles' own
  (shared/heap.keep_freed_memory), so a tile's windows reuse the pages the last one freed.
Which zooms are prepared at once is the caller's choice (default 1x); the others are
prepared by the first tile that needs them, without the planes.
"""

from __future__ import annotations

import threading
import weakref

from .strips import FieldBudget

_PREPARED: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()
FIELD_BYTES = 384 * 2**20  # block fields kept by a preparation, all channels and levels


class Preparation:
    def __init__(self, field_bytes: int = FIELD_BYTES):
        self.field_bytes = field_bytes
        self.budget = FieldBudget(field_bytes)  # every channel's and zoom's block fields together
        self.edges, self.levels, self.caches, self.windings, self.planes, self.coarse = {}, {}, {}, {}, {}, {}
        self.lock = threading.Lock()

    def get(self, table: dict, key, make):
        with self.lock:
            lock = table.setdefault(("lock", key), threading.Lock())
        with lock:
            if key not in table:
                table[key] = make()
            return table[key]


def prepared(vi):
    """The VectorImage's preparation, or None."""
    return _PREPARED.get(vi)


def prepare(vi, zooms=(1.0,), field_bytes: int = FIELD_BYTES, planes: bool = True) -> Preparation:
    """Prepare (once) what renders of ``vi`` at these zooms (output pixels per source pixel)
    share, and keep it with ``vi``; later renders and tiles reuse it. ``planes``: also the
    sample planes of the reductions among them (see the module docstring)."""
    from .. import threads
    from . import _plane_key, channel_state, make_plane, plane_lattice, prepared_buckets, prepared_windings, viewport
    from ..options import RenderOptions
    from .distance import MODES

    prep = _PREPARED.get(vi)
    if prep is None:
        prep = _PREPARED[vi] = Preparation(field_bytes)
    for z in zooms:
        opts = RenderOptions(scale=float(z), max_pixels=2**62)
        vp = viewport(vi, opts)
        for ch in vi.channels:
            cl, _ = channel_state(vi, ch, vp, opts, prep)
            if cl.level.block:  # what its crops (tiles) read
                prepared_windings(vi, ch, cl, vp, prep)
                cl.coarse_dmax(MODES[opts.distance])  # its coarse field (made with it) and regions' d_max
            else:
                prepared_buckets(vi, ch, cl, vp, prep)
        if planes and plane_lattice(vi, vp) is not None:  # a reduction: its samples, once
            def plane(ch, vp=vp, opts=opts):
                prep.get(prep.planes, _plane_key(vi, ch, vp, opts), lambda: make_plane(vi, ch, vp, opts, prep))

            with threads.pool(threads.available(len(vi.channels))) as pool:
                list(pool.map(plane, vi.channels))
    return prep
