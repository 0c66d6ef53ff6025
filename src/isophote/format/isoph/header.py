"""The .isoph header both ways: ``header_bytes`` writes it, ``parse_header`` checks it in
named steps (docs/format.md, "Preamble", "Header body", "Validation"), ``read_info``
describes a file from it alone."""

from __future__ import annotations

import os
import struct
import zlib

import numpy as np

from ...errors import FormatError, LimitError
from ...model import CAP_RAMP, DOME
from ...shared.grid import QUANT
from ..limits import (
    CHANNEL_LAYOUTS, COLOUR_CODES, COLOUR_NAMES, COMPRESSION_NAMES, COMPRESSION_RANGE,
    COMPRESSION_STORED, EXPANSION_SLACK, FORMAT_VERSION, MAGIC, MAX_ANCHOR_SHIFT, MAX_CAPS,
    MAX_CHANNELS, MAX_EXPANSION, MAX_GRID_SHIFT, MAX_HEIGHT, MAX_LEVELS, MAX_META_BYTES,
    MAX_SEGMENTS, MAX_TONE_KNOTS, MAX_WIDTH, READ_VERSIONS, SOURCE_DEPTHS,
)
from ..validate import check_cap_ramp, check_levels, check_tone, parse_meta
from .layout import (
    CAP_RAMP_FIELD, CHANNEL, CHANNEL_V1, CRC, FIXED, MAX_HEADER_BYTES, MIN_HEADER_BYTES, PREAMBLE,
    PREAMBLE_BYTES, ChannelInfo, Header, raw_channel_bytes,
)

# ---- writing ---------------------------------------------------------------------------------


def header_bytes(width, height, colour, depth, infos, compression, payload, raw_size, meta) -> bytes:
    """The header (version FORMAT_VERSION) of a payload and its channels' summaries."""
    body = bytearray(
        FIXED.pack(
            width, height, COLOUR_CODES[colour], depth, len(infos), compression, QUANT, QUANT,
            len(payload), raw_size, zlib.crc32(payload), len(meta),
        )
    )
    body += meta
    for c in infos:
        n_tone = 0 if c.tone is None else c.tone.shape[0]
        body += CHANNEL.pack(c.name.encode("ascii"), len(c.levels), c.base_band, c.n_contours,
                             c.n_segments, c.n_caps, n_tone, c.s_p, c.g, c.s_c, c.s_v, c.coded_size)
        body += np.asarray(c.levels, dtype="<f8").tobytes()
        if c.tone is not None:
            body += np.ascontiguousarray(c.tone, dtype="<f8").tobytes()
        body += CAP_RAMP_FIELD.pack(c.cap_ramp)
    header_size = PREAMBLE_BYTES + len(body) + CRC.size
    head = PREAMBLE.pack(MAGIC, FORMAT_VERSION, 0, header_size) + bytes(body)
    return head + CRC.pack(zlib.crc32(head))


# ---- reading: the steps ------------------------------------------------------------------


def unsupported(version: int) -> FormatError:
    return FormatError(
        f"unsupported .isoph format version {version} (this reader knows versions "
        f"{', '.join(map(str, READ_VERSIONS))})"
    )


class _Fields:
    """Takes the header body's fields in order, never past the header checksum."""

    def __init__(self, data: bytes, pos: int, end: int):
        self.data, self.pos, self.end = data, pos, end

    def take(self, size: int, what: str) -> bytes:
        if self.pos + size > self.end:
            raise FormatError(f"header too short for its {what}")
        self.pos += size
        return self.data[self.pos - size : self.pos]

    def done(self) -> None:
        if self.pos != self.end:
            raise FormatError(f"header has {self.end - self.pos} unexpected byte(s) after the channel summaries")


def _preamble(data: bytes, file_size: int):
    """(version, header_size) of a preamble whose header is all there and whose checksum holds."""
    if len(data) < PREAMBLE_BYTES:
        if MAGIC.startswith(data[:8]):
            raise FormatError(
                f"truncated .isoph file: {file_size} bytes, shorter than the {PREAMBLE_BYTES}-byte preamble"
            )
        raise FormatError("not an .isoph file (bad magic bytes)")
    magic, version, reserved, header_size = PREAMBLE.unpack_from(data, 0)
    if magic != MAGIC:
        raise FormatError("not an .isoph file (bad magic bytes)")
    if not MIN_HEADER_BYTES <= header_size <= MAX_HEADER_BYTES:
        if version > FORMAT_VERSION:  # a newer layout may well have a larger header
            raise unsupported(version)
        raise FormatError(
            f"header size {header_size} is outside [{MIN_HEADER_BYTES}, {MAX_HEADER_BYTES}] (corrupted preamble)"
        )
    if file_size < header_size or len(data) < header_size:
        raise FormatError(
            f"truncated .isoph file: {file_size} bytes, the header alone declares {header_size}"
        )
    (stored_crc,) = CRC.unpack_from(data, header_size - 4)
    if zlib.crc32(data[: header_size - 4]) != stored_crc:
        raise FormatError("header checksum mismatch (corrupted header)")
    if version not in READ_VERSIONS:
        raise unsupported(version)
    if reserved != 0:
        raise FormatError(f"reserved preamble field is {reserved}, must be 0 in version {version}")
    return version, header_size


def _fixed_fields(fields: _Fields, h: Header) -> int:
    """Check the fixed fields and meta into ``h``; the channel count."""
    version = h.version
    (width, height, colour, depth, n_channels, compression, xy_quant, value_quant,
     h.payload_size, h.raw_size, h.payload_crc, meta_size) = FIXED.unpack(fields.take(FIXED.size, "fixed fields"))
    if width < 1 or height < 1:
        raise FormatError(f"image size {width} x {height} is empty")
    if width > MAX_WIDTH or height > MAX_HEIGHT:
        raise LimitError(f"image size {width} x {height} exceeds the {MAX_WIDTH} x {MAX_HEIGHT} limit")
    h.width, h.height = width, height
    if colour not in COLOUR_NAMES:
        raise FormatError(f"unknown colour code {colour} (0 = grey, 1 = yuv)")
    h.colour = COLOUR_NAMES[colour]
    if depth not in SOURCE_DEPTHS:
        raise FormatError(f"source depth {depth} is not 8 or 16")
    h.source_depth = depth
    if not 1 <= n_channels <= MAX_CHANNELS:
        raise FormatError(f"channel count {n_channels} is outside [1, {MAX_CHANNELS}]")
    known = COMPRESSION_NAMES if version >= 2 else {k: v for k, v in COMPRESSION_NAMES.items() if k < 3}
    if compression not in known:
        raise FormatError(
            f"unknown compression code {compression} in version {version} "
            f"({', '.join(f'{k} = {v}' for k, v in known.items())})"
        )
    h.compression = compression
    if xy_quant != QUANT or value_quant != QUANT:
        raise FormatError(
            f"quanta {xy_quant}/{value_quant} are not {QUANT}/{QUANT} as version {version} requires"
        )
    if meta_size > MAX_META_BYTES:
        raise LimitError(f"meta of {meta_size} bytes exceeds the {MAX_META_BYTES}-byte limit")
    h.meta = parse_meta(fields.take(meta_size, "meta"))
    return n_channels


def _summary_counts(label, n_levels, base_band, n_contours, n_segments, n_caps, n_tone) -> None:
    if n_levels > MAX_LEVELS:
        raise LimitError(f"channel {label}: {n_levels} levels exceed the limit of {MAX_LEVELS}")
    if n_segments > MAX_SEGMENTS:
        raise LimitError(f"channel {label}: {n_segments} segments exceed the limit of {MAX_SEGMENTS}")
    if n_caps > MAX_CAPS:
        raise LimitError(f"channel {label}: {n_caps} caps exceed the limit of {MAX_CAPS}")
    if n_tone > MAX_TONE_KNOTS:
        raise LimitError(f"channel {label}: {n_tone} tone knots exceed the limit of {MAX_TONE_KNOTS}")
    if n_contours > n_segments:
        raise FormatError(f"channel {label}: {n_contours} contours but only {n_segments} segments")
    if n_contours > 0 and n_levels == 0:
        raise FormatError(f"channel {label}: {n_contours} contours but no levels")
    if base_band > n_levels:
        raise FormatError(f"channel {label}: base band {base_band} is outside [0, {n_levels}]")


def _summary_grids(label, compression, s_p, g, s_c, s_v, coded_size) -> None:
    if compression == COMPRESSION_RANGE:
        if max(s_p, s_c, s_v) > MAX_GRID_SHIFT or g > MAX_ANCHOR_SHIFT:
            raise FormatError(
                f"channel {label}: grid shifts {s_p}/{g}/{s_c}/{s_v} exceed "
                f"{MAX_GRID_SHIFT}/{MAX_ANCHOR_SHIFT}/{MAX_GRID_SHIFT}/{MAX_GRID_SHIFT}"
            )
    elif s_p or g or s_c or s_v or coded_size:
        raise FormatError(
            f"channel {label}: grid shifts and coded size must be 0 with compression "
            f"{COMPRESSION_NAMES[compression]!r}"
        )


def _channel_summary(fields: _Fields, version: int, compression: int, i: int) -> ChannelInfo:
    """Channel i's summary: counts, grids, levels, tone curve and cap ramp, checked."""
    if version == 1:
        summary = fields.take(CHANNEL_V1.size, f"channel {i} summary")
        name, n_levels, base_band, n_contours, n_segments, n_caps = CHANNEL_V1.unpack(summary)
        n_tone = s_p = g = s_c = s_v = coded_size = 0
    else:
        summary = fields.take(CHANNEL.size, f"channel {i} summary")
        (name, n_levels, base_band, n_contours, n_segments, n_caps, n_tone, s_p, g, s_c, s_v,
         coded_size) = CHANNEL.unpack(summary)
    # The name goes into messages before it is checked: a control byte would break the
    # one-line promise, so anything but printable ASCII is shown escaped.
    label = chr(name[0]) if 0x21 <= name[0] <= 0x7E else f"\\x{name[0]:02x}"
    _summary_counts(label, n_levels, base_band, n_contours, n_segments, n_caps, n_tone)
    _summary_grids(label, compression, s_p, g, s_c, s_v, coded_size)
    levels = np.frombuffer(fields.take(8 * n_levels, f"channel {label} levels"), dtype="<f8")
    levels = levels.astype(np.float64)
    check_levels(levels, label)
    tone = None
    if n_tone:
        tone = np.frombuffer(fields.take(16 * n_tone, f"channel {label} tone"), dtype="<f8")
        tone = tone.astype(np.float64).reshape(n_tone, 2)
        check_tone(tone, label)
    cap_ramp = CAP_RAMP
    if version >= 3:
        (cap_ramp,) = CAP_RAMP_FIELD.unpack(fields.take(CAP_RAMP_FIELD.size, f"channel {label} cap ramp"))
        check_cap_ramp(cap_ramp, label)
    return ChannelInfo(label, levels, base_band, n_contours, n_segments, n_caps, tone,
                       s_p, g, s_c, s_v, coded_size, cap_ramp)


def _check_sizes(h: Header, file_size: int) -> None:
    """The counts fix the raw size; the raw size must be plausible for the stored size, and
    the stored size must be what the file holds."""
    raw_size, payload_size = h.raw_size, h.payload_size
    expected_raw = sum(raw_channel_bytes(c.n_contours, c.n_segments, c.n_caps) for c in h.channels)
    if raw_size != expected_raw:
        raise FormatError(
            f"raw payload size {raw_size} does not match the {expected_raw} bytes the counts need"
        )
    if raw_size > MAX_EXPANSION * payload_size + EXPANSION_SLACK:
        raise FormatError(
            f"payload of {payload_size} bytes declares {raw_size} raw bytes, "
            f"over the {MAX_EXPANSION}:1 limit"
        )
    if h.compression == COMPRESSION_STORED and payload_size != raw_size:
        raise FormatError(f"stored payload of {payload_size} bytes but raw size {raw_size}")
    if h.compression == COMPRESSION_RANGE:
        coded = sum(c.coded_size for c in h.channels)
        if coded != payload_size:
            raise FormatError(f"channels' coded sizes add up to {coded} bytes, the payload has {payload_size}")
    expected = h.header_size + payload_size
    if file_size < expected:
        raise FormatError(f"truncated .isoph file: {file_size} bytes, the header declares {expected}")
    if file_size > expected:
        raise FormatError(f"{file_size - expected} unexpected byte(s) after the payload")


def parse_header(data: bytes, file_size: int) -> Header:
    """Parse and check the header at the start of ``data`` (which may be the whole file)."""
    h = Header()
    h.version, h.header_size = _preamble(data, file_size)
    fields = _Fields(data, PREAMBLE_BYTES, h.header_size - 4)
    n_channels = _fixed_fields(fields, h)
    h.channels = [_channel_summary(fields, h.version, h.compression, i) for i in range(n_channels)]
    fields.done()
    names = tuple(c.name for c in h.channels)
    if names not in CHANNEL_LAYOUTS[h.colour]:
        raise FormatError(f"channels {','.join(names)} do not fit colour {h.colour!r}")
    _check_sizes(h, file_size)
    return h


# ---- reading a file's header -------------------------------------------------------------


def read_head(f):
    """(file size, the header's bytes as far as the preamble vouches for them)."""
    size = os.fstat(f.fileno()).st_size
    head = f.read(PREAMBLE_BYTES)
    if len(head) == PREAMBLE_BYTES and head[:8] == MAGIC:
        header_size = PREAMBLE.unpack(head)[3]
        if header_size <= MAX_HEADER_BYTES:
            head += f.read(header_size - PREAMBLE_BYTES)
    return size, head


def guarded(parse):
    """Run ``parse``; a stray low-level error from bad data becomes a FormatError."""
    try:
        return parse()
    except (FormatError, LimitError):
        raise
    except (ValueError, IndexError, OverflowError, struct.error, RecursionError) as e:
        # A last resort: every problem should meet its own check first (the tests say so).
        raise FormatError(f"malformed .isoph file ({type(e).__name__}: {e})") from None


def with_where(where: str, parse):
    """Run ``parse``, prefixing its error messages with ``where`` (a path)."""
    try:
        return parse()
    except FormatError as e:
        raise FormatError(f"{where}{e}") from None
    except LimitError as e:
        raise LimitError(f"{where}{e}") from None


def checked_header(where: str, head: bytes, size: int) -> Header:
    """parse_header, its errors one-line FormatErrors prefixed with ``where``."""
    return with_where(where, lambda: guarded(lambda: parse_header(head, size)))


def read_info(path_or_bytes) -> dict:
    """Describe an .isoph file from its header alone; the payload is not decompressed.

    Parameters
    ----------
    path_or_bytes : str, os.PathLike, bytes, bytearray or memoryview

    Returns
    -------
    dict
        ``format_version``, ``width``, ``height``, ``colour``, ``source_depth``, ``bytes``
        (the file size), ``compression`` ("none", "zlib", "lzma" or "range"), ``meta``
        (dict) and ``channels``: a list of ``{"name", "levels" (list of float),
        "base_band", "contours", "segments", "caps", "tone_knots" (0: no tone curve),
        "cap_ramp" (pixels, or "dome"),
        "point_grid" (control points on the 1/point_grid px grid), "coded_bytes" (range-coded
        bytes, 0 for the other compressions)}``.

    The header checksum is verified and the file size checked against the header, so a
    truncated file is reported; the payload's checksum is ``load``'s business.
    """
    if isinstance(path_or_bytes, (bytes, bytearray, memoryview)):
        head = bytes(path_or_bytes)
        size = len(head)
        where = ""
    else:
        where = f"{os.fspath(path_or_bytes)}: "
        try:
            with open(path_or_bytes, "rb") as f:
                size, head = read_head(f)
        except OSError as e:
            raise FormatError(f"{where}cannot read: {e.strerror or e}") from None
    h = checked_header(where, head, size)
    return {
        "format_version": h.version,
        "width": h.width,
        "height": h.height,
        "colour": h.colour,
        "source_depth": h.source_depth,
        "bytes": size,
        "compression": COMPRESSION_NAMES[h.compression],
        "meta": h.meta,
        "channels": [_channel_info(c) for c in h.channels],
    }


def _channel_info(c: ChannelInfo) -> dict:
    return {
        "name": c.name,
        "levels": [float(v) for v in c.levels],
        "base_band": c.base_band,
        "contours": c.n_contours,
        "segments": c.n_segments,
        "caps": c.n_caps,
        "tone_knots": 0 if c.tone is None else int(c.tone.shape[0]),
        "cap_ramp": "dome" if c.cap_ramp == DOME else float(c.cap_ramp),
        "point_grid": QUANT >> c.s_p,
        "coded_bytes": c.coded_size,
    }
