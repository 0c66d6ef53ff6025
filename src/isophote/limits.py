"""The limits every stage shares, each defined once with its reason.

MAX_PIXELS
    100 MP (10000 x 10000): the largest image the encoder accepts, a decoded raster may
    declare (a decompression-bomb guard, checked before any pixel is decoded) and, by
    default, a render may produce (``RenderOptions.max_pixels``). It keeps every count and
    index of the .isoph format inside its u32 fields (docs/format.md).
"""

MAX_PIXELS = 100_000_000
