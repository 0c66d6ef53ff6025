"""Tiles of a master: ``Tiler(vi).tile(x, y, w, h, out_w, out_h)`` (or ``vi.tile``).

A tile is exactly ``vi.render(crop=(x, y, w, h), width=out_w, height=out_h, **options)``:
the same call, reading the master's preparation (prepare.py: the segments, each level's
block index and canvas-wide regions, and the block fields recently used), so a tile costs
the blocks under it, once computed. Tiles of one zoom (the same out_w / w and out_h / h,
their origins on that zoom's pixel lattice) join seamlessly, since every crop at one scale
is the same region of the full render.

Preparation cost (VectorImage.prepare, or the first tile of a zoom): per channel and zoom a
segment index, the canvas-wide regions and the row windings (prepare.py gives the bytes and
passes), and for the reductions among the zooms given, the samples of the whole canvas at
their lattices. Block fields are kept within prepare.FIELD_BYTES (384 MB), every channel and
zoom together. After that
a tile at or above 1x reads the segments of its own blocks and columns only: its cost is its
windows' fields and its samples, whatever the canvas; a tile of a prepared reduction copies
and box-filters its samples. A render lets go of the fields of the blocks it read whole
(above 1x a tile on its zoom's grid reads one block, which no other tile reads) and keeps
those it read in part for its neighbours.
"""

from __future__ import annotations

from .prepare import FIELD_BYTES, prepare


class Tiler:
    """Tiles of ``vi`` with fixed render options (fill, distance, sharpen, depth, ...)."""

    def __init__(self, vi, zooms=(), field_bytes: int = FIELD_BYTES, **options):
        self.vi, self.options = vi, options
        self.preparation = prepare(vi, zooms, field_bytes)

    def tile(self, x, y, w, h, out_w: int, out_h: int):
        """The crop (x, y, w, h) of the master (source pixels) rendered to out_w x out_h."""
        from . import render

        return render(self.vi, width=int(out_w), height=int(out_h), crop=(x, y, w, h), **self.options)
