"""The static Deep Zoom pyramid of one master (``isophote tiles``).

Each tile is byte for byte the tile the server answers at /dzi/{id}_files/{level}/{col}_{row}
(the region and size of dzi.tile_region). Levels at or above 1:1 are rendered a row of tiles
at a time, as one band cut into tiles: the band has the tiles' scale (m output pixels per
source pixel, with integer tile corners) so each cut equals the tile's own render (a crop is
the same region of the full render at that scale), and today's renderer computes its
distance grid once a band instead of once a tile. Levels below 1:1 are rendered tile by tile
(their edge tiles' scale is the level's size over the region's, not a power of two).
"""

from __future__ import annotations

import math
import os
import sys

from ..imageio import encode_image
from . import dzi
from .tiles import render_tile


def write_pyramid(m, folder: str, zoom: int, fmt: str, tile: int = dzi.TILE, progress: bool = False) -> int:
    """Write folder/{id}_files/{level}/{col}_{row}.{fmt}; return the number of tiles."""
    dzi.check_zoom(zoom, tile)
    top = dzi.top_level(m.width, m.height, zoom)
    n = 0
    for level in range(top + 1):
        lw, lh = dzi.level_size(m.width, m.height, zoom, level)
        cols, rows = math.ceil(lw / tile), math.ceil(lh / tile)
        d = os.path.join(folder, f"{m.id}_files", str(level))
        os.makedirs(d)
        banded = 2 ** (top - level) <= zoom
        for row in range(rows):
            if progress:
                sys.stderr.write(f"\r\033[Kisophote: level {level}/{top}, row {row + 1}/{rows}")
                sys.stderr.flush()
            if banded:
                (_, y, _, h), (_, oh) = dzi.tile_region(m.width, m.height, zoom, level, 0, row, tile)
                band = render_tile(m, (0, y, m.width, h), (lw, oh))
            for col in range(cols):
                region, (ow, oh) = dzi.tile_region(m.width, m.height, zoom, level, col, row, tile)
                a = band[:, col * tile: col * tile + ow] if banded else render_tile(m, region, (ow, oh))
                with open(os.path.join(d, f"{col}_{row}.{fmt}"), "wb") as f:
                    f.write(encode_image(a, fmt))
                n += 1
    if progress:
        sys.stderr.write("\r\033[K")
    return n
