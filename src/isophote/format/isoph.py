"""The .isoph binary format: a VectorImage on disk.

This docstring is the specification; docs/format.md says the same for readers who do not read
Python. Every multi-byte number is LITTLE-ENDIAN. CRC-32 is the ISO-HDLC one of zlib and PNG
(``zlib.crc32``). Offsets are in bytes from the start of the file. This module writes version
4 and reads versions 1 to 4 (version 3 is version 4 less the handle shifts of its range-coded
channels, version 2 is version 3 with other predictions there, version 1 is version 2 less
tone curves, grids and range coding; their differences are listed under "Version 3",
"Version 2" and "Version 1").

Overview
========
A file is a header that can be read on its own, then one payload::

    +---------------------------------------------+  offset 0
    | preamble (16 bytes, the same in every       |
    |   version)                                  |
    | header body (fixed fields, meta JSON, one   |
    |   summary per channel)                      |
    | header_crc (u32)                            |  ends at offset header_size
    +---------------------------------------------+
    | payload (payload_size bytes)                |  ends at the end of the file
    +---------------------------------------------+

Nothing may follow the payload. The header holds everything ``isophote info`` shows (size,
colour, every channel's levels, tone curve and counts) and declares every count before any
array is read, so a reader checks the counts against the limits below and against the
payload size before it allocates anything.

Preamble (16 bytes, version-independent)
----------------------------------------
::

    offset size  field
     0     8     magic        89 49 53 4F 50 48 0D 0A   ("\\x89ISOPH\\r\\n")
     8     u16   version      4
    10     u16   reserved     0
    12     u32   header_size  bytes from offset 0 to the end of header_crc

The magic's first byte has its high bit set and its last two are CR LF, so 7-bit transfers and
newline conversion both break it (the trick of PNG's signature). Every version keeps this
preamble and keeps ``header_crc`` in the last 4 bytes of the header, so a reader checks the
checksum first and only then trusts ``version``: a corrupted version number reads as
corruption, a genuine newer file as "unsupported version N".

Header body
-----------
::

    offset size  field
    16     u32   width          canvas width in source pixels, 1 .. MAX_WIDTH
    20     u32   height         canvas height in source pixels, 1 .. MAX_HEIGHT
    24     u8    colour         0 = "grey", 1 = "yuv"
    25     u8    source_depth   8 or 16 (informational)
    26     u8    n_channels     1 .. MAX_CHANNELS (see "Channels" below)
    27     u8    compression    0 = stored, 1 = zlib, 2 = LZMA2, 3 = range (see "Payload")
    28     u16   xy_quant       64: coordinates are integers in 1/64 source pixel
    30     u16   value_quant    64: cap values are integers in 1/64 grey level
    32     u64   payload_size   bytes of the payload as stored after the header
    40     u64   raw_size       bytes of the payload in the column layout (see "Payload")
    48     u32   payload_crc    CRC-32 of the payload_size stored payload bytes
    52     u32   meta_size      0 .. MAX_META_BYTES
    56     ...   meta           meta_size bytes: a UTF-8 JSON object (nothing if meta_size 0)
    then n_channels channel summaries of 39 + 8 L + 16 T bytes each:
           u8    name           ASCII "Y", "U", "V" or "A"
           u16   n_levels       L, 0 .. MAX_LEVELS
           u16   base_band      band of the root region (Channel.base_band), 0 .. L
           u32   n_contours     C, 0 .. n_segments (every contour has at least 1 segment)
           u32   n_segments     S, over all the channel's contours, 0 .. MAX_SEGMENTS
           u32   n_caps         K, 0 .. MAX_CAPS
           u16   n_tone         T: 0 = no tone curve, else 2 .. MAX_TONE_KNOTS knots
           u8    point_shift    s_p, 0 .. 6: control points on the 1/(64 >> s_p) px grid
           u8    anchor_shift   g, 0 .. 16: the anchor grid (range coding; 0 = none)
           u8    cap_shift      s_c, 0 .. 6: cap positions on the 1/(64 >> s_c) px grid
           u8    value_shift    s_v, 0 .. 6: cap values on the 1/(64 >> s_v) grey-level grid
           u64   coded_size     bytes of this channel's range-coded data (0 unless range)
           f64   levels[L]      finite, strictly increasing
           f64   tone[2 T]      knots x0, y0, x1, y1, ...: finite, x strictly increasing,
                                y non-decreasing (Channel.tone)
           f64   cap_ramp       the caps' longest ramp in pixels (Channel.cap_ramp): > 0,
                                finite or +infinity (DOME: caps without a plateau)
    then   u32   header_crc     CRC-32 of bytes [0, header_size - 4)

Both quanta must be 64: they are the finest grids, and the shifts make coarser ones per
channel. With compression 0, 1 or 2 every shift and coded_size must be 0 (the column layout
is always on the 1/64 grids); with compression 3 the coded sizes add up to payload_size.
Channels are in the data model's canonical order: "grey" has Y, or Y and A; "yuv" has Y, U,
V, or Y, U, V and A. A channel with contours has levels (C > 0 needs L > 0).

``meta`` holds ``VectorImage.meta`` as JSON with sorted keys and no spaces, so that equal
dicts give equal bytes. It round-trips as JSON does: tuples come back as lists and keys as
strings; NumPy scalars and arrays are written as numbers and lists; anything else, NaN and
infinity included, cannot be written, and a reader refuses them too (``NaN``, ``Infinity``
and ``1e400`` are not JSON numbers), so whatever loads can be saved again.
``VectorImage.equals`` ignores meta.

Payload
-------
``compression`` says how the payload is stored:

- 0, stored: the raw column layout itself (``payload_size == raw_size``).
- 1, zlib: the column layout in one zlib stream (RFC 1950), written at level 6.
- 2, LZMA2: the column layout in one raw LZMA2 stream (no .xz container) whose dictionary is
  at most LZMA_DICT_SIZE = 8 MiB; a reader decodes it with an 8 MiB dictionary. The writer
  uses preset 6.
- 3, range (the writer's default): each channel's range-coded data (see "Range-coded
  channels"), channel after channel, ``coded_size`` bytes each.

A zlib or LZMA2 stream must decompress to exactly ``raw_size`` bytes and end exactly at the
end of the file. Whatever the compression, ``raw_size`` is the size of the column layout,
``sum(10 C + 24 S + 18 K + ceil(S / 8))``, and may not exceed ``MAX_EXPANSION *
payload_size + EXPANSION_SLACK``: this bounds the work and memory of reading any file by
its size. The writer stores the payload (code 0) in the rare case that a compressor does
better than that (thousands of identical contours).

Column layout (compressions 0, 1, 2)
------------------------------------
The raw payload is the channels' columns, channel after channel in header order, and
nothing else. A column of n values of width w bytes (u16: w = 2, u32: w = 4) is stored as w
BYTE PLANES of n bytes each, least significant first: plane j holds byte j of every value::

    values     0x0102  0x0304  0x0506              (u16, n = 3)
    stored     02 04 06 | 01 03 05                 (plane 0, then plane 1)

``zz(v)`` is the zigzag map from signed to unsigned: 0, -1, 1, -2, 2 ... -> 0, 1, 2, 3, 4 ...
(``(v << 1) ^ (v >> 63)``). For a channel with L levels, C contours, S segments and K caps::

    column        values  width  value                       meaning
    level         C       u16    zz(lev[k] - lev[k-1])       contour_level, lev[-1] = 0
    n_segments    C       u32    n[k] - 1                    n[k] >= 1 segments in contour k
    parent        C       u32    0, or zz(k - parent[k])     0 = the frame (parent -1)
    points        6 S     u32    zz(dx), zz(dy), ...         see "Points"
    cap_band      K       u16    cap_band[i]                 0 .. L
    cap_contour   K       u32    zz(cc[i] - cc[i-1])         cap_contour, cc[-1] = -1
    cap_xy        2 K     u32    zz(dx), zz(dy), ...         see "Caps"
    cap_value     K       u32    zz(v)                       in 1/64 grey level
    border        ceil(S/8) bytes, not a column              see "Border"

Points: contour k's chain has 1 + 3 n[k] control points P0, C0a, C0b, P1, ..., Pn and is
closed (Pn == P0), so the closing point is not stored; the other 3 n[k] are, as integers on
the 1/64-pixel grid (``round(x * 64)``). The stored points of all the channel's chains, in
order, make one stream of 3 S points, each stored as its difference from the point before
it in the stream (the first from (0, 0)); the (dx, dy) pairs make one column of 6 S values.

Caps: a cap's position is stored as its difference from the first control point (P0) of
its contour ``cap_contour[i]``, or from (0, 0) when that is -1 (the root region).

Border: the flag of segment s (segments of all contours, in order) is bit ``s % 8`` (least
significant first) of byte ``s // 8``; the padding bits of the last byte are zero.

Parent: ``k - parent[k]`` is never 0 (a contour is not its own parent), which frees 0 for the
frame.

Range-coded channels (compression 3)
------------------------------------
Each channel is one stream of a binary range coder with adaptive probabilities; the symbols
are integers predicted from what came before, and each integer is coded with the adaptive
*model* its context picks, so that the probabilities follow the statistics of each kind of
number. _kernels/entropy.py implements it (its docstring gives the coder's arithmetic:
LZMA's range coder without its always-zero first byte, 15-bit probabilities, each the mean
of a 1/16 and a 1/128 adaptation; unsigned integers as a unary bit length and mantissa
bits, signed ones as magnitude and sign), and _kernels/entropy_ref.py is a plain-Python
twin written from this text. The decoder must read exactly ``coded_size`` bytes.

Integers are on the channel's grids: a control point's coordinates are ``round(x * 64) >>
s_p`` (the writer picks the largest s_p <= 6 that loses nothing), cap positions ``>> s_c``
and cap values ``>> s_v`` likewise. ``bucket(v)`` is the bit length of |v|, at most NB - 1
= 11; ``rnd3(v) = floor((v + 1) / 3)`` is v / 3 rounded. In this order:

1. Contours, k = 0 .. C-1. The parent *candidates* of contour k are k - 1, its parent, that
   one's parent and so on: at most PATH_MAX = 32 of them, stopping after the first that is
   -1 (the frame) or not below k. ``rank`` = 1 + the position of parent[k] in that list, or
   0 if it is not there (unsigned, model by min(previous rank, 3)); for rank 0,
   ``k - parent[k]`` follows. Then the level: ``level[k] - level[parent[k]]`` when
   0 <= parent[k] < k, else ``level[k] - level[k-1]`` (level[-1] = 0). Then n[k] - 1.
2. Points, contour after contour. Anchors (the points P_i) fitted to isolines traced on a
   sample grid lie with at least one coordinate on that grid; ``anchor_shift`` g > 0 names
   it (2**g units of the point grid; the writer picks g when it saves bits): each anchor
   then first gets a flag f = (x on the grid) + 2 (y on the grid), and an on-grid
   coordinate is coded as ``(x >> g) - ((x_before + 2**(g-1)) >> g)``, an off-grid one as
   ``x - x_before``. P0 comes first, after the previous contour's P0 ((0, 0) at first).
   Then each segment i from A = P_i to N = P_{i+1}: its border flag (context: the previous
   segment's flag, or the first segment); unless it is the last segment (whose N is P0),
   N's flag (context: A's flag) and N's coordinates after those of the prediction
   ``B = A + (e >> 1)``, e the previous segment's chord in this contour ((0, 0) for the
   first segment; ``>>`` an arithmetic shift of each coordinate) (x: model by border flag
   and bucket of the previous segment's max(|e.x|, |e.y|); y: by border flag and
   bucket(N.x - A.x)); then the handles as residuals against a straight segment,
   ``h = Ca - A - rnd3(d)`` and ``r = Cb - N + rnd3(d)`` with d = N - A, turned into the
   chord's frame: ``(h.a, h.c) = rot_d(h)`` and ``(r.a, r.c) = rot_d(r)`` (a along the
   chord, c across it). A non-border segment first gets its *handle shift* sh: the largest
   integer <= MAX_HANDLE_SHIFT = 5 such that 2**sh divides h.a, h.c, r.a and r.c (unsigned,
   model by the previous non-border segment's sh in this channel, 0 at first, and by
   max|d|: bucket <= 7, <= 9, larger); the four terms are then divided by 2**sh (exactly),
   and border segments take sh = 0 without coding it. The terms are coded as h.a, h.c,
   ``r.a + ((h.a + 1) >> 1)`` (the two handles tend to grow and shrink together), r.c.
   Models: h.a by border flag and bucket(max|d|); h.c and the r.a term by bucket(h.a) and
   bucket(max|d|); r.c by bucket(h.c) and bucket(max|d|); border segments have their own
   models for h.c, r.a and r.c. A reader multiplies the terms by 2**sh back and rejects a
   shift above MAX_HANDLE_SHIFT.

   The shift is what makes the encoder's coarse handles cheap: it puts each segment's
   handles on the coarsest of these grids (2**sh / 64 px in the chord's frame, sh <= 5) on
   which the segment still lies inside its error ribbon (encoder/fit.py), so most handle
   terms lose 3 to 5 low bits that would otherwise cost about a bit each.

   ``rot_d`` is an integer rotation by minus the angle of d in three lifting shears, exact
   and exactly invertible. If d.x < 0, or d.x = 0 and d.y < 0, d is negated and s = -1,
   else s = 1. With L = sqrt(d.x^2 + d.y^2), p = d.y / (L + d.x) and q = -d.y / L, all in
   IEEE-754 double arithmetic (correctly rounded, no fused multiply-add), and
   [t] = floor(t + 0.5) of a double: x += [p y]; y += [q x]; x += [p y]; rot_d(v) =
   (s x, s y). For d = (0, 0) it is the identity. The inverse undoes the shears in
   reverse order (x -= [p y]; y -= [q x]; x -= [p y], after x, y = s a, s c).
3. Caps: ``cap_contour[i] - cap_contour[i-1]`` (cc[-1] = -1); the band,
   ``cap_band - level[cc]`` (or ``cap_band - base_band`` for cc = -1); the position after
   the contour's P0 rounded to the cap grid (``(P0 + half) >> s_c``, (0, 0) for cc = -1);
   the value after ``floor(clamp(levels[level[cc]] * 64, +-2**30) + 0.5) >> s_v`` (0 for
   cc = -1), in a model chosen by the band's relation (0, 1 or other).

The exact contexts and the order of every bit are those of the two implementations, which
the tests hold to the same bytes. On the corpus photographs this coding takes about 35 bits a
segment, everything included: 0.51 of the column layout under zlib (benchmarks/coding.py and
benchmarks/results/coding.md, which measure each step and stream).

Version 3
---------
Version 3 has version 4's header and payload less the handle shifts: every handle term is
coded as it is (sh = 0 throughout, nothing coded for it). On the corpus photographs, with
the encoder's coarse handles, version 4 files are 26 % smaller than version 3 files of
handles fitted on the 1/64 grid (balanced preset, 0.18 dB less PSNR); on handles with no
coarse grid version 4 spends only the shifts' bits more.

Version 2
---------
Version 2 has version 3's header and payload, less the channel summaries' cap_ramp (31 + 8 L
+ 16 T bytes each; every channel has model.py's CAP_RAMP); only two predictions of its
range-coded channels differ (3.6 % more bytes on the corpus photographs): N's coordinates come after A's
own (B = A), and the handles' residuals h and r are coded as they are, in x and y: h.x by
border flag and bucket(max|d|), h.y by bucket(h.x) and bucket(max|d|), r.x and r.y by
bucket(max(|h.x|, |h.y|)) and bucket(max|d|); border segments have their own models for
h.y, r.x and r.y. This module reads it; ``dumps`` writes version 4.

Version 1
---------
Version 1 (isophote 0.1) has a 17 + 8 L byte channel summary (name .. n_caps and the
levels: no n_tone, shifts or coded_size, hence no tone curves) and compressions 0, 1 and 2
only. This module reads it; ``dumps`` writes version 4.

Precision
---------
The writer rounds control points and cap positions to the nearest 1/64 pixel and cap values
to the nearest 1/64 grey level (halves to even); levels and tone knots are float64, exact. So
``loads(dumps(vi))`` equals ``vi`` exactly (``VectorImage.equals``) when vi's coordinates and
cap values are already on those grids, which the encoder guarantees, and otherwise equals vi
so rounded (at most 1/128 px and 1/128 grey level away; the encoder's error ribbons are at
least 0.05 px wide). Coarser grids (the encoder's QUANT) are found and used by the writer;
they never lose anything. ``loads`` returns canonical dtypes: float64 levels, points,
cap_xy, cap_value and tone; int32 contour_level, parent, cap_band and cap_contour; int64
offsets; bool border.

Validation
----------
Never trust a file. ``loads`` rejects with a FormatError (a LimitError for a size over a
limit) whose one-line message says what is wrong: bad magic; truncation or trailing bytes;
header or payload checksum mismatch; unknown version, reserved bits, compression, quanta,
shifts, colour, depth or channel layout; a count over its limit or not matching the payload
size; levels not finite and strictly increasing; a bad tone curve or cap ramp; a base band
outside [0, L]; a payload that does not decompress to exactly raw_size bytes, or range-coded data that
ends early or has bytes left over; a contour level outside [0, L); segment counts that do
not add up to S; a parent outside [-1, C), a parent candidate that does not exist, or parents
that form a cycle; a cap band outside [0, L], a cap contour outside [-1, C); a handle shift
above MAX_HANDLE_SHIFT; a coordinate or cap value beyond its limit; non-zero padding bits. All header checks come before the payload
is decompressed or decoded, so the work on any file is bounded by its size. CRC-32 catches
every error burst of up to 32 bits, so any corrupted byte is reported; the checks behind it
make crafted files safe too.

Limits, with their reasons
--------------------------
MAX_WIDTH = MAX_HEIGHT = 2**20
    2**20 px a side is far beyond any camera; with control points allowed well outside the
    frame (COORD_LIMIT), every coordinate times 64 still fits in int32.
MAX_LEVELS = 1024
    Four levels per grey step of the 0..255 scale: finer levels carry no information an
    8-bit-scale rendering can show, and the level list (8 KiB a channel) stays a small part
    of a header that is read on its own.
MAX_TONE_KNOTS = 4096
    A knot per 1/16 grey level: more than any remapping of at most MAX_LEVELS levels needs
    (64 KiB a channel).
MAX_CHANNELS = 4
    Y, U, V and alpha.
MAX_META_BYTES = 65536
    meta describes the file (source, options); it is not image data, and it sits in the
    header, which ``read_info`` reads whole.
MAX_SEGMENTS = MAX_CAPS = 2**28 per channel
    Over 6 GB of raw payload, far beyond what a 100-megapixel photograph
    (imageio.MAX_INPUT_PIXELS) yields; it keeps every count and index inside the u32 fields
    and every running sum of coordinates inside int64 (3 S * 2**31 < 2**63).
COORD_LIMIT = 2**30 (in 1/64 px: |coordinate| < 2**24 px)
    Bezier control points may lie outside the canvas, but not absurdly far (16 times
    MAX_WIDTH); differences of two coordinates then fit a zigzagged u32.
CAP_VALUE_LIMIT = 2**30 (in 1/64 grey level: |value| < 2**24)
    Cap values live on the 0..255 scale with some overshoot; beyond this is garbage.
MAX_EXPANSION = 64, EXPANSION_SLACK = 1 MiB
    raw_size <= 64 * payload_size + 1 MiB. Photograph payloads are 3.5 (zlib) to 5.5 (range)
    times smaller than their column layout, so this never binds them, but it bounds decoding
    work and memory by the file's size: a small file cannot be a decompression bomb.
MAX_HEADER_BYTES
    The largest header the limits above allow (about 350 KiB).
"""

from __future__ import annotations

import json
import lzma
import os
import struct
import zlib
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..shared.grid import QUANT  # coordinates in 1/QUANT px, cap values in 1/QUANT grey level
from ._coder import entropy
from ..errors import FormatError, LimitError
from ..imageio import atomic_write_bytes
from ..model import CAP_RAMP, DOME, Channel, VectorImage

# ---- magic numbers: every constant of the format, in one place ----------------------------

MAGIC = b"\x89ISOPH\r\n"
FORMAT_VERSION = 4  # written
READ_VERSIONS = (1, 2, 3, 4)  # read

COLOUR_CODES = {"grey": 0, "yuv": 1}
COLOUR_NAMES = {v: k for k, v in COLOUR_CODES.items()}
SOURCE_DEPTHS = (8, 16)
# The channel layouts of the data model, in its canonical order.
CHANNEL_LAYOUTS = {
    "grey": (("Y",), ("Y", "A")),
    "yuv": (("Y", "U", "V"), ("Y", "U", "V", "A")),
}

COMPRESSION_STORED = 0
COMPRESSION_ZLIB = 1
COMPRESSION_LZMA = 2
COMPRESSION_RANGE = 3
COMPRESSION_CODES = {"none": COMPRESSION_STORED, "zlib": COMPRESSION_ZLIB, "lzma": COMPRESSION_LZMA,
                     "range": COMPRESSION_RANGE}
COMPRESSION_NAMES = {v: k for k, v in COMPRESSION_CODES.items()}
DEFAULT_COMPRESSION = "range"
ZLIB_LEVEL = 6
LZMA_DICT_SIZE = 1 << 23  # 8 MiB
LZMA_PRESET = 6
_LZMA_WRITE_FILTERS = [{"id": lzma.FILTER_LZMA2, "preset": LZMA_PRESET, "dict_size": LZMA_DICT_SIZE}]
_LZMA_READ_FILTERS = [{"id": lzma.FILTER_LZMA2, "dict_size": LZMA_DICT_SIZE}]
MAX_GRID_SHIFT = 6  # point, cap and value grids: 1/64 .. 1/1
MAX_ANCHOR_SHIFT = 16
PARALLEL_SEGMENTS = 20_000  # range-code channels in threads above this many segments

# ---- limits (their reasons are in the module docstring) -----------------------------------

MAX_WIDTH = 1 << 20
MAX_HEIGHT = 1 << 20
MAX_LEVELS = 1024
MAX_TONE_KNOTS = 4096
MAX_CHANNELS = 4
MAX_META_BYTES = 1 << 16
MAX_SEGMENTS = 1 << 28
MAX_CAPS = 1 << 28
COORD_LIMIT = 1 << 30  # exclusive, in 1/QUANT px
CAP_VALUE_LIMIT = 1 << 30  # exclusive, in 1/QUANT grey level
MAX_EXPANSION = 64
EXPANSION_SLACK = 1 << 20

# ---- byte layout ---------------------------------------------------------------------------

_PREAMBLE = struct.Struct("<8sHHI")  # magic, version, reserved, header_size
_FIXED = struct.Struct("<IIBBBBHHQQII")  # width .. meta_size: offsets 16 .. 56
# name, n_levels, base_band, n_contours, n_segments, n_caps, n_tone, point_shift,
# anchor_shift, cap_shift, value_shift, coded_size
_CHANNEL = struct.Struct("<cHHIIIHBBBBQ")
_CHANNEL_V1 = struct.Struct("<cHHIII")  # name .. n_caps
_CAP_RAMP = struct.Struct("<d")  # after the levels and tone knots (versions 3 and 4)
_CRC = struct.Struct("<I")
PREAMBLE_BYTES = _PREAMBLE.size  # 16
_MIN_HEADER_BYTES = PREAMBLE_BYTES + _FIXED.size + _CHANNEL_V1.size + _CRC.size
MAX_HEADER_BYTES = (
    PREAMBLE_BYTES + _FIXED.size + MAX_META_BYTES
    + MAX_CHANNELS * (_CHANNEL.size + 8 * MAX_LEVELS + 16 * MAX_TONE_KNOTS + _CAP_RAMP.size) + _CRC.size
)

assert entropy.LIMIT == COORD_LIMIT == CAP_VALUE_LIMIT

__all__ = [
    "dumps", "loads", "save", "load", "read_info",
    "MAGIC", "FORMAT_VERSION", "READ_VERSIONS", "QUANT", "DEFAULT_COMPRESSION",
    "MAX_WIDTH", "MAX_HEIGHT", "MAX_LEVELS", "MAX_TONE_KNOTS", "MAX_CHANNELS", "MAX_META_BYTES",
    "MAX_SEGMENTS", "MAX_CAPS", "COORD_LIMIT", "CAP_VALUE_LIMIT",
    "MAX_EXPANSION", "EXPANSION_SLACK", "MAX_HEADER_BYTES",
]


# =============================================================================================
# Public API
# =============================================================================================


def dumps(vi: VectorImage, compression: str = DEFAULT_COMPRESSION) -> bytes:
    """Serialise a VectorImage to .isoph bytes (format version 4).

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
        bytes. Coordinates and cap values are rounded to the 1/64 grids (module docstring).

    Raises
    ------
    ValueError
        ``vi`` breaks the data model (unsorted levels, an open chain, cyclic parents, a
        tone curve that is not monotone, ...) or its meta cannot be written as JSON.
    LimitError
        A size, coordinate or cap value exceeds a limit of the format.
    """
    if compression not in COMPRESSION_CODES:
        raise ValueError(f"compression must be one of {', '.join(COMPRESSION_CODES)}, got {compression!r}")
    try:
        return _dumps(vi, COMPRESSION_CODES[compression])
    except FormatError as e:
        raise ValueError(f"cannot write .isoph: {e}") from None


def loads(data) -> VectorImage:
    """Parse .isoph bytes (bytes, bytearray or memoryview) into a VectorImage.

    Raises FormatError, or LimitError for a declared size over a limit, for anything that is
    not a valid .isoph file; never another exception type for bad data.
    """
    buf = bytes(data)

    def parse():
        h = _parse_header(buf, len(buf))
        return _decode(h, memoryview(buf)[h.header_size :])

    return _guarded(parse)


def save(vi: VectorImage, path, compression: str = DEFAULT_COMPRESSION) -> None:
    """Write ``vi`` to ``path`` atomically (a temporary file renamed into place)."""
    atomic_write_bytes(path, dumps(vi, compression=compression))


def load(path) -> VectorImage:
    """Read an .isoph file. FormatError (or LimitError) for unreadable or malformed files.

    The header is read and checked first; then exactly the payload it declares.
    """
    where = f"{os.fspath(path)}: "
    try:
        with open(path, "rb") as f:
            size, head = _read_head(f)
            h = _with_where(where, lambda: _guarded(lambda: _parse_header(head, size)))
            f.seek(h.header_size)
            payload = f.read(h.payload_size)
    except OSError as e:
        raise FormatError(f"{where}cannot read: {e.strerror or e}") from None
    if len(payload) != h.payload_size:
        raise FormatError(f"{where}truncated .isoph file: the file shrank while being read")
    return _with_where(where, lambda: _guarded(lambda: _decode(h, payload)))


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
                size, head = _read_head(f)
        except OSError as e:
            raise FormatError(f"{where}cannot read: {e.strerror or e}") from None
    h = _with_where(where, lambda: _guarded(lambda: _parse_header(head, size)))
    return {
        "format_version": h.version,
        "width": h.width,
        "height": h.height,
        "colour": h.colour,
        "source_depth": h.source_depth,
        "bytes": size,
        "compression": COMPRESSION_NAMES[h.compression],
        "meta": h.meta,
        "channels": [
            {
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
            for c in h.channels
        ],
    }


def _read_head(f):
    """(file size, the header's bytes as far as the preamble vouches for them)."""
    size = os.fstat(f.fileno()).st_size
    head = f.read(PREAMBLE_BYTES)
    if len(head) == PREAMBLE_BYTES and head[:8] == MAGIC:
        header_size = _PREAMBLE.unpack(head)[3]
        if header_size <= MAX_HEADER_BYTES:
            head += f.read(header_size - PREAMBLE_BYTES)
    return size, head


def _guarded(parse):
    """Run ``parse``; a stray low-level error from bad data becomes a FormatError."""
    try:
        return parse()
    except (FormatError, LimitError):
        raise
    except (ValueError, IndexError, OverflowError, struct.error, RecursionError) as e:
        # A last resort: every problem should meet its own check first (the tests say so).
        raise FormatError(f"malformed .isoph file ({type(e).__name__}: {e})") from None


def _with_where(where: str, parse):
    """Run ``parse``, prefixing its error messages with ``where`` (a path)."""
    try:
        return parse()
    except FormatError as e:
        raise FormatError(f"{where}{e}") from None
    except LimitError as e:
        raise LimitError(f"{where}{e}") from None


# =============================================================================================
# Columns: zigzag and byte planes
# =============================================================================================


def _zigzag(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.int64)
    return (v << 1) ^ (v >> 63)


def _unzigzag(u: np.ndarray) -> np.ndarray:
    u = np.asarray(u, dtype=np.int64)  # u32 values: no overflow
    return (u >> 1) ^ -(u & 1)


def _planes(values, width: int) -> bytes:
    """A column as ``width`` byte planes, least significant first (values fit the width)."""
    v = np.ascontiguousarray(values, dtype=np.int64).ravel().astype(f"<u{width}")
    return v.view(np.uint8).reshape(-1, width).T.tobytes()


class _Columns:
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


def _raw_channel_bytes(c: int, s: int, k: int) -> int:
    """Bytes of one channel's raw payload (see the column table)."""
    return 10 * c + 24 * s + 18 * k + (s + 7) // 8


# =============================================================================================
# Header
# =============================================================================================


class _ChannelInfo:
    __slots__ = ("name", "levels", "base_band", "n_contours", "n_segments", "n_caps", "tone",
                 "s_p", "g", "s_c", "s_v", "coded_size", "cap_ramp")

    def __init__(self, name, levels, base_band, n_contours, n_segments, n_caps, tone=None,
                 s_p=0, g=0, s_c=0, s_v=0, coded_size=0, cap_ramp=CAP_RAMP):
        self.name, self.levels, self.base_band = name, levels, base_band
        self.n_contours, self.n_segments, self.n_caps = n_contours, n_segments, n_caps
        self.tone, self.coded_size, self.cap_ramp = tone, coded_size, cap_ramp
        self.s_p, self.g, self.s_c, self.s_v = s_p, g, s_c, s_v


class _Header:
    __slots__ = (
        "version", "width", "height", "colour", "source_depth", "compression",
        "payload_size", "raw_size", "payload_crc", "meta", "channels", "header_size",
    )


def _header_bytes(width, height, colour, depth, infos, compression, payload, raw_size, meta) -> bytes:
    body = bytearray(
        _FIXED.pack(
            width, height, COLOUR_CODES[colour], depth, len(infos), compression, QUANT, QUANT,
            len(payload), raw_size, zlib.crc32(payload), len(meta),
        )
    )
    body += meta
    for c in infos:
        n_tone = 0 if c.tone is None else c.tone.shape[0]
        body += _CHANNEL.pack(c.name.encode("ascii"), len(c.levels), c.base_band, c.n_contours,
                              c.n_segments, c.n_caps, n_tone, c.s_p, c.g, c.s_c, c.s_v, c.coded_size)
        body += np.asarray(c.levels, dtype="<f8").tobytes()
        if c.tone is not None:
            body += np.ascontiguousarray(c.tone, dtype="<f8").tobytes()
        body += _CAP_RAMP.pack(c.cap_ramp)
    header_size = PREAMBLE_BYTES + len(body) + _CRC.size
    head = _PREAMBLE.pack(MAGIC, FORMAT_VERSION, 0, header_size) + bytes(body)
    return head + _CRC.pack(zlib.crc32(head))


def _unsupported(version: int) -> FormatError:
    return FormatError(
        f"unsupported .isoph format version {version} (this reader knows versions "
        f"{', '.join(map(str, READ_VERSIONS))})"
    )


def _parse_header(data: bytes, file_size: int) -> _Header:
    """Parse and check the header at the start of ``data`` (which may be the whole file)."""
    if len(data) < PREAMBLE_BYTES:
        if MAGIC.startswith(data[:8]):
            raise FormatError(
                f"truncated .isoph file: {file_size} bytes, shorter than the {PREAMBLE_BYTES}-byte preamble"
            )
        raise FormatError("not an .isoph file (bad magic bytes)")
    magic, version, reserved, header_size = _PREAMBLE.unpack_from(data, 0)
    if magic != MAGIC:
        raise FormatError("not an .isoph file (bad magic bytes)")
    if not _MIN_HEADER_BYTES <= header_size <= MAX_HEADER_BYTES:
        if version > FORMAT_VERSION:  # a newer layout may well have a larger header
            raise _unsupported(version)
        raise FormatError(
            f"header size {header_size} is outside [{_MIN_HEADER_BYTES}, {MAX_HEADER_BYTES}] (corrupted preamble)"
        )
    if file_size < header_size or len(data) < header_size:
        raise FormatError(
            f"truncated .isoph file: {file_size} bytes, the header alone declares {header_size}"
        )
    (stored_crc,) = _CRC.unpack_from(data, header_size - 4)
    if zlib.crc32(data[: header_size - 4]) != stored_crc:
        raise FormatError("header checksum mismatch (corrupted header)")
    if version not in READ_VERSIONS:
        raise _unsupported(version)
    if reserved != 0:
        raise FormatError(f"reserved preamble field is {reserved}, must be 0 in version {version}")

    end = header_size - 4
    pos = PREAMBLE_BYTES

    def take(size, what):
        nonlocal pos
        if pos + size > end:
            raise FormatError(f"header too short for its {what}")
        pos += size
        return data[pos - size : pos]

    (width, height, colour, depth, n_channels, compression, xy_quant, value_quant,
     payload_size, raw_size, payload_crc, meta_size) = _FIXED.unpack(take(_FIXED.size, "fixed fields"))
    h = _Header()
    h.version, h.header_size = version, header_size
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
    h.meta = _parse_meta(take(meta_size, "meta"))

    channels = []
    for i in range(n_channels):
        if version == 1:
            summary = take(_CHANNEL_V1.size, f"channel {i} summary")
            name, n_levels, base_band, n_contours, n_segments, n_caps = _CHANNEL_V1.unpack(summary)
            n_tone = s_p = g = s_c = s_v = coded_size = 0
        else:
            summary = take(_CHANNEL.size, f"channel {i} summary")
            (name, n_levels, base_band, n_contours, n_segments, n_caps, n_tone, s_p, g, s_c, s_v,
             coded_size) = _CHANNEL.unpack(summary)
        # The name goes into messages before it is checked: a control byte would break the
        # one-line promise, so anything but printable ASCII is shown escaped.
        label = chr(name[0]) if 0x21 <= name[0] <= 0x7E else f"\\x{name[0]:02x}"
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
        levels = np.frombuffer(take(8 * n_levels, f"channel {label} levels"), dtype="<f8")
        levels = levels.astype(np.float64)
        _check_levels(levels, label)
        tone = None
        if n_tone:
            tone = np.frombuffer(take(16 * n_tone, f"channel {label} tone"), dtype="<f8")
            tone = tone.astype(np.float64).reshape(n_tone, 2)
            _check_tone(tone, label)
        cap_ramp = CAP_RAMP
        if version >= 3:
            (cap_ramp,) = _CAP_RAMP.unpack(take(_CAP_RAMP.size, f"channel {label} cap ramp"))
            _check_cap_ramp(cap_ramp, label)
        channels.append(_ChannelInfo(label, levels, base_band, n_contours, n_segments, n_caps, tone,
                                     s_p, g, s_c, s_v, coded_size, cap_ramp))
    if pos != end:
        raise FormatError(f"header has {end - pos} unexpected byte(s) after the channel summaries")
    names = tuple(c.name for c in channels)
    if names not in CHANNEL_LAYOUTS[h.colour]:
        raise FormatError(f"channels {','.join(names)} do not fit colour {h.colour!r}")
    h.channels = channels

    # The counts fix the raw size; the raw size must be plausible for the stored size, and
    # the stored size must be what the file holds.
    expected_raw = sum(_raw_channel_bytes(c.n_contours, c.n_segments, c.n_caps) for c in channels)
    if raw_size != expected_raw:
        raise FormatError(
            f"raw payload size {raw_size} does not match the {expected_raw} bytes the counts need"
        )
    if raw_size > MAX_EXPANSION * payload_size + EXPANSION_SLACK:
        raise FormatError(
            f"payload of {payload_size} bytes declares {raw_size} raw bytes, "
            f"over the {MAX_EXPANSION}:1 limit"
        )
    if compression == COMPRESSION_STORED and payload_size != raw_size:
        raise FormatError(f"stored payload of {payload_size} bytes but raw size {raw_size}")
    if compression == COMPRESSION_RANGE:
        coded = sum(c.coded_size for c in channels)
        if coded != payload_size:
            raise FormatError(f"channels' coded sizes add up to {coded} bytes, the payload has {payload_size}")
    expected = header_size + payload_size
    if file_size < expected:
        raise FormatError(f"truncated .isoph file: {file_size} bytes, the header declares {expected}")
    if file_size > expected:
        raise FormatError(f"{file_size - expected} unexpected byte(s) after the payload")
    h.payload_size, h.raw_size, h.payload_crc = payload_size, raw_size, payload_crc
    return h


def _parse_meta(b: bytes) -> dict:
    if not b:
        return {}

    def finite(text):  # JSON has no NaN or infinity, and the writer cannot write them back
        value = float(text)
        if not np.isfinite(value):
            raise ValueError(f"{text} is not a finite number")
        return value

    def no_constant(name):
        raise ValueError(f"{name} is not JSON")

    try:
        meta = json.loads(b.decode("utf-8"), parse_float=finite, parse_constant=no_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise FormatError(f"meta is not valid UTF-8 JSON ({type(e).__name__})") from None
    if not isinstance(meta, dict):
        raise FormatError(f"meta is a JSON {type(meta).__name__}, not an object")
    return meta


def _meta_bytes(meta) -> bytes:
    if not meta:
        return b""
    if not isinstance(meta, dict):
        raise FormatError(f"meta must be a dict, not {type(meta).__name__}")

    def default(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        raise TypeError(f"{type(o).__name__} is not JSON-serialisable")

    try:
        # Through JSON once first, so that the keys are strings (sortable) and values plain.
        plain = json.loads(json.dumps(meta, allow_nan=False, default=default))
        text = json.dumps(plain, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    except (TypeError, ValueError, RecursionError) as e:
        raise FormatError(f"meta cannot be written as JSON: {e}") from None
    b = text.encode("utf-8")
    if len(b) > MAX_META_BYTES:
        raise LimitError(f"meta of {len(b)} bytes as JSON exceeds the {MAX_META_BYTES}-byte limit")
    return b


# =============================================================================================
# Checks shared by the writer and the reader
# =============================================================================================


def _check_levels(levels: np.ndarray, label: str) -> None:
    if not np.all(np.isfinite(levels)):
        raise FormatError(f"channel {label}: a level is not finite")
    if levels.shape[0] > 1 and not np.all(levels[1:] > levels[:-1]):
        raise FormatError(f"channel {label}: levels are not strictly increasing")


def _check_cap_ramp(cap_ramp, label: str) -> float:
    """A cap ramp as a float: a number, positive, finite or +infinity (DOME)."""
    try:
        value = float(cap_ramp)
    except (TypeError, ValueError):
        raise FormatError(f"channel {label}: cap_ramp must be a number, not {cap_ramp!r}") from None
    if not value > 0.0:  # NaN fails too
        raise FormatError(f"channel {label}: cap ramp {value!r} is not positive")
    return value


def _check_tone(tone: np.ndarray, label: str) -> None:
    """A tone curve: (T, 2) knots, 2 <= T <= MAX_TONE_KNOTS, finite, x strictly increasing,
    y non-decreasing (model.py)."""
    if tone.ndim != 2 or tone.shape[1] != 2:
        raise FormatError(f"channel {label}: tone must be a (K, 2) array of knots")
    if tone.shape[0] > MAX_TONE_KNOTS:
        raise LimitError(f"channel {label}: {tone.shape[0]} tone knots exceed the limit of {MAX_TONE_KNOTS}")
    if tone.shape[0] < 2:
        raise FormatError(f"channel {label}: a tone curve needs at least 2 knots, not {tone.shape[0]}")
    if not np.all(np.isfinite(tone)):
        raise FormatError(f"channel {label}: a tone knot is not finite")
    if not np.all(tone[1:, 0] > tone[:-1, 0]):
        raise FormatError(f"channel {label}: tone knots' x are not strictly increasing")
    if not np.all(tone[1:, 1] >= tone[:-1, 1]):
        raise FormatError(f"channel {label}: tone knots' y decrease (the curve must be monotone)")


def _check_range(a: np.ndarray, lo: int, hi: int, what: str) -> None:
    """Every value of ``a`` in [lo, hi)."""
    if a.size and (int(a.min()) < lo or int(a.max()) >= hi):
        bad = int(np.flatnonzero((a < lo) | (a >= hi))[0])
        raise FormatError(f"{what} {int(a[bad])} (entry {bad}) is outside [{lo}, {hi})")


def _is_forest(parent: np.ndarray) -> bool:
    """True when following parent links from every contour reaches -1 (no cycle). O(C).

    Parents that all precede their children (a natural order for an encoder) make a forest
    at once. Otherwise Kahn's algorithm peels contours without children until none is left;
    the contours of a cycle never lose their last child. Iterative: deep nesting cannot
    overflow a stack.
    """
    c = parent.shape[0]
    if np.all(parent < np.arange(c)):
        return True
    children = np.bincount(parent[parent >= 0], minlength=c).tolist()
    par = parent.tolist()
    todo = [k for k in range(c) if children[k] == 0]
    peeled = 0
    while todo:
        k = todo.pop()
        peeled += 1
        p = par[k]
        if p >= 0:
            children[p] -= 1
            if children[p] == 0:
                todo.append(p)
    return peeled == c


def _check_semantics(label, n_levels, contour_level, parent, cap_band, cap_contour) -> None:
    c = contour_level.shape[0]
    _check_range(contour_level, 0, n_levels, f"channel {label}: contour level")
    _check_range(parent, -1, c, f"channel {label}: parent")
    if not _is_forest(parent):
        raise FormatError(f"channel {label}: parent links form a cycle")
    _check_range(cap_band, 0, n_levels + 1, f"channel {label}: cap band")
    _check_range(cap_contour, -1, c, f"channel {label}: cap contour")


# =============================================================================================
# Writing
# =============================================================================================


def check_image_kind(vi, too_big=LimitError) -> None:
    """The image-level rules every writer shares (this module and format/svg.py): a
    VectorImage, a size within the limits (``too_big`` is raised beyond them), a known colour,
    source depth and channel layout."""
    if not isinstance(vi, VectorImage):
        raise FormatError(f"expected a VectorImage, got {type(vi).__name__}")
    width, height = int(vi.width), int(vi.height)
    if width < 1 or height < 1:
        raise FormatError(f"image size {width} x {height} is empty")
    if width > MAX_WIDTH or height > MAX_HEIGHT:
        raise too_big(f"image size {width} x {height} exceeds the {MAX_WIDTH} x {MAX_HEIGHT} limit")
    if vi.colour not in COLOUR_CODES:
        raise FormatError(f"unknown colour {vi.colour!r} (grey or yuv)")
    if vi.source_depth not in SOURCE_DEPTHS:
        raise FormatError(f"source depth {vi.source_depth} is not 8 or 16")
    names = tuple(getattr(ch, "name", None) for ch in vi.channels)
    if names not in CHANNEL_LAYOUTS[vi.colour]:
        raise FormatError(f"channels {names} do not fit colour {vi.colour!r}")


def _dumps(vi: VectorImage, compression: int) -> bytes:
    check_image_kind(vi)
    width, height = int(vi.width), int(vi.height)
    meta = _meta_bytes(vi.meta)
    checked = [_checked_channel(ch) for ch in vi.channels]
    raw_size = sum(_raw_channel_bytes(c.info.n_contours, c.info.n_segments, c.info.n_caps) for c in checked)

    if compression == COMPRESSION_RANGE:
        payload = b"".join(_map(_range_channel, checked, sum(c.info.n_segments for c in checked)))
    else:
        raw = b"".join(_column_channel(c) for c in checked)
        payload = raw
        if compression == COMPRESSION_ZLIB:
            payload = zlib.compress(raw, ZLIB_LEVEL)
        elif compression == COMPRESSION_LZMA:
            payload = lzma.compress(raw, format=lzma.FORMAT_RAW, filters=_LZMA_WRITE_FILTERS)
    if raw_size > MAX_EXPANSION * len(payload) + EXPANSION_SLACK:
        # Absurdly repetitive contours: readers refuse such ratios (decompression bombs).
        compression = COMPRESSION_STORED
        payload = b"".join(_column_channel(c) for c in checked)
    infos = [c.info for c in checked]
    if compression != COMPRESSION_RANGE:
        for info in infos:
            info.s_p = info.g = info.s_c = info.s_v = info.coded_size = 0
    head = _header_bytes(width, height, vi.colour, int(vi.source_depth), infos, compression,
                         payload, raw_size, meta)
    return head + payload


def _map(fn, items, n_segments):
    """[fn(x) for x in items], in threads for big images (the kernels release the GIL)."""
    if n_segments < PARALLEL_SEGMENTS or len(items) < 2:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(max_workers=min(len(items), os.cpu_count() or 1, 4)) as pool:
        return list(pool.map(fn, items))


class _Checked:
    """One channel, checked against the data model, on the 1/64 grids (int64)."""

    __slots__ = ("info", "level", "offsets", "nseg", "q", "border", "parent", "cap_band",
                 "cap_contour", "cq", "vq")


def _checked_channel(ch: Channel) -> _Checked:
    """Check one channel against the data model; quantise it to the 1/64 grids."""
    label = ch.name
    levels = np.asarray(ch.levels, dtype=np.float64)
    if levels.ndim != 1:
        raise FormatError(f"channel {label}: levels must be 1-D")
    if levels.shape[0] > MAX_LEVELS:
        raise LimitError(f"channel {label}: {levels.shape[0]} levels exceed the limit of {MAX_LEVELS}")
    _check_levels(levels, label)
    tone = getattr(ch, "tone", None)
    if tone is not None:
        tone = np.asarray(tone, dtype=np.float64)
        _check_tone(tone, label)
    cap_ramp = _check_cap_ramp(getattr(ch, "cap_ramp", CAP_RAMP), label)

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
    _check_semantics(label, levels.shape[0], level, parent, cap_band, cap_contour)
    base_band = int(ch.base_band)
    if not 0 <= base_band <= levels.shape[0]:
        raise FormatError(f"channel {label}: base band {base_band} is outside [0, {levels.shape[0]}]")

    q = _quantise(points, COORD_LIMIT, f"channel {label}: a control point")
    if c and not np.array_equal(q[offsets[:-1]], q[offsets[1:] - 1]):
        bad = int(np.flatnonzero(np.any(q[offsets[:-1]] != q[offsets[1:] - 1], axis=1))[0])
        raise FormatError(f"channel {label}: contour {bad} is not closed (last point != first)")
    out = _Checked()
    out.info = _ChannelInfo(label, levels, base_band, c, s, k, tone, cap_ramp=cap_ramp)
    out.level, out.offsets, out.nseg, out.q = level, offsets, nseg, q
    out.border = border.astype(bool)
    out.parent, out.cap_band, out.cap_contour = parent, cap_band, cap_contour
    out.cq = _quantise(cap_xy, COORD_LIMIT, f"channel {label}: a cap position")
    out.vq = _quantise(cap_value, CAP_VALUE_LIMIT, f"channel {label}: a cap value")
    return out


def _stored_points(ch: _Checked) -> np.ndarray:
    """(3 S, 2): the chains' points without their closing points."""
    keep = np.ones(ch.q.shape[0], bool)
    keep[ch.offsets[1:] - 1] = False
    return ch.q[keep]


def _column_channel(ch: _Checked) -> bytes:
    """One channel in the column layout (compressions 0, 1 and 2)."""
    c = ch.level.shape[0]
    d = np.diff(_stored_points(ch), axis=0, prepend=np.zeros((1, 2), np.int64))
    columns = [
        _planes(_zigzag(np.diff(ch.level, prepend=0)), 2),
        _planes(ch.nseg - 1, 4),
        _planes(np.where(ch.parent < 0, 0, _zigzag(np.arange(c) - ch.parent)), 4),
        _planes(_zigzag(d), 4),
        _planes(ch.cap_band, 2),
        _planes(_zigzag(np.diff(ch.cap_contour, prepend=-1)), 4),
        _planes(_zigzag(ch.cq - _cap_origins(ch.q, ch.offsets, ch.cap_contour)), 4),
        _planes(_zigzag(ch.vq), 4),
        np.packbits(ch.border, bitorder="little").tobytes(),
    ]
    return b"".join(columns)


def _grid_shift(a: np.ndarray) -> int:
    """The largest s <= MAX_GRID_SHIFT such that every value of ``a`` is a multiple of 2**s."""
    if a.size == 0:
        return 0
    bits = int(np.bitwise_or.reduce(a.ravel()))
    s = 0
    while s < MAX_GRID_SHIFT and bits & ((1 << (s + 1)) - 1) == 0:
        s += 1
    return s


def _anchor_shift(anchors: np.ndarray) -> int:
    """The anchor grid g that saves the most bits (0: none), decided in integers.

    An anchor flag costs about 1.5 bits and an on-grid coordinate saves about g bits, so
    g scores 2 g (on-grid coordinates) - 3 (anchors). Points off any grid score < 0 for
    every g (a coordinate is on the 2**g grid with probability 2**-g, and g 2**(1-g) <= 1).
    """
    best, best_g = 0, 0
    n = anchors.shape[0]
    for g in range(1, MAX_ANCHOR_SHIFT + 1):
        on = int(np.count_nonzero((anchors & ((1 << g) - 1)) == 0))
        score = 2 * g * on - 3 * n
        if score > best:
            best, best_g = score, g
    return best_g


def _range_channel(ch: _Checked, version: int = FORMAT_VERSION) -> bytes:
    """One channel range-coded (compression 3) in ``version``'s layout (2, 3 or 4); sets its
    grids and coded size in ch.info."""
    info = ch.info
    pts = _stored_points(ch)
    info.s_p = _grid_shift(pts)
    info.s_c = _grid_shift(ch.cq)
    info.s_v = _grid_shift(ch.vq)
    pts = pts >> info.s_p
    info.g = _anchor_shift(pts[0::3])
    coded, _ = entropy.encode_channel(
        ch.level, ch.nseg, ch.parent, np.ascontiguousarray(pts), ch.border.astype(np.uint8), info.g,
        ch.cap_contour, ch.cap_band, np.ascontiguousarray(ch.cq >> info.s_c), ch.vq >> info.s_v,
        info.s_p, info.s_c, info.s_v, info.levels, info.base_band, version, False,
    )
    info.coded_size = int(coded.shape[0])
    return coded.tobytes()


def _int_array(a, label, what) -> np.ndarray:
    a = np.asarray(a)
    if a.ndim != 1 or (a.size and a.dtype.kind not in "iu"):
        raise FormatError(f"channel {label}: {what} must be a 1-D integer array")
    return a.astype(np.int64)


def _quantise(a: np.ndarray, limit: int, what: str) -> np.ndarray:
    """Round to the 1/QUANT grid (halves to even), as int64 within (-limit, limit)."""
    if not np.all(np.isfinite(a)):
        raise FormatError(f"{what} is not finite")
    scaled = np.rint(a * QUANT)
    if scaled.size and float(np.abs(scaled).max()) >= limit:
        raise LimitError(f"{what} lies beyond the format's limit of +-{limit // QUANT}")
    return scaled.astype(np.int64)


# =============================================================================================
# Reading
# =============================================================================================


def _decode(h: _Header, payload) -> VectorImage:
    """The image from a checked header and its payload (bytes or memoryview)."""
    if zlib.crc32(payload) != h.payload_crc:
        raise FormatError("payload checksum mismatch (corrupted payload)")
    if h.compression == COMPRESSION_RANGE:
        chunks, pos = [], 0
        for info in h.channels:
            chunks.append((info, np.frombuffer(payload, np.uint8, info.coded_size, pos).copy(), h.version))
            pos += info.coded_size
        channels = tuple(_map(_decode_range_channel, chunks, sum(c.n_segments for c in h.channels)))
    else:
        cols = _Columns(_decompress(payload, h.compression, h.raw_size))
        channels = tuple(_decode_channel(cols, info) for info in h.channels)
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
            d = lzma.LZMADecompressor(format=lzma.FORMAT_RAW, filters=_LZMA_READ_FILTERS)
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


def _decode_channel(cols: _Columns, info: _ChannelInfo) -> Channel:
    """One channel off the column layout."""
    label, c, s, k = info.name, info.n_contours, info.n_segments, info.n_caps
    level = np.cumsum(_unzigzag(cols.column(c, 2)))
    nseg = cols.column(c, 4) + 1
    pcode = cols.column(c, 4)
    d = _unzigzag(cols.column(6 * s, 4)).reshape(-1, 2)  # |d| <= 2**31
    cap_band = cols.column(k, 2)
    cap_contour = np.cumsum(_unzigzag(cols.column(k, 4))) - 1
    cq = _unzigzag(cols.column(2 * k, 4)).reshape(-1, 2)
    vq = _unzigzag(cols.column(k, 4))
    border_bits = np.unpackbits(cols.take((s + 7) // 8), bitorder="little")

    if int(nseg.sum()) != s:
        raise FormatError(
            f"channel {label}: contours have {int(nseg.sum())} segments, the header declares {s}"
        )
    parent = np.where(pcode == 0, -1, np.arange(c, dtype=np.int64) - _unzigzag(pcode))
    _check_semantics(label, info.levels.shape[0], level, parent, cap_band, cap_contour)

    # Points: running sums along the stream (3 S values of at most 2**31: no overflow).
    stored = np.cumsum(d, axis=0)
    _check_limit(stored, COORD_LIMIT, f"channel {label}: a control point")
    offsets = np.zeros(c + 1, np.int64)
    np.cumsum(3 * nseg + 1, out=offsets[1:])
    q = np.empty((int(offsets[-1]), 2), np.int64)
    keep = np.ones(q.shape[0], bool)
    keep[offsets[1:] - 1] = False
    q[keep] = stored
    q[offsets[1:] - 1] = q[offsets[:-1]]  # close every chain
    cq = cq + _cap_origins(q, offsets, cap_contour)  # cap_contour was checked above
    _check_limit(cq, COORD_LIMIT, f"channel {label}: a cap position")
    _check_limit(vq, CAP_VALUE_LIMIT, f"channel {label}: a cap value")

    if np.any(border_bits[s:]):
        raise FormatError(f"channel {label}: padding bits after the border flags are not zero")
    return _channel(info, level, offsets, q, border_bits[:s], parent, cap_band, cap_contour, cq, vq)


def _channel(info, level, offsets, q, border, parent, cap_band, cap_contour, cq, vq) -> Channel:
    """A Channel in canonical dtypes from decoded integers (1/64 units)."""
    return Channel(
        name=info.name,
        levels=info.levels.copy(),
        contour_level=level.astype(np.int32),
        offsets=offsets,
        points=q.astype(np.float64) / QUANT,
        border=border.astype(bool),
        parent=parent.astype(np.int32),
        cap_band=cap_band.astype(np.int32),
        cap_contour=cap_contour.astype(np.int32),
        cap_xy=cq.astype(np.float64) / QUANT,
        cap_value=vq.astype(np.float64) / QUANT,
        base_band=info.base_band,
        tone=None if info.tone is None else info.tone.copy(),
        cap_ramp=float(info.cap_ramp),
    )


# What each decoder status means: (message template, with {where} and {extra}).
_RANGE_ERRORS = {
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
}


def _decode_range_channel(item) -> Channel:
    """One channel off its range-coded bytes (compression 3)."""
    info, data, version = item
    c, s, k = info.n_contours, info.n_segments, info.n_caps
    (status, where, extra, level, nseg, parent, q, border, cap_contour, cap_band, cq, vq) = \
        entropy.decode_channel(data, c, s, k, info.g, info.s_p, info.s_c, info.s_v, info.levels,
                               info.base_band, version)
    if status != entropy.OK:
        msg = _RANGE_ERRORS[status].format(where=where, extra=extra, c=c, s=s, L=info.levels.shape[0])
        raise FormatError(f"channel {info.name}: {msg}")
    _check_semantics(info.name, info.levels.shape[0], level, parent, cap_band, cap_contour)
    offsets = np.zeros(c + 1, np.int64)
    np.cumsum(3 * nseg + 1, out=offsets[1:])
    return _channel(info, level, offsets, q, border, parent, cap_band, cap_contour, cq, vq)


def _cap_origins(q: np.ndarray, offsets: np.ndarray, cap_contour: np.ndarray) -> np.ndarray:
    """(K, 2): the first point of each cap's contour, (0, 0) for the root region."""
    origins = np.zeros((cap_contour.shape[0], 2), np.int64)
    inner = cap_contour >= 0
    origins[inner] = q[offsets[cap_contour[inner]]]
    return origins


def _check_limit(q: np.ndarray, limit: int, what: str) -> None:
    if q.size and int(np.abs(q).max()) >= limit:
        raise FormatError(f"{what} lies beyond the format's limit of +-{limit} (1/{QUANT} units)")
