"""The .isoph reader: ``loads`` and ``load``, every version of READ_VERSIONS (docs/format.md;
the versions differ in their header, read by header.py, and in the range coder's layout,
which format/_coder/entropy.py takes as an argument)."""

from __future__ import annotations

import lzma
import os
import zlib

import numpy as np

from ...errors import FormatError
from ...model import VectorImage
from ...shared.heap import return_freed_memory
from ..limits import COMPRESSION_RANGE, COMPRESSION_STORED, COMPRESSION_ZLIB, LZMA_DICT_SIZE
from .columns import Columns, decode_column_channel
from .header import checked_header, guarded, parse_header, read_head, with_where
from .layout import Header
from .rangecoded import decode_range_channel, map_channels

LZMA_READ_FILTERS = [{"id": lzma.FILTER_LZMA2, "dict_size": LZMA_DICT_SIZE}]


def loads(data) -> VectorImage:
    """Parse .isoph bytes (bytes, bytearray or memoryview) into a VectorImage.

    Raises FormatError, or LimitError for a declared size over a limit, for anything that is
    not a valid .isoph file; never another exception type for bad data.
    """
    buf = bytes(data)

    def parse():
        h = parse_header(buf, len(buf))
        return decode(h, memoryview(buf)[h.header_size :])

    return guarded(parse)


def load(path, compact: bool = False) -> VectorImage:
    """Read an .isoph file. FormatError (or LimitError) for unreadable or malformed files.

    The header is read and checked first; then exactly the payload it declares. With
    ``compact`` the control points are float32 where that holds them exactly (every
    coordinate under 2**18 px: layout.grid_to_float32), half their memory: for rendering,
    whose kernels read them as the float64 values they are (the same pixels); edits and
    warps compute in the points' dtype, so they take a master loaded without it.
    """
    where = f"{os.fspath(path)}: "
    try:
        with open(path, "rb") as f:
            size, head = read_head(f)
            h = checked_header(where, head, size)
            f.seek(h.header_size)
            payload = f.read(h.payload_size)
    except OSError as e:
        raise FormatError(f"{where}cannot read: {e.strerror or e}") from None
    if len(payload) != h.payload_size:
        raise FormatError(f"{where}truncated .isoph file: the file shrank while being read")
    return with_where(where, lambda: guarded(lambda: decode(h, payload, compact)))


def decode(h: Header, payload, compact: bool = False) -> VectorImage:
    """The image from a checked header and its payload (bytes or memoryview); ``compact``:
    float32 points where exact (load)."""
    return_freed_memory()  # glibc: the decoders' temporaries go back to the system (shared/heap.py)
    if zlib.crc32(payload) != h.payload_crc:
        raise FormatError("payload checksum mismatch (corrupted payload)")
    if h.compression == COMPRESSION_RANGE:
        chunks, pos = [], 0
        for info in h.channels:
            chunks.append((info, np.frombuffer(payload, np.uint8, info.coded_size, pos).copy(), h.version, compact))
            pos += info.coded_size
        channels = tuple(map_channels(decode_range_channel, chunks, sum(c.n_segments for c in h.channels)))
    else:
        cols = Columns(_decompress(payload, h.compression, h.raw_size))
        channels = tuple(decode_column_channel(cols, info, compact) for info in h.channels)
    return VectorImage(
        width=h.width, height=h.height, colour=h.colour, channels=channels,
        source_depth=h.source_depth, meta=h.meta,
    )


def _decompress(payload: bytes, compression: int, raw_size: int) -> bytes:
    if compression == COMPRESSION_STORED:
        return payload
    # Ask for one byte more than declared: a stream that yields it is longer than declared.
    try:
        if compression == COMPRESSION_ZLIB:
            d = zlib.decompressobj()
            raw = d.decompress(payload, raw_size + 1)
            ended = d.eof and not d.unconsumed_tail and not d.unused_data
        else:
            d = lzma.LZMADecompressor(format=lzma.FORMAT_RAW, filters=LZMA_READ_FILTERS)
            raw = d.decompress(payload, raw_size + 1)
            ended = d.eof and not d.unused_data
    except (zlib.error, lzma.LZMAError) as e:
        raise FormatError(f"payload does not decompress ({e})") from None
    if len(raw) > raw_size:
        raise FormatError(f"payload decompresses to more than the {raw_size} bytes the header declares")
    if len(raw) < raw_size:
        raise FormatError(f"payload decompresses to {len(raw)} bytes, the header declares {raw_size}")
    if not ended:
        raise FormatError("compressed payload does not end where the file ends")
    return raw
