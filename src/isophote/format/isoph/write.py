"""The .isoph writer: ``dumps`` and ``save`` (version FORMAT_VERSION, docs/format.md)."""

from __future__ import annotations

import lzma
import zlib

import numpy as np

from ...errors import FormatError, LimitError
from ...imageio import atomic_write_bytes
from ...model import CAP_RAMP, Channel, VectorImage
from ...shared.grid import QUANT
from ..limits import (
    CAP_VALUE_LIMIT, COMPRESSION_CODES, COMPRESSION_LZMA, COMPRESSION_RANGE, COMPRESSION_STORED,
    COMPRESSION_ZLIB, COORD_LIMIT, DEFAULT_COMPRESSION, EXPANSION_SLACK, LZMA_DICT_SIZE, LZMA_PRESET,
    MAX_CAPS, MAX_EXPANSION, MAX_LEVELS, MAX_SEGMENTS, ZLIB_LEVEL,
)
from ..validate import (
    check_cap_ramp, check_image_kind, check_levels, check_semantics, check_tone, meta_bytes,
)
from .columns import column_channel
from .header import header_bytes
from .layout import ChannelInfo, Checked, raw_channel_bytes
from .rangecoded import map_channels, range_channel

LZMA_WRITE_FILTERS = [{"id": lzma.FILTER_LZMA2, "preset": LZMA_PRESET, "dict_size": LZMA_DICT_SIZE}]


def dumps(vi: VectorImage, compression: str = DEFAULT_COMPRESSION) -> bytes:
    """Serialise a VectorImage to .isoph bytes (format version 5).

    Parameters
    ----------
    vi : VectorImage
    compression : {"range", "zlib", "lzma", "none"}
        "range" (the default) range-codes predicted values: 0.57 of "zlib" on photographs,
        writing about 2.5 and reading about 1 microsecond a segment; "zlib", "lzma" and
        "none" store the column layout (version 1's), "zlib" faster both ways.

    Returns
    -------
    bytes
        Deterministic: the same image (with the same zlib/liblzma) always gives the same
        bytes. Coordinates and cap values are rounded to the 1/64 grids (docs/format.md).

    Raises
    ------
    ValueError
        ``vi`` breaks the data model (unsorted levels, an open chain, cyclic parents, a
        tone curve that is not monotone, ...) or its meta cannot be written as JSON.
    LimitError
        A size, coordinate or cap value exceeds a limit of the format.
    """
    return _dumps_checked(vi, _compression_code(compression), in_place=False)


def save(vi: VectorImage, path, compression: str = DEFAULT_COMPRESSION) -> None:
    """Write ``vi`` to ``path`` atomically (a temporary file renamed into place)."""
    atomic_write_bytes(path, dumps(vi, compression=compression))


def dumps_held(held: list, compression: str = DEFAULT_COMPRESSION) -> bytes:
    """dumps of the one VectorImage in ``held``, which is emptied and whose points become
    the file's integers in their own memory (where they are C-contiguous float64): a caller
    whose image no one else holds (``isophote encode``'s own) writes it without a second
    copy of its points (16 bytes a point: 560 MiB of a 16 MP photograph's luma at `high`).
    The same bytes as dumps; the image must not be used after."""
    if len(held) != 1:
        raise ValueError("held must hold exactly one VectorImage")
    code = _compression_code(compression)  # refused before the image is taken
    return _dumps_checked(held.pop(), code, in_place=True)


def _compression_code(compression: str) -> int:
    if compression not in COMPRESSION_CODES:
        raise ValueError(f"compression must be one of {', '.join(COMPRESSION_CODES)}, got {compression!r}")
    return COMPRESSION_CODES[compression]


def _dumps_checked(vi: VectorImage, code: int, in_place: bool) -> bytes:
    """_dumps with the data model's errors as ValueError."""
    try:
        return _dumps(vi, code, in_place)
    except FormatError as e:
        raise ValueError(f"cannot write .isoph: {e}") from None


def _dumps(vi: VectorImage, compression: int, in_place: bool = False) -> bytes:
    check_image_kind(vi)
    width, height = int(vi.width), int(vi.height)
    meta = meta_bytes(vi.meta)
    if compression == COMPRESSION_RANGE:
        checked, coded = _range_coded(vi.channels, in_place)
        payload = b"".join(coded)
        del coded
    else:
        checked = [checked_channel(ch, in_place) for ch in vi.channels]
        raw = b"".join(column_channel(c) for c in checked)
        payload = raw
        if compression == COMPRESSION_ZLIB:
            payload = zlib.compress(raw, ZLIB_LEVEL)
        elif compression == COMPRESSION_LZMA:
            payload = lzma.compress(raw, format=lzma.FORMAT_RAW, filters=LZMA_WRITE_FILTERS)
    raw_size = sum(raw_channel_bytes(c.info.n_contours, c.info.n_segments, c.info.n_caps) for c in checked)
    if raw_size > MAX_EXPANSION * len(payload) + EXPANSION_SLACK:
        # Absurdly repetitive contours: readers refuse such ratios (decompression bombs).
        if compression == COMPRESSION_RANGE:  # the coder shifted the stored points in place
            for c in checked:
                np.left_shift(c.stored, c.info.s_p, out=c.stored)
        compression = COMPRESSION_STORED
        payload = b"".join(column_channel(c) for c in checked)
    infos = [c.info for c in checked]
    if compression != COMPRESSION_RANGE:
        for info in infos:
            info.s_p = info.g = info.s_c = info.s_v = info.coded_size = 0
    head = header_bytes(width, height, vi.colour, int(vi.source_depth), infos, compression,
                        payload, raw_size, meta)
    return head + payload


# Channels with this many points in all are checked and range-coded one at a time (each
# channel's parts of points in threads, format/isoph/rangecoded.py code_channel), fewer side
# by side: one channel's checking temporaries and coder buffers at a time. The same bytes
# either way.
ONE_AT_A_TIME_POINTS = 1 << 22


def _range_coded(channels, in_place: bool = False):
    """([Checked], [coded bytes]) of the channels, each checked then range-coded, its stored
    points shifted in place (with ``in_place``, in the channel's own memory: checked_channel)."""
    def one(ch):
        c = checked_channel(ch, in_place)
        return c, range_channel(c, take=True)

    n_points = sum(_rows(ch.points) for ch in channels)
    if n_points >= ONE_AT_A_TIME_POINTS:
        done = [one(ch) for ch in channels]
    else:
        done = map_channels(one, list(channels), n_points // 3)
    return [c for c, _ in done], [b for _, b in done]


def _rows(a) -> int:
    """len(a), 0 where it has none (checked_channel refuses such points)."""
    try:
        return len(a)
    except TypeError:
        return 0


def _channel_header(ch: Channel):
    """(levels, tone, cap_ramp) of a channel, checked."""
    label = ch.name
    levels = np.asarray(ch.levels, dtype=np.float64)
    if levels.ndim != 1:
        raise FormatError(f"channel {label}: levels must be 1-D")
    if levels.shape[0] > MAX_LEVELS:
        raise LimitError(f"channel {label}: {levels.shape[0]} levels exceed the limit of {MAX_LEVELS}")
    check_levels(levels, label)
    tone = getattr(ch, "tone", None)
    if tone is not None:
        tone = np.asarray(tone, dtype=np.float64)
        check_tone(tone, label)
    cap_ramp = check_cap_ramp(getattr(ch, "cap_ramp", CAP_RAMP), label)
    return levels, tone, cap_ramp


def checked_channel(ch: Channel, in_place: bool = False) -> Checked:
    """Check one channel against the data model; quantise it to the 1/64 grids. With
    ``in_place`` the stored points are made in the points' own memory where they are a
    C-contiguous writeable float64 array (dumps_held: ch is not usable after)."""
    label = ch.name
    levels, tone, cap_ramp = _channel_header(ch)
    level = _int_array(ch.contour_level, label, "contour_level")
    c = level.shape[0]
    offsets = _int_array(ch.offsets, label, "offsets")
    points = np.asarray(ch.points, dtype=np.float64)
    if offsets.shape[0] != c + 1 or offsets[0] != 0:
        raise FormatError(f"channel {label}: offsets must have C + 1 = {c + 1} entries, starting at 0")
    if points.ndim != 2 or points.shape[1] != 2 or offsets[-1] != points.shape[0]:
        raise FormatError(f"channel {label}: points must be (offsets[-1], 2)")
    sizes = np.diff(offsets)
    if c and (sizes.min() < 4 or np.any((sizes - 1) % 3)):
        raise FormatError(f"channel {label}: every chain must have 1 + 3n points, n >= 1")
    nseg = (sizes - 1) // 3
    s = int(nseg.sum())
    if s > MAX_SEGMENTS:
        raise LimitError(f"channel {label}: {s} segments exceed the limit of {MAX_SEGMENTS}")
    border = np.asarray(ch.border)
    if border.shape != (s,):
        raise FormatError(f"channel {label}: border must have one flag per segment ({s})")
    parent = _int_array(ch.parent, label, "parent")
    if parent.shape[0] != c:
        raise FormatError(f"channel {label}: parent must have one entry per contour")
    cap_band = _int_array(ch.cap_band, label, "cap_band")
    k = cap_band.shape[0]
    if k > MAX_CAPS:
        raise LimitError(f"channel {label}: {k} caps exceed the limit of {MAX_CAPS}")
    cap_contour = _int_array(ch.cap_contour, label, "cap_contour")
    cap_xy = np.asarray(ch.cap_xy, dtype=np.float64)
    cap_value = np.asarray(ch.cap_value, dtype=np.float64)
    if cap_contour.shape != (k,) or cap_xy.shape != (k, 2) or cap_value.shape != (k,):
        raise FormatError(f"channel {label}: cap arrays must all have K = {k} entries")
    check_semantics(label, levels.shape[0], level, parent, cap_band, cap_contour)
    base_band = int(ch.base_band)
    if not 0 <= base_band <= levels.shape[0]:
        raise FormatError(f"channel {label}: base band {base_band} is outside [0, {levels.shape[0]}]")

    what = f"channel {label}: a control point"
    first = _quantise(points[offsets[:-1]], COORD_LIMIT, what)
    last = _quantise(points[offsets[1:] - 1], COORD_LIMIT, what)
    stored = _stored_points(points, offsets, what, in_place)
    del points
    if c and not np.array_equal(first, last):
        bad = int(np.flatnonzero(np.any(first != last, axis=1))[0])
        raise FormatError(f"channel {label}: contour {bad} is not closed (last point != first)")
    out = Checked()
    out.info = ChannelInfo(label, levels, base_band, c, s, k, tone, cap_ramp=cap_ramp)
    out.level, out.offsets, out.nseg, out.stored = level, offsets, nseg, stored
    out.border = border.astype(bool)
    out.parent, out.cap_band, out.cap_contour = parent, cap_band, cap_contour
    out.cq = _quantise(cap_xy, COORD_LIMIT, f"channel {label}: a cap position")
    out.vq = _quantise(cap_value, CAP_VALUE_LIMIT, f"channel {label}: a cap value")
    return out


def _int_array(a, label, what) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != 1 or (a.size and a.dtype.kind not in "iu"):
        raise FormatError(f"channel {label}: {what} must be a 1-D integer array")
    return a.astype(np.int64)


QUANTISE_CHUNK = 1 << 18  # rows _quantise rounds at a time (no whole-array temporaries)


def _quantised_chunks(a: np.ndarray, limit: int, what: str):
    """(first row, its chunk rounded to the 1/QUANT grid (halves to even) as int64) for each
    chunk of QUANTISE_CHUNK rows of ``a``, checked within (-limit, limit)."""
    a = np.asarray(a, dtype=np.float64)
    for i in range(0, a.shape[0] if a.ndim else 1, QUANTISE_CHUNK):
        part = a[i : i + QUANTISE_CHUNK] if a.ndim else a
        if not np.all(np.isfinite(part)):
            raise FormatError(f"{what} is not finite")
        scaled = np.rint(part * QUANT)
        if scaled.size and float(np.abs(scaled).max()) >= limit:
            raise LimitError(f"{what} lies beyond the format's limit of +-{limit // QUANT}")
        yield i, scaled.astype(np.int64)


def _quantise(a: np.ndarray, limit: int, what: str) -> np.ndarray:
    """Round to the 1/QUANT grid (halves to even), as int64 within (-limit, limit); a chunk
    of rows at a time (a 16 MP photograph's luma at `high` has 37 M points: its float
    temporaries were 1.2 GB)."""
    a = np.asarray(a, dtype=np.float64)
    out = np.empty(a.shape, np.int64)
    for i, rows in _quantised_chunks(a, limit, what):
        if a.ndim:
            out[i : i + rows.shape[0]] = rows
        else:
            out[...] = rows
    return out


def _stored_points(points: np.ndarray, offsets: np.ndarray, what: str, in_place: bool = False) -> np.ndarray:
    """(offsets[-1] - C, 2): _quantise(points) without each chain's closing point (what the
    file stores), made chunk by chunk: no whole (N, 2) temporaries beside it. With
    ``in_place``, in the memory of ``points`` where that is a C-contiguous writeable float64
    array: a chunk's rows go to rows before its end, all read by then."""
    closing = offsets[1:] - 1
    n = points.shape[0] - closing.shape[0]
    if in_place and points.dtype == np.float64 and points.flags.c_contiguous and points.flags.writeable:
        out = points.view(np.int64)[:n]
    else:
        out = np.empty((n, 2), np.int64)
    d = 0
    for i, rows in _quantised_chunks(points, COORD_LIMIT, what):
        keep = np.ones(rows.shape[0], bool)
        lo, hi = np.searchsorted(closing, [i, i + rows.shape[0]])
        keep[closing[lo:hi] - i] = False
        kept = rows[keep]
        out[d : d + kept.shape[0]] = kept
        d += kept.shape[0]
    return out
