"""Deep Zoom (DZI) pyramids of a master enlarged ``zoom`` times.

The pyramid describes a virtual image of (zoom * width) x (zoom * height) pixels, so its top
levels are renders above 1:1 (the master is a vector; nothing is upscaled). Level L of a
pyramid with top level M (M = ceil(log2 of the virtual image's longer side)) shows the master
at m = zoom / 2^(M - L) output pixels per source pixel; its tile (col, row) covers output
pixels [col * T, (col + 1) * T) x [row * T, (row + 1) * T) cut to the level's size, where the
level is ceil(m * width) x ceil(m * height). With zoom a power of two dividing the tile size T,
every tile's region in source pixels has integer corners, so each tile is exactly the IIIF
request ``x,y,w,h / w',h'`` of that region (tile_region), and the viewer's IIIF tile source
(static/viewer.js) uses the same arithmetic. Tiles have no overlap.
"""

from __future__ import annotations

import math

TILE = 256


class LevelError(ValueError):
    """A level, column or row outside the pyramid (the server answers 404)."""


def check_zoom(zoom: int, tile: int = TILE) -> None:
    if zoom < 1 or zoom & (zoom - 1) or tile % zoom:
        raise ValueError(f"zoom must be a power of two that divides the tile size {tile}, got {zoom}")


def top_level(width: int, height: int, zoom: int) -> int:
    return max(0, math.ceil(math.log2(max(width, height) * zoom)))


def level_size(width: int, height: int, zoom: int, level: int) -> tuple:
    """(w, h) of a level in output pixels."""
    shift = top_level(width, height, zoom) - level
    if shift < 0:
        raise LevelError(f"level {level} is above the top level {level + shift}")
    return math.ceil(width * zoom / 2**shift), math.ceil(height * zoom / 2**shift)


def tile_region(width: int, height: int, zoom: int, level: int, col: int, row: int, tile: int = TILE):
    """((x, y, w, h) in source pixels, (out_w, out_h)) of one tile."""
    if level < 0:
        raise LevelError(f"level {level} is below 0")
    lw, lh = level_size(width, height, zoom, level)
    if not (0 <= col * tile < lw and 0 <= row * tile < lh):
        raise LevelError(f"tile {col}_{row} is outside level {level} ({lw}x{lh})")
    shift = top_level(width, height, zoom) - level
    ow, oh = min(tile, lw - col * tile), min(tile, lh - row * tile)
    if 2**shift <= zoom:  # m = zoom / 2^shift >= 1 source pixel per ... output pixels
        m = zoom // 2**shift
        return (col * tile // m, row * tile // m, ow // m, oh // m), (ow, oh)
    k = 2**shift // zoom  # source pixels per output pixel
    x, y = col * tile * k, row * tile * k
    return (x, y, min(tile * k, width - x), min(tile * k, height - y)), (ow, oh)


def descriptor(width: int, height: int, zoom: int, fmt: str, tile: int = TILE) -> str:
    """The .dzi XML of the virtual (zoom x) image."""
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<Image xmlns="http://schemas.microsoft.com/deepzoom/2008" Format="{fmt}" Overlap="0" '
        f'TileSize="{tile}"><Size Width="{width * zoom}" Height="{height * zoom}"/></Image>\n'
    )


def tiles(width: int, height: int, zoom: int, tile: int = TILE):
    """Every (level, col, row) of the pyramid, coarsest level first."""
    for level in range(top_level(width, height, zoom) + 1):
        lw, lh = level_size(width, height, zoom, level)
        for row in range(math.ceil(lh / tile)):
            for col in range(math.ceil(lw / tile)):
                yield level, col, row
