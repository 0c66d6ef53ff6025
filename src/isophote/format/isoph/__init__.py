"""The .isoph binary format: a VectorImage on disk.

The specification is docs/format.md, and only there: it is written for readers who do not
read Python (tables of every field, the coder's arithmetic, the reasons for each limit), and
tests/format/test_format.py holds an independent writer built from its text to the same bytes, so
that is the text to keep right; this package cites it section by section instead of saying
it again. tests/format/test_spec.py checks that the two agree where they can (the magic,
the version, the limits named in its table).

Where each section of docs/format.md lives:

    Preamble, Header body      header.py (parse_header's steps, header_bytes, read_info);
                               the byte layout and the records passed around: layout.py
    Payload, Column layout     columns.py (compressions 0, 1, 2, both ways)
    Range-coded channels       rangecoded.py (grids, statuses) and format/_coder/entropy.py
    Versions 1 to 3            header.py (their summaries) and the coder (their layouts)
    Precision, writing         write.py (dumps, save)
    Validation                 read.py (loads, load), header.py, format/validate.py
    Limits, and why            format/limits.py

This module writes version 5 and reads versions 1 to 5.
"""

from __future__ import annotations

from ..limits import (
    CAP_VALUE_LIMIT, COORD_LIMIT, DEFAULT_COMPRESSION, EXPANSION_SLACK, FORMAT_VERSION, MAGIC,
    MAX_CAPS, MAX_CHANNELS, MAX_EXPANSION, MAX_HEIGHT, MAX_LEVELS, MAX_META_BYTES, MAX_SEGMENTS,
    MAX_TONE_KNOTS, MAX_WIDTH, QUANT, READ_VERSIONS, ZLIB_LEVEL,
)
from .header import read_info
from .layout import MAX_HEADER_BYTES
from .read import load, loads
from .write import dumps, save

__all__ = [
    "dumps", "loads", "save", "load", "read_info",
    "MAGIC", "FORMAT_VERSION", "READ_VERSIONS", "QUANT", "DEFAULT_COMPRESSION", "ZLIB_LEVEL",
    "MAX_WIDTH", "MAX_HEIGHT", "MAX_LEVELS", "MAX_TONE_KNOTS", "MAX_CHANNELS", "MAX_META_BYTES",
    "MAX_SEGMENTS", "MAX_CAPS", "COORD_LIMIT", "CAP_VALUE_LIMIT",
    "MAX_EXPANSION", "EXPANSION_SLACK", "MAX_HEADER_BYTES",
]
