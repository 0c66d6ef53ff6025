"""The column layout of compressions 0, 1 and 2, both ways (docs/format.md, "Column layout"):
zigzagged differences in byte planes."""

from __future__ import annotations

import numpy as np

from ...errors import FormatError
from ...shared.grid import QUANT
from ..limits import CAP_VALUE_LIMIT, COORD_LIMIT
from ..validate import check_semantics
from .layout import Checked, ChannelInfo, cap_origins, closed_points, to_channel


def zigzag(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.int64)
    return (v << 1) ^ (v >> 63)


def unzigzag(u: np.ndarray) -> np.ndarray:
    u = np.asarray(u, dtype=np.int64)  # u32 values: no overflow
    return (u >> 1) ^ -(u & 1)


def planes(values, width: int) -> bytes:
    """A column as ``width`` byte planes, least significant first (values fit the width)."""
    v = np.ascontiguousarray(values, dtype=np.int64).ravel().astype(f"<u{width}")
    return v.view(np.uint8).reshape(-1, width).T.tobytes()


class Columns:
    """Reads a channel's columns off the raw payload, in order."""

    def __init__(self, raw: bytes):
        self.buf = np.frombuffer(raw, dtype=np.uint8)
        self.pos = 0

    def take(self, n: int) -> np.ndarray:
        if self.pos + n > self.buf.shape[0]:  # the header's raw_size check makes this moot
            raise FormatError("payload ends inside a column")
        out = self.buf[self.pos : self.pos + n]
        self.pos += n
        return out

    def column(self, n: int, width: int) -> np.ndarray:
        """n values of ``width`` bytes, as int64."""
        planes = self.take(n * width).reshape(width, n)
        return np.ascontiguousarray(planes.T).view(f"<u{width}").ravel().astype(np.int64)


def column_channel(ch: Checked) -> bytes:
    """One channel in the column layout (compressions 0, 1 and 2)."""
    c = ch.level.shape[0]
    d = np.diff(ch.stored, axis=0, prepend=np.zeros((1, 2), np.int64))
    columns = [
        planes(zigzag(np.diff(ch.level, prepend=0)), 2),
        planes(ch.nseg - 1, 4),
        planes(np.where(ch.parent < 0, 0, zigzag(np.arange(c) - ch.parent)), 4),
        planes(zigzag(d), 4),
        planes(ch.cap_band, 2),
        planes(zigzag(np.diff(ch.cap_contour, prepend=-1)), 4),
        planes(zigzag(ch.cq - cap_origins(ch.stored, ch.offsets, ch.cap_contour)), 4),
        planes(zigzag(ch.vq), 4),
        np.packbits(ch.border, bitorder="little").tobytes(),
    ]
    return b"".join(columns)


def _check_limit(q: np.ndarray, limit: int, what: str) -> None:
    if q.size and int(np.abs(q).max()) >= limit:
        raise FormatError(f"{what} lies beyond the format's limit of +-{limit} (1/{QUANT} units)")


def decode_column_channel(cols: Columns, info: ChannelInfo, compact: bool = False):
    """One channel off the column layout (compact: layout.to_channel's)."""
    label, c, s, k = info.name, info.n_contours, info.n_segments, info.n_caps
    level = np.cumsum(unzigzag(cols.column(c, 2)))
    nseg = cols.column(c, 4) + 1
    pcode = cols.column(c, 4)
    d = unzigzag(cols.column(6 * s, 4)).reshape(-1, 2)  # |d| <= 2**31
    cap_band = cols.column(k, 2)
    cap_contour = np.cumsum(unzigzag(cols.column(k, 4))) - 1
    cq = unzigzag(cols.column(2 * k, 4)).reshape(-1, 2)
    vq = unzigzag(cols.column(k, 4))
    border_bits = np.unpackbits(cols.take((s + 7) // 8), bitorder="little")

    if int(nseg.sum()) != s:
        raise FormatError(
            f"channel {label}: contours have {int(nseg.sum())} segments, the header declares {s}"
        )
    parent = np.where(pcode == 0, -1, np.arange(c, dtype=np.int64) - unzigzag(pcode))
    check_semantics(label, info.levels.shape[0], level, parent, cap_band, cap_contour)

    # Points: running sums along the stream (3 S values of at most 2**31: no overflow).
    stored = np.cumsum(d, axis=0)
    _check_limit(stored, COORD_LIMIT, f"channel {label}: a control point")
    offsets = np.zeros(c + 1, np.int64)
    np.cumsum(3 * nseg + 1, out=offsets[1:])
    cq = cq + cap_origins(stored, offsets, cap_contour)  # cap_contour was checked above
    q = closed_points(stored, offsets)
    del stored
    _check_limit(cq, COORD_LIMIT, f"channel {label}: a cap position")
    _check_limit(vq, CAP_VALUE_LIMIT, f"channel {label}: a cap value")

    if np.any(border_bits[s:]):
        raise FormatError(f"channel {label}: padding bits after the border flags are not zero")
    return to_channel(info, level, offsets, q, border_bits[:s], parent, cap_band, cap_contour, cq, vq, compact)
