"""The format's limits and magic numbers, each defined once with its reason beside it.

Both containers (.isoph and the isophote SVG profile) read and write against these; the
specification (docs/format.md, "Limits, and why") gives the same reasons in prose, and
tests/format/test_spec.py checks that its table names exactly the limits below.
"""

from __future__ import annotations

from ..shared.grid import QUANT  # coordinates in 1/QUANT px, cap values in 1/QUANT grey level

# ---- identity --------------------------------------------------------------------------------

# The first byte has its high bit set and the last two are CR LF, so 7-bit transfers and newline
# conversion both break it (the trick of PNG's signature).
MAGIC = b"\x89ISOPH\r\n"
FORMAT_VERSION = 5  # written
READ_VERSIONS = (1, 2, 3, 4, 5)  # read: every file an earlier isophote wrote stays readable
SVG_FORMAT_VERSION = 1  # the isophote SVG profile's iso:format
GZIP_MAGIC = b"\x1f\x8b"  # an SVGZ is told by this, not by its name

# ---- what an image may be ----------------------------------------------------------------

COLOUR_CODES = {"grey": 0, "yuv": 1}
COLOUR_NAMES = {v: k for k, v in COLOUR_CODES.items()}
SOURCE_DEPTHS = (8, 16)  # the bit depth of the encoded raster (informational)
# The channel layouts of the data model, in its canonical order.
CHANNEL_LAYOUTS = {
    "grey": (("Y",), ("Y", "A")),
    "yuv": (("Y", "U", "V"), ("Y", "U", "V", "A")),
}

# ---- sizes -----------------------------------------------------------------------------------

# 2**20 px a side is far beyond any camera; with control points allowed well outside the frame
# (COORD_LIMIT), every coordinate times 64 still fits in int32.
MAX_WIDTH = 1 << 20
MAX_HEIGHT = 1 << 20
# Four levels per grey step of the 0..255 scale: finer levels carry no information an
# 8-bit-scale rendering can show, and the level list (8 KiB a channel) stays a small part of a
# header that is read on its own.
MAX_LEVELS = 1024
# A knot per 1/16 grey level: more than any remapping of at most MAX_LEVELS levels needs
# (64 KiB a channel).
MAX_TONE_KNOTS = 4096
MAX_CHANNELS = 4  # Y, U, V and alpha
# meta describes the file (source, options); it is not image data, and it sits in the header,
# which read_info reads whole.
MAX_META_BYTES = 1 << 16
# Over 6 GB of raw payload, far beyond what a 100-megapixel photograph (limits.MAX_PIXELS)
# yields; it keeps every count and index inside the u32 fields and every running sum of
# coordinates inside int64 (3 S * 2**31 < 2**63).
MAX_SEGMENTS = 1 << 28  # per channel
MAX_CAPS = 1 << 28  # per channel
# Bezier control points may lie outside the canvas, but not absurdly far (16 times MAX_WIDTH:
# |coordinate| < 2**24 px); differences of two coordinates then fit a zigzagged u32.
COORD_LIMIT = 1 << 30  # exclusive, in 1/QUANT px
# Cap values live on the 0..255 scale with some overshoot; beyond this (2**24) is garbage.
CAP_VALUE_LIMIT = 1 << 30  # exclusive, in 1/QUANT grey level
# raw_size <= MAX_EXPANSION * payload_size + EXPANSION_SLACK. Photograph payloads are 3.5
# (zlib) to 5.5 (range) times smaller than their column layout, so this never binds them, but
# it bounds decoding work and memory by the file's size: a small file cannot be a
# decompression bomb.
MAX_EXPANSION = 64
EXPANSION_SLACK = 1 << 20
# 1 GiB of SVG text: about 30 times a 0.3 MP photograph's SVG; parsing takes about twice that
# in memory. Also the bound after gunzip (reading stops there).
MAX_SVG_BYTES = 1 << 30

# ---- the payload's codings ---------------------------------------------------------------

COMPRESSION_STORED = 0
COMPRESSION_ZLIB = 1
COMPRESSION_LZMA = 2
COMPRESSION_RANGE = 3  # version 2 on
COMPRESSION_CODES = {"none": COMPRESSION_STORED, "zlib": COMPRESSION_ZLIB, "lzma": COMPRESSION_LZMA,
                     "range": COMPRESSION_RANGE}
COMPRESSION_NAMES = {v: k for k, v in COMPRESSION_CODES.items()}
DEFAULT_COMPRESSION = "range"  # 0.57 of zlib's bytes on photographs
ZLIB_LEVEL = 6
LZMA_DICT_SIZE = 1 << 23  # 8 MiB: a reader decodes with this dictionary, so the writer keeps to it
LZMA_PRESET = 6
MAX_GRID_SHIFT = 6  # point, cap and value grids: 1/64 .. 1/1 (QUANT >> shift)
MAX_ANCHOR_SHIFT = 16  # the anchor grid: 2**g units of the point grid

# The largest header the limits above allow (about 350 KiB) is format/isoph/layout.py's
# MAX_HEADER_BYTES: it follows from the byte layout.

__all__ = [
    "QUANT", "MAGIC", "FORMAT_VERSION", "READ_VERSIONS", "SVG_FORMAT_VERSION", "GZIP_MAGIC",
    "COLOUR_CODES", "COLOUR_NAMES", "SOURCE_DEPTHS", "CHANNEL_LAYOUTS",
    "MAX_WIDTH", "MAX_HEIGHT", "MAX_LEVELS", "MAX_TONE_KNOTS", "MAX_CHANNELS", "MAX_META_BYTES",
    "MAX_SEGMENTS", "MAX_CAPS", "COORD_LIMIT", "CAP_VALUE_LIMIT", "MAX_EXPANSION", "EXPANSION_SLACK",
    "MAX_SVG_BYTES",
    "COMPRESSION_STORED", "COMPRESSION_ZLIB", "COMPRESSION_LZMA", "COMPRESSION_RANGE",
    "COMPRESSION_CODES", "COMPRESSION_NAMES", "DEFAULT_COMPRESSION", "ZLIB_LEVEL",
    "LZMA_DICT_SIZE", "LZMA_PRESET", "MAX_GRID_SHIFT", "MAX_ANCHOR_SHIFT",
]
