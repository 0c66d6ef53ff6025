"""The .isoph byte layout (docs/format.md, "Preamble", "Header body") and the records the
header, the writer and the readers pass each other."""

from __future__ import annotations

import struct

import numpy as np

from ...model import CAP_RAMP, Channel
from ...shared.grid import QUANT
from ..limits import MAX_CHANNELS, MAX_LEVELS, MAX_META_BYTES, MAX_TONE_KNOTS

PREAMBLE = struct.Struct("<8sHHI")  # magic, version, reserved, header_size
FIXED = struct.Struct("<IIBBBBHHQQII")  # width .. meta_size: offsets 16 .. 56
# name, n_levels, base_band, n_contours, n_segments, n_caps, n_tone, point_shift,
# anchor_shift, cap_shift, value_shift, coded_size
CHANNEL = struct.Struct("<cHHIIIHBBBBQ")
CHANNEL_V1 = struct.Struct("<cHHIII")  # name .. n_caps
CAP_RAMP_FIELD = struct.Struct("<d")  # after the levels and tone knots (versions 3 and 4)
CRC = struct.Struct("<I")
PREAMBLE_BYTES = PREAMBLE.size  # 16
MIN_HEADER_BYTES = PREAMBLE_BYTES + FIXED.size + CHANNEL_V1.size + CRC.size
# The largest header the limits allow (about 350 KiB): read_info reads no more.
MAX_HEADER_BYTES = (
    PREAMBLE_BYTES + FIXED.size + MAX_META_BYTES
    + MAX_CHANNELS * (CHANNEL.size + 8 * MAX_LEVELS + 16 * MAX_TONE_KNOTS + CAP_RAMP_FIELD.size) + CRC.size
)


class ChannelInfo:
    """One channel's summary in the header."""

    __slots__ = ("name", "levels", "base_band", "n_contours", "n_segments", "n_caps", "tone",
                 "s_p", "g", "s_c", "s_v", "coded_size", "cap_ramp")

    def __init__(self, name, levels, base_band, n_contours, n_segments, n_caps, tone=None,
                 s_p=0, g=0, s_c=0, s_v=0, coded_size=0, cap_ramp=CAP_RAMP):
        self.name, self.levels, self.base_band = name, levels, base_band
        self.n_contours, self.n_segments, self.n_caps = n_contours, n_segments, n_caps
        self.tone, self.coded_size, self.cap_ramp = tone, coded_size, cap_ramp
        self.s_p, self.g, self.s_c, self.s_v = s_p, g, s_c, s_v


class Header:
    """A checked header (header.parse_header)."""

    __slots__ = (
        "version", "width", "height", "colour", "source_depth", "compression",
        "payload_size", "raw_size", "payload_crc", "meta", "channels", "header_size",
    )


class Checked:
    """One channel, checked against the data model, on the 1/64 grids (int64). ``stored``:
    (3 S, 2), the chains' points without their closing points (what both layouts code)."""

    __slots__ = ("info", "level", "offsets", "nseg", "stored", "border", "parent", "cap_band",
                 "cap_contour", "cq", "vq")


def raw_channel_bytes(c: int, s: int, k: int) -> int:
    """Bytes of one channel's raw payload (see the column table)."""
    return 10 * c + 24 * s + 18 * k + (s + 7) // 8


def closed_points(stored: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(offsets[-1], 2): the stored points with each chain's closing point (its first) put
    back."""
    c = offsets.shape[0] - 1
    q = np.empty((stored.shape[0] + c, 2), stored.dtype)
    closing = offsets[1:] - 1
    keep = np.ones(q.shape[0], bool)
    keep[closing] = False
    q[keep] = stored
    q[closing] = stored[offsets[:-1] - np.arange(c)]
    return q


def cap_origins(stored: np.ndarray, offsets: np.ndarray, cap_contour: np.ndarray) -> np.ndarray:
    """(K, 2): the first point of each cap's contour, (0, 0) for the root region (contour i
    starts at stored row offsets[i] - i: each chain before it left its closing point out)."""
    origins = np.zeros((cap_contour.shape[0], 2), np.int64)
    inner = cap_contour >= 0
    cc = cap_contour[inner]
    origins[inner] = stored[offsets[cc] - cc]
    return origins


CONVERT_CHUNK = 1 << 18  # points grid_to_pixels converts at a time


def grid_to_pixels(q: np.ndarray) -> np.ndarray:
    """``q.astype(float64) / QUANT``, the same values, in q's own memory where q is a
    writeable C-contiguous int64 array (the decoders' own, which nothing else holds), a chunk
    of rows at a time: a 16 MP photograph's luma holds 14 M points, 218 MB that the plain
    formula held three times at once."""
    if q.dtype != np.int64 or q.ndim != 2 or not q.flags.c_contiguous or not q.flags.writeable:
        return q.astype(np.float64) / QUANT
    out = q.view(np.float64)
    for a in range(0, q.shape[0], CONVERT_CHUNK):
        out[a : a + CONVERT_CHUNK] = q[a : a + CONVERT_CHUNK].astype(np.float64) / QUANT
    return out


EXACT_GRID = 1 << 24  # 1/64 units: grid values below this are exact in float32 (24 bits), 2**18 px


def grid_to_float32(q: np.ndarray):
    """``(q / QUANT).astype(float32)``, the same values as grid_to_pixels' (q below
    EXACT_GRID in magnitude), in q's own memory where q is a writeable C-contiguous int32 or
    int64 (N, 2) array (the decoders' own), a chunk of rows at a time: each chunk is
    converted before it is written, over rows already read (int64: into the first half,
    whose second half's pages are then given back, shared/heap.release_read). None where
    float32 would round a value or q is not such an array."""
    from ...shared.heap import release_read

    if q.dtype not in (np.int32, np.int64) or q.ndim != 2 or not q.flags.c_contiguous or not q.flags.writeable \
            or not _exact(q):
        return None
    n = q.shape[0]
    out = q.reshape(-1).view(np.float32)[: 2 * n].reshape(n, 2)
    for a in range(0, n, CONVERT_CHUNK):
        out[a : a + CONVERT_CHUNK] = q[a : a + CONVERT_CHUNK].astype(np.float32) / np.float32(QUANT)
    if q.dtype == np.int64:
        release_read(q.reshape(-1).view(np.uint8), 8 * n, 16 * n)
    return out


def _exact(q: np.ndarray) -> bool:
    """Whether grid values q are exact in float32 (below EXACT_GRID in magnitude)."""
    return q.size == 0 or max(-int(q.min()), int(q.max())) < EXACT_GRID


def _grid_values(v: np.ndarray, compact: bool) -> np.ndarray:
    """Grid values v / QUANT: float32 with ``compact`` where exact, else float64."""
    if compact and _exact(v):
        return v.astype(np.float32) / np.float32(QUANT)
    return v.astype(np.float64) / QUANT


def to_channel(info, level, offsets, q, border, parent, cap_band, cap_contour, cq, vq, compact=False) -> Channel:
    """A Channel in canonical dtypes from decoded integers (1/64 units); q, the decoder's
    own, becomes the points in place: float64, or with ``compact`` float32 where exact
    (grid_to_float32; its freed half before the caps' arrays are made), and the caps'
    positions and values float32 with them where exact."""
    points = grid_to_float32(q) if compact else None
    return Channel(
        name=info.name,
        levels=info.levels.copy(),
        contour_level=level.astype(np.int32),
        offsets=offsets,
        points=grid_to_pixels(q) if points is None else points,
        border=border.astype(bool),
        parent=parent.astype(np.int32),
        cap_band=cap_band.astype(np.int32),
        cap_contour=cap_contour.astype(np.int32),
        cap_xy=_grid_values(cq, points is not None),
        cap_value=_grid_values(vq, points is not None),
        base_band=info.base_band,
        tone=None if info.tone is None else info.tone.copy(),
        cap_ramp=float(info.cap_ramp),
    )
