"""Range-coded channels (compression 3, docs/format.md "Range-coded channels"), both ways:
the grids a channel's integers are put on, and the coder's calls (format/_coder/entropy.py)
with what each of its error statuses means."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ... import threads
from ...errors import FormatError
from ..limits import CAP_VALUE_LIMIT, COORD_LIMIT, FORMAT_VERSION, MAX_ANCHOR_SHIFT, MAX_GRID_SHIFT
from ..validate import check_semantics
from .._coder import entropy
from .layout import Checked, to_channel

PARALLEL_SEGMENTS = 20_000  # range-code channels in threads above this many segments
ANCHOR_CHUNK = 1 << 18  # anchors anchor_shift counts at a time (no whole-array temporaries)

assert entropy.LIMIT == COORD_LIMIT == CAP_VALUE_LIMIT


def map_channels(fn, items, n_segments):
    """[fn(x) for x in items], in threads for big images (the kernels release the GIL)."""
    if n_segments < PARALLEL_SEGMENTS or len(items) < 2 or threads.available() < 2:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(max_workers=threads.available(min(len(items), 4))) as pool:
        return list(pool.map(fn, items))


def grid_shift(a: np.ndarray) -> int:
    """The largest s <= MAX_GRID_SHIFT such that every value of ``a`` is a multiple of 2**s."""
    if a.size == 0:
        return 0
    bits = int(np.bitwise_or.reduce(a.ravel()))
    s = 0
    while s < MAX_GRID_SHIFT and bits & ((1 << (s + 1)) - 1) == 0:
        s += 1
    return s


def anchor_shift(anchors: np.ndarray) -> int:
    """The anchor grid g that saves the most bits (0: none), decided in integers.

    An anchor flag costs about 1.5 bits and an on-grid coordinate saves about g bits, so
    g scores 2 g (on-grid coordinates) - 3 (anchors). Points off any grid score < 0 for
    every g (a coordinate is on the 2**g grid with probability 2**-g, and g 2**(1-g) <= 1).
    """
    best, best_g = 0, 0
    n = anchors.shape[0]
    for g in range(1, MAX_ANCHOR_SHIFT + 1):
        on = sum(int(np.count_nonzero((anchors[i : i + ANCHOR_CHUNK] & ((1 << g) - 1)) == 0))
                 for i in range(0, n, ANCHOR_CHUNK))
        score = 2 * g * on - 3 * n
        if score > best:
            best, best_g = score, g
    return best_g


def range_channel(ch: Checked, version: int = FORMAT_VERSION, take: bool = False) -> bytes:
    """One channel range-coded (compression 3) in ``version``'s layout (2 to 5); sets its
    grids and coded size in ch.info. With ``take`` it shifts the channel's stored points onto
    their grid in place (ch.info.s_p says by how much; ``ch.stored << s_p`` gives them
    back), without a copy of them (16 bytes a point, 560 MiB of a 16 MP photograph's luma at
    `high`)."""
    info = ch.info
    pts = ch.stored if take else ch.stored.copy()
    info.s_p = grid_shift(pts)
    info.s_c = grid_shift(ch.cq)
    info.s_v = grid_shift(ch.vq)
    np.right_shift(pts, info.s_p, out=pts)
    info.g = anchor_shift(pts[0::3])
    coded, _ = code_channel(ch.level, ch.nseg, ch.parent, pts, ch.border.astype(np.uint8), info.g, ch.cap_contour,
                            ch.cap_band, ch.cq >> info.s_c, ch.vq >> info.s_v, info.s_p, info.s_c, info.s_v,
                            info.levels, info.base_band, version)
    info.coded_size = len(coded)
    return coded


def code_channel(level, nseg, parent, pts, border, g, cap_contour, cap_band, cap_xy, cap_value, s_p, s_c, s_v,
                 levels, base_band, version, account=False, workers=None):
    """A channel's coded bytes in ``version``'s layout (the arguments of entropy.encode_channel)
    and the bits spent per model (all 0 unless ``account``). From layout 5: the channel's own
    stream, its later parts of points (entropy.encode_part) side by side in ``workers`` threads
    (None: the processors'), their sizes (u32) and their count (u32); the same bytes whatever
    the threads."""
    pts = np.ascontiguousarray(pts)
    starts = entropy.part_starts(nseg, entropy.PART_SEGMENTS if version >= 5 else 0)
    t0 = entropy.first_points(nseg)

    def part(p):  # p = 0: the channel's own stream (contours, the first part, caps)
        if p == 0:
            return entropy.encode_channel(level, nseg, parent, pts, border, g, cap_contour, cap_band,
                                          np.ascontiguousarray(cap_xy), cap_value, s_p, s_c, s_v, levels, base_band,
                                          version, account, entropy.PART_SEGMENTS)
        st = entropy.new_state(account)
        return entropy.encode_part(st, pts, border, nseg, starts[p], starts[p + 1], t0, g, version), st[6:] / 1e6

    n = starts.shape[0] - 1
    workers = threads.available(n) if workers is None else max(1, min(workers, n))
    if workers > 1:  # the parts are independent streams: side by side
        with ThreadPoolExecutor(max_workers=workers) as pool:
            parts = list(pool.map(part, range(n)))
    else:
        parts = [part(p) for p in range(n)]
    coded = parts[0][0].tobytes()
    if version >= 5:
        coded += b"".join(p.tobytes() for p, _ in parts[1:])
        coded += b"".join(len(p).to_bytes(4, "little") for p, _ in parts[1:]) + (n - 1).to_bytes(4, "little")
    bits = parts[0][1].copy()
    if account:
        for _, b in parts[1:]:
            bits += b
    return coded, bits


# What each decoder status means: (message template, with {where} and {extra}).
RANGE_ERRORS = {
    entropy.E_RANK: "contour {where}: parent candidate {extra} does not exist",
    entropy.E_PARENT: "parent {extra} (entry {where}) is outside [-1, {c})",
    entropy.E_LEVEL: "contour level {extra} (entry {where}) is outside [0, {L})",
    entropy.E_NSEG: "contours have more than {s} segments, the header declares {s}",
    entropy.E_NSEG_SHORT: "contours have {extra} segments, the header declares {s}",
    entropy.E_POINT: "a control point of contour {where} lies beyond the format's limit",
    entropy.E_CAP_CONTOUR: "cap contour {extra} (entry {where}) is outside [-1, {c})",
    entropy.E_CAP_XY: "cap position {where} lies beyond the format's limit",
    entropy.E_CAP_VALUE: "cap value {where} lies beyond the format's limit",
    entropy.E_SHORT: "range-coded data ends early (truncated or corrupted)",
    entropy.E_LONG: "range-coded data has bytes left over (corrupted)",
    entropy.E_SHIFT: f"a handle shift in contour {{where}} is above {entropy.MAX_HANDLE_SHIFT}",
    entropy.E_PARTS: "the table of its parts of points ({extra} after the first) fits neither its data nor its contours",
}


def decode_range_channel(item):
    """One channel off its range-coded bytes: ``item`` is (ChannelInfo, bytes, version,
    compact) (compact: layout.to_channel's)."""
    info, data, version, compact = item
    c, s, k = info.n_contours, info.n_segments, info.n_caps
    args = (data, c, s, k, info.g, info.s_p, info.s_c, info.s_v, info.levels, info.base_band, version)
    (status, where, extra, level, nseg, parent, q, border, cap_contour, cap_band, cq, vq) = \
        entropy.decode_channel(*args) if version < 5 else decode_parts(*args, points32=compact)
    if status != entropy.OK:
        msg = RANGE_ERRORS[status].format(where=where, extra=extra, c=c, s=s, L=info.levels.shape[0])
        raise FormatError(f"channel {info.name}: {msg}")
    check_semantics(info.name, info.levels.shape[0], level, parent, cap_band, cap_contour)
    offsets = np.zeros(c + 1, np.int64)
    np.cumsum(3 * nseg + 1, out=offsets[1:])
    return to_channel(info, level, offsets, q, border, parent, cap_band, cap_contour, cq, vq, compact)


def decode_parts(data, c, s, k, g, s_p, s_c, s_v, levels, base_band, version, workers=None, points32=False):
    """entropy.decode_channel for layout 5 (uint8 data): the channel's stream (contours, the
    points' first part, caps), its other parts of points, each its own stream, their sizes
    (u32) and their count (u32) last. The parts are decoded side by side, in ``workers``
    threads (None: the processors'); each writes its own rows of the points, so the result
    does not depend on how many. ``points32``: the points int32 (half the bytes, for a
    compact load: layout.grid_to_float32); the decoder checks every value against the
    format's limit (2**30) before it stores it, so none wraps."""
    n = data.shape[0]
    count = int.from_bytes(data[n - 4:n].tobytes(), "little") if n >= 4 else -1
    table = n - 4 - 4 * count
    fits = 0 <= count <= max(c - 1, 0) and table >= 0
    sizes = np.frombuffer(data[table:n - 4].tobytes(), "<u4").astype(np.int64) if fits else np.zeros(0, np.int64)
    main_len = table - int(sizes.sum())
    q = np.zeros((3 * s + c, 2), np.int32 if points32 else np.int64)
    border = np.zeros(s, np.uint8)
    caps = entropy.new_caps(k)
    if not fits or main_len < 0:
        return (entropy.E_PARTS, 0, count, np.zeros(c, np.int64), np.zeros(c, np.int64), np.zeros(c, np.int64), q,
                border, *caps)
    main = data[:main_len]
    status, where, extra, level, nseg, parent, ds, probs = entropy.decode_contours(main, c, s, levels.shape[0])
    starts = entropy.part_starts(nseg, entropy.PART_SEGMENTS)
    if status == entropy.OK and starts.shape[0] - 2 != count:
        status, where, extra = entropy.E_PARTS, starts.shape[0] - 1, count
    if status != entropy.OK:
        return (status, where, extra, level, nseg, parent, q, border, *caps)
    first = np.zeros(c, np.int64)
    ends = main_len + np.cumsum(sizes)

    def part(p):
        args = (nseg, q, border, first, int(starts[p]), int(starts[p + 1]), g, s_p, version)
        if p == 0:  # the channel's own stream, after its contours
            return entropy.decode_part(ds, main, probs, *args)
        inp = data[ends[p - 1] - sizes[p - 1]:ends[p - 1]]
        pds, pprobs = entropy.start_part(inp)
        status, where, extra = entropy.decode_part(pds, inp, pprobs, *args)
        return (entropy.end_part(pds, inp), starts[p + 1], 0) if status == entropy.OK else (status, where, extra)

    workers = threads.available(count + 1) if workers is None else max(1, min(workers, count + 1))
    if workers > 1:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            results = list(pool.map(part, range(count + 1)))
    else:
        results = [part(p) for p in range(count + 1)]
    for status, where, extra in results:
        if status != entropy.OK:
            return (status, where, extra, level, nseg, parent, q, border, *caps)
    entropy.shift_points(q, s_p)
    status, where, extra = entropy.decode_caps(ds, main, probs, level, q, first, s_c, s_v, levels, base_band, *caps)
    return (status, where, extra, level, nseg, parent, q, border, *caps)
