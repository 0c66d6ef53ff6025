"""Fuzzing: bad files and bad images never crash, hang or lose data.

What holds, and is tried here on generated and mutated inputs:

- any bytes given to ``isoph.loads`` / ``read_info`` give a VectorImage or a one-line
  FormatError / LimitError, never another exception; whatever loads can be written again and
  rendered (tiny) without an exception;
- random valid VectorImages (hypothesis strategies over every format field) round-trip
  exactly;
- mutated real files (the encoder's, in every compression; bit flips, byte changes,
  insertions, deletions, splices, truncations; checksums left broken or repaired, and
  mutations of the decompressed payload re-compressed behind valid checksums) only ever
  give clean errors or valid images;
- any array given to ``isophote.encode`` encodes (deterministically, byte for byte) or
  gives an InputError; mutated image files give a Raster or an InputError / LimitError;
- the command line: exit 2 and one line for bad files, no output left, an existing output
  untouched, inputs never modified, the same input giving the same bytes.

Budgets. In CI every test runs a fixed, derandomised set of examples (the whole file in well
under 60 s). Longer runs, with fresh random examples::

    ISOPHOTE_FUZZ_EXAMPLES=5000 .venv/bin/python -m pytest tests/format/test_fuzz.py
    ISOPHOTE_FUZZ_REPORT=counts.json ...   # also write the counts of outcomes per test

and ``fuzz/fuzz_isoph.py`` runs a coverage-guided (atheris) or plain mutation loop for as
long as asked.
"""

from __future__ import annotations

import json
import lzma
import os
import struct
import subprocess
import sys
import zlib
from collections import Counter

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import isophote
from isophote import cli
from isophote.errors import FormatError, InputError, LimitError
from isophote.format import isoph
from isophote.imageio import read_image, write_image
from isophote.encoder import QUANT
from isophote.model import Channel, VectorImage

EXAMPLES = int(os.environ.get("ISOPHOTE_FUZZ_EXAMPLES") or 0)
COUNTS: Counter = Counter()  # outcome counts, "test: outcome" -> n


def budget(ci_examples: int):
    """CI: ``ci_examples`` fixed examples. On demand: ISOPHOTE_FUZZ_EXAMPLES random ones."""
    return settings(max_examples=EXAMPLES or ci_examples, deadline=None, derandomize=not EXAMPLES,
                    database=None, suppress_health_check=list(HealthCheck), print_blob=True)


@pytest.fixture(scope="module", autouse=True)
def _report_counts():
    yield
    path = os.environ.get("ISOPHOTE_FUZZ_REPORT")
    if path:
        with open(path, "w") as f:
            json.dump(dict(sorted(COUNTS.items())), f, indent=1)


# =============================================================================================
# Out-of-bounds accesses in the numba kernels, found by fuzzing (fixed): regression tests
# =============================================================================================

# A 3 x 3 image on which _kernels/enclose.py::innermost_enclosing wrote past the end of its
# `touched` array (a loop whose winding number returned to 0 along the ray and was crossed
# again was listed twice). Compiled, that corrupted the heap (the process died later, e.g.
# "corrupted size vs. prev_size"). The kernels' Python source (``py_func``) raises IndexError
# where the compiled code would read or write out of bounds, so the tests run that.
ENCLOSE_REPRO = np.array([[0, 0, 0], [255, 0, 255], [255, 255, 255]], np.uint8)


def test_enclose_kernel_stays_in_bounds(monkeypatch):
    import isophote.encoder.hierarchy as hierarchy

    compiled = isoph.dumps(isophote.encode(ENCLOSE_REPRO))
    monkeypatch.setattr(hierarchy, "innermost_enclosing", hierarchy.innermost_enclosing.py_func)
    assert isoph.dumps(isophote.encode(ENCLOSE_REPRO)) == compiled
    rng = np.random.default_rng(0)
    for _ in range(10):  # binary noise made it overflow often
        isophote.encode(rng.random((5, 6)) < 0.5)


# =============================================================================================
# Strategies for format fields: random valid VectorImages
# =============================================================================================

Q = 64
COORD = (1 << 30) - 1  # largest |coordinate| in 1/64 px (isoph.COORD_LIMIT is exclusive)
LAYOUTS = [("grey", "Y"), ("grey", "YA"), ("yuv", "YUV"), ("yuv", "YUVA")]


def _coords(extreme: bool):
    small = st.integers(-64 * 80, 64 * 80)
    return st.one_of(small, st.integers(-COORD, COORD), st.sampled_from([COORD, -COORD, 0])) if extreme else small


@st.composite
def channels(draw, name, extreme=True):
    n_levels = draw(st.integers(0, 19).map(lambda x: 0 if x == 0 else 1 + x % 6))  # few without levels
    if extreme and draw(st.integers(0, 9)) == 0:
        n_levels = isoph.MAX_LEVELS
    if n_levels > 6:
        levels = float(draw(st.integers(-(2**40), 2**40))) + np.arange(n_levels) * 0.25
    else:
        values = draw(st.lists(st.floats(-1e300, 1e300, allow_nan=False, allow_infinity=False)
                               if extreme else st.floats(-20, 280, allow_nan=False),
                               min_size=n_levels, max_size=n_levels, unique=True))
        levels = np.sort(np.asarray(values, np.float64))
        if np.any(np.diff(levels) <= 0):  # 0.0 and -0.0 are "unique" floats but equal levels
            levels = np.arange(n_levels, dtype=np.float64)
    c = draw(st.integers(0, 5)) if n_levels else 0
    chains = []
    for _ in range(c):
        n = draw(st.integers(1, 4))
        pts = draw(st.lists(st.tuples(_coords(extreme), _coords(extreme)), min_size=3 * n, max_size=3 * n))
        chains.append(np.asarray(pts + pts[:1], np.float64) / Q)
    order = draw(st.permutations(range(c)))
    parent = np.full(c, -1, np.int32)
    for i in range(1, c):  # a forest, in any order
        j = draw(st.integers(-1, i - 1))
        if j >= 0:
            parent[order[i]] = order[j]
    s = sum((len(ch) - 1) // 3 for ch in chains)
    k = draw(st.integers(0, 3))
    offsets = np.zeros(c + 1, np.int64)
    offsets[1:] = np.cumsum([len(ch) for ch in chains])
    return Channel(
        name=name,
        levels=levels,
        contour_level=np.asarray(draw(st.lists(st.integers(0, max(n_levels - 1, 0)), min_size=c, max_size=c)),
                                 np.int32).reshape(-1),
        offsets=offsets,
        points=np.concatenate(chains) if chains else np.zeros((0, 2)),
        border=np.asarray(draw(st.lists(st.booleans(), min_size=s, max_size=s)), bool).reshape(-1),
        parent=parent,
        cap_band=np.asarray(draw(st.lists(st.integers(0, n_levels), min_size=k, max_size=k)), np.int32).reshape(-1),
        cap_contour=np.asarray(draw(st.lists(st.integers(-1, c - 1), min_size=k, max_size=k)), np.int32).reshape(-1),
        cap_xy=np.asarray(draw(st.lists(st.tuples(_coords(extreme), _coords(extreme)), min_size=k, max_size=k)),
                          np.float64).reshape(-1, 2) / Q,
        cap_value=np.asarray(draw(st.lists(st.integers(-COORD, COORD) if extreme else st.integers(-64 * 20, 64 * 280),
                                           min_size=k, max_size=k)), np.float64).reshape(-1) / Q,
        base_band=draw(st.integers(0, n_levels)),
        tone=draw(tones(extreme)),
    )


@st.composite
def tones(draw, extreme=True):
    """None, or a valid tone curve: 2 .. 6 knots (or MAX_TONE_KNOTS), x strictly increasing,
    y non-decreasing."""
    if draw(st.integers(0, 2)):
        return None
    n = isoph.MAX_TONE_KNOTS if extreme and draw(st.integers(0, 19)) == 0 else draw(st.integers(2, 6))
    finite = st.floats(-1e300, 1e300, allow_nan=False) if extreme else st.floats(-20, 280, allow_nan=False)
    x = np.unique(np.asarray(draw(st.lists(finite, min_size=min(n, 6), max_size=min(n, 6))), np.float64))
    if x.shape[0] < 2 or n > 6:
        x = np.arange(n, dtype=np.float64) * 0.0625
    y = np.sort(np.asarray(draw(st.lists(finite, min_size=x.shape[0], max_size=x.shape[0])), np.float64)) \
        if x.shape[0] <= 6 else np.arange(x.shape[0]) // 7 * 1.0
    return np.c_[x, y]


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**53), 2**53) | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=4), inner, max_size=3),
    max_leaves=8,
)


@st.composite
def vector_images(draw, extreme=True, max_side=None):
    colour, names = draw(st.sampled_from(LAYOUTS))
    side = st.integers(1, max_side) if max_side else st.one_of(
        st.integers(1, 64), st.sampled_from([1, isoph.MAX_WIDTH - 1, isoph.MAX_WIDTH]))
    return VectorImage(
        width=draw(side), height=draw(side), colour=colour,
        channels=tuple(draw(channels(n, extreme)) for n in names),
        source_depth=draw(st.sampled_from([8, 16])),
        meta=draw(st.dictionaries(st.text(max_size=6), json_values, max_size=3)),
    )


# A channel with no levels is valid (the format allows L = 0, and tests/format/test_format.py writes
# one); the fill kernel read levels[0] and levels[-1] of the empty array (fixed).
NO_LEVELS = VectorImage(3, 2, "yuv", (Channel.empty("Y", []), Channel.empty("U", [5.0]), Channel.empty("V", [])))


def test_render_of_a_channel_without_levels_stays_in_bounds(monkeypatch):
    import isophote.render.blocks as blocks

    compiled = [NO_LEVELS.render(fill=f) for f in ("diffusion", "flat")]
    for module in (blocks,):
        if hasattr(getattr(module, "evaluate", None), "py_func"):
            monkeypatch.setattr(module, "evaluate", module.evaluate.py_func)
    python = [NO_LEVELS.render(fill=f) for f in ("diffusion", "flat")]
    assert all(np.array_equal(a, b) for a, b in zip(compiled, python))


# =============================================================================================
# Oracles
# =============================================================================================

RENDER_CANVAS = 64 * 64  # render only small canvases: the distance grid covers the whole canvas


def render_small(vi: VectorImage, seed: int = 0) -> np.ndarray:
    """A tiny render with options chosen from ``seed``: it must succeed, in range, twice alike."""
    rng = np.random.default_rng(seed)
    opts = dict(width=int(min(vi.width, rng.integers(1, 13))), height=int(min(vi.height, rng.integers(1, 13))),
                fill=str(rng.choice(["diffusion", "flat"])),
                distance=str(rng.choice(["euclidean", "manhattan", "geodesic"])),
                supersample=int(rng.integers(1, 3)), depth=int(rng.choice([8, 16])))
    out = vi.render(**opts)
    assert out.shape[:2] == (opts["height"], opts["width"])
    assert out.dtype == (np.uint16 if opts["depth"] == 16 else np.uint8)
    assert np.array_equal(out, vi.render(**opts)), "render is not deterministic"
    return out


def check_isoph(data: bytes, label: str, render=True, seed=0) -> str:
    """Arbitrary bytes as an .isoph file: a one-line FormatError/LimitError, or a valid image
    that read_info describes alike, that writes and reads back equal, and that renders."""
    try:
        vi = isoph.loads(data)
    except (FormatError, LimitError) as e:
        msg = str(e)
        assert msg and "\n" not in msg, msg
        try:  # the header-only reader fails cleanly too, or accepts the header
            isoph.read_info(data)
        except (FormatError, LimitError) as e2:
            assert "\n" not in str(e2)
        COUNTS[f"{label}: {type(e).__name__}"] += 1
        return type(e).__name__
    info = isoph.read_info(data)
    assert (info["width"], info["height"], info["colour"]) == (vi.width, vi.height, vi.colour)
    assert [(c["name"], c["contours"], c["segments"], c["caps"]) for c in info["channels"]] == [
        (ch.name, ch.n_contours, ch.n_segments, ch.cap_band.shape[0]) for ch in vi.channels]
    again = isoph.loads(isoph.dumps(vi, compression=info["compression"]))
    assert again.equals(vi) and again.meta == vi.meta
    outcome = "valid"
    if render and vi.width * vi.height <= RENDER_CANVAS:
        render_small(vi, seed)
        outcome = "valid, rendered"
    COUNTS[f"{label}: {outcome}"] += 1
    return outcome


# =============================================================================================
# Format: valid images round-trip; random bytes and lying fields fail cleanly
# =============================================================================================


@budget(60)
@given(vector_images(), st.sampled_from(["range", "range", "zlib", "lzma", "none"]))
def test_random_valid_images_round_trip_exactly(vi, compression):
    b = isoph.dumps(vi, compression=compression)
    out = isoph.loads(b)
    assert out.equals(vi) and out.meta == json.loads(json.dumps(vi.meta))
    assert isoph.dumps(out, compression=compression) == b
    info = isoph.read_info(b)
    assert info["bytes"] == len(b) and [c["segments"] for c in info["channels"]] == [
        ch.n_segments for ch in vi.channels]
    COUNTS["round trip: exact"] += 1


@budget(40)
@given(vector_images(extreme=False, max_side=40), st.integers(0, 2**32 - 1))
def test_whatever_validates_renders(vi, seed):
    """A stranger's file that passes every check (contours crossing, odd hierarchies, caps
    anywhere) renders without an exception."""
    vi = isoph.loads(isoph.dumps(vi))
    out = render_small(vi, seed)
    assert out.ndim in (2, 3)
    COUNTS["valid renders"] += 1


@budget(150)
@given(st.one_of(st.binary(max_size=400), st.binary(max_size=300).map(lambda b: isoph.MAGIC + b)))
def test_random_bytes(data):
    check_isoph(data, "random bytes")


@st.composite
def checksummed_headers(draw):
    """A preamble and a header body of random bytes whose checksum is right: the parser's
    field checks, not the CRC, have to catch everything."""
    body = bytearray(draw(st.binary(min_size=40, max_size=260)))
    if draw(st.booleans()):  # plausible fixed fields, so that the channel summaries are reached
        struct.pack_into("<IIBBBBHH", body, 0, draw(st.integers(1, 64)), draw(st.integers(1, 64)),
                         draw(st.integers(0, 1)), draw(st.sampled_from([8, 16])), draw(st.integers(1, 4)),
                         draw(st.integers(0, 3)), 64, 64)
        struct.pack_into("<I", body, 36, draw(st.integers(0, 8)))  # meta_size
    version = draw(st.sampled_from([1, 2, 3]))
    head = isoph.MAGIC + struct.pack("<HHI", version, 0, 16 + len(body) + 4) + bytes(body)
    head += struct.pack("<I", zlib.crc32(head))
    return head + draw(st.binary(max_size=200))


@budget(150)
@given(checksummed_headers())
def test_checksummed_random_headers(data):
    check_isoph(data, "checksummed headers")


INTERESTING_U32 = [0, 1, 2, 3, 7, 8, 64, 255, 256, 1023, 1024, 1025, 2**16 - 1, 2**16, 2**20, 2**20 + 1,
                   2**28, 2**28 + 1, 2**31 - 1, 2**31, 2**32 - 1]


@st.composite
def lying_files(draw):
    """Every field from a strategy of interesting values; the payload either random or a
    valid compression of random raw bytes of exactly the size the counts declare."""
    u32 = st.one_of(st.sampled_from(INTERESTING_U32), st.integers(0, 2**32 - 1))
    small = st.one_of(st.integers(0, 4), st.sampled_from(INTERESTING_U32))
    colour, names = draw(st.sampled_from(LAYOUTS + [("grey", "YU"), ("yuv", "Y"), ("grey", "X")]))
    if draw(st.integers(0, 9)) == 0:  # any byte as a name, control bytes included
        names = draw(st.lists(st.characters(max_codepoint=255), min_size=1, max_size=4))
    colour_code = draw(st.one_of(st.just({"grey": 0, "yuv": 1}[colour]), st.integers(0, 255)))
    n_channels = draw(st.one_of(st.just(len(names)), st.integers(0, 255)))
    compression = draw(st.one_of(st.integers(0, 3), st.integers(0, 255)))
    meta = draw(st.one_of(st.just(b""), st.just(b'{"a":NaN}'), st.just(b'{"a":1e400}'),
                          st.dictionaries(st.text(max_size=4), json_values, max_size=2).map(
                              lambda d: json.dumps(d).encode()), st.binary(max_size=20)))
    version = draw(st.sampled_from([1, 2, 3, 3]))
    chans, counts = [], []
    for name in names:
        n_levels = draw(st.one_of(st.integers(0, 5), st.sampled_from([1024, 1025, 65535])))
        lv = draw(st.lists(st.floats(width=64), min_size=min(n_levels, 5), max_size=min(n_levels, 5)))
        if draw(st.booleans()):
            lv = sorted(v for v in lv if np.isfinite(v))
        lv = (lv + [float(v) for v in range(n_levels - len(lv))])[:n_levels] if n_levels <= 1024 else lv
        c, s, k = draw(small), draw(small), draw(small)
        base_band = draw(st.integers(0, min(n_levels + 1, 65535)))
        # versions 2 and 3: a tone curve, grids (mostly plausible), a coded size
        n_tone = draw(st.one_of(st.just(0), st.integers(1, 5), st.sampled_from([4096, 4097, 65535])))
        tone = draw(st.lists(st.floats(width=64), min_size=2 * min(n_tone, 5), max_size=2 * min(n_tone, 5)))
        if draw(st.booleans()):
            tone = [float(v) for v in range(2 * n_tone)] if n_tone <= 4096 else tone
        shifts = draw(st.one_of(st.just((0, 0, 0, 0)), st.tuples(st.integers(0, 7), st.integers(0, 17),
                                                                  st.integers(0, 7), st.integers(0, 7))))
        chans.append((name, n_levels, lv, base_band, c, s, k, n_tone, tone, shifts))
        counts.append((c, s, k))
    raw_size = sum(10 * c + 24 * s + 18 * k + (s + 7) // 8 for c, s, k in counts)
    if raw_size <= 4096 and draw(st.booleans()) and compression != 3:
        raw = draw(st.binary(min_size=raw_size, max_size=raw_size))
        payload = {0: raw, 1: zlib.compress(raw), 2: lzma.compress(
            raw, format=lzma.FORMAT_RAW, filters=[{"id": lzma.FILTER_LZMA2, "dict_size": 1 << 23}])}.get(
            compression, raw)
    else:
        payload = draw(st.binary(max_size=300))
    # coded sizes: usually a split of the payload among the channels
    cuts = sorted(draw(st.lists(st.integers(0, len(payload)), min_size=len(chans) - 1, max_size=len(chans) - 1))
                  ) if chans else []
    coded = [b - a for a, b in zip([0] + cuts, cuts + [len(payload)])]
    if draw(st.integers(0, 4)) == 0:
        coded = [draw(u32) for _ in chans]
    summaries = b""
    for (name, n_levels, lv, base_band, c, s, k, n_tone, tone, shifts), size in zip(chans, coded):
        if version == 1:
            summaries += struct.pack("<cHHIII", name.encode("latin-1"), n_levels, base_band, c, s, k)
        else:
            if compression != 3 and draw(st.integers(0, 3)):
                shifts, size = (0, 0, 0, 0), 0
            summaries += struct.pack("<cHHIIIHBBBBQ", name.encode("latin-1"), n_levels, base_band, c, s, k,
                                     n_tone, *shifts, size)
        summaries += struct.pack(f"<{len(lv)}d", *lv)
        if version >= 2:
            summaries += struct.pack(f"<{len(tone)}d", *tone)
    fixed = struct.pack(
        "<IIBBBBHHQQII", draw(st.one_of(st.integers(1, 64), u32)), draw(st.one_of(st.integers(1, 64), u32)),
        colour_code, draw(st.sampled_from([8, 16, 0, 255])), n_channels, compression,
        draw(st.sampled_from([64, 64, 0, 32])), 64,
        draw(st.one_of(st.just(len(payload)), st.integers(0, 2**64 - 1))),
        draw(st.one_of(st.just(raw_size), st.integers(0, 2**64 - 1))),
        zlib.crc32(payload), len(meta))
    body = fixed + meta + summaries
    head = isoph.MAGIC + struct.pack("<HHI", version, 0, 16 + len(body) + 4) + body
    return head + struct.pack("<I", zlib.crc32(head)) + payload


@budget(200)
@given(lying_files(), st.integers(0, 2**32 - 1))
def test_lying_fields(data, seed):
    check_isoph(data, "lying fields", seed=seed)


def test_channel_names_with_control_bytes_stay_on_one_line():
    """Found by atheris: a channel name byte of 0x0A put a newline into the message."""
    b = bytearray(isoph.dumps(VectorImage(3, 2, "grey", (Channel.empty("Y", [10.0]),))))
    for name in (b"\n", b"\r", b"\x00", b"\xff", b" ", b"X"):
        b[56] = name[0]  # the first channel summary (no meta)
        with pytest.raises(FormatError) as e:
            isoph.loads(_refresh(bytes(b), payload_too=False))
        assert "\n" not in str(e.value) and "\r" not in str(e.value) and "do not fit colour" in str(e.value)


def test_meta_with_nan_or_infinity_is_refused_by_the_reader():
    """The writer cannot write NaN or infinity in meta (JSON has neither); the reader must
    not accept them either, or a loaded image could not be saved again."""
    b = isoph.dumps(VectorImage(3, 2, "grey", (Channel.empty("Y", [10.0]),)))
    hs = struct.unpack_from("<I", b, 12)[0]
    for text in (b'{"a":NaN}', b'{"a":-Infinity}', b'{"a":1e400}', b'{"a":[1,{"b":-1e999}]}'):
        head, payload = bytearray(b[: hs - 4]), b[hs:]
        assert struct.unpack_from("<I", head, 52)[0] == 0  # no meta yet
        struct.pack_into("<I", head, 52, len(text))
        head[56:56] = text
        struct.pack_into("<I", head, 12, len(head) + 4)
        with pytest.raises(FormatError, match="meta"):
            isoph.loads(bytes(head) + struct.pack("<I", zlib.crc32(bytes(head))) + payload)
    head = bytearray(b[: hs - 4])  # the same file with finite meta loads
    struct.pack_into("<I", head, 52, 9)
    head[56:56] = b'{"a":1.5}'
    struct.pack_into("<I", head, 12, len(head) + 4)
    assert isoph.loads(bytes(head) + struct.pack("<I", zlib.crc32(bytes(head))) + b[hs:]).meta == {"a": 1.5}


# =============================================================================================
# The mutation fuzzer over real files
# =============================================================================================


def _smooth(h, w, c):
    y, x = np.mgrid[0:h, 0:w]
    planes = [40 + 170 * x / max(w - 1, 1), 220 - 150 * y / max(h - 1, 1),
              60 + 120 * ((x - w / 2) ** 2 + (y - h / 2) ** 2 < (min(h, w) / 3) ** 2), 255 - 100 * x / max(w - 1, 1)]
    return np.stack(planes[:c], axis=-1)


@pytest.fixture(scope="module")
def seeds():
    """Real files: the encoder's output for small images of every layout, in every
    compression (range coding last)."""
    out = []
    for h, w, c in [(16, 24, 3), (12, 12, 1), (10, 9, 4), (9, 10, 2)]:
        vi = isophote.encode(_smooth(h, w, c))
        for compression in ("zlib", "lzma", "none"):
            out.append(isoph.dumps(vi, compression=compression))
    noise = np.random.default_rng(5).integers(0, 256, (6, 7, 3)).astype(np.uint8)
    out.append(isoph.dumps(isophote.encode(noise), compression="zlib"))
    for h, w, c in [(16, 24, 3), (12, 12, 1), (10, 9, 4), (9, 10, 2)]:  # the default: range coding
        out.append(isoph.dumps(isophote.encode(_smooth(h, w, c))))
    out.append(isoph.dumps(isophote.encode(noise)))
    return out


def _split(data: bytes):
    hs = struct.unpack_from("<I", data, 12)[0]
    return hs, data[:hs], data[hs:]


def _refresh(data: bytes, payload_too: bool) -> bytes:
    """Fix the header CRC (and the payload CRC) of mutated bytes where the layout allows."""
    b = bytearray(data)
    if len(b) < 20:
        return bytes(b)
    hs = struct.unpack_from("<I", b, 12)[0]
    if not 60 <= hs <= len(b):
        return bytes(b)
    if payload_too:
        struct.pack_into("<I", b, 48, zlib.crc32(bytes(b[hs:])))
    struct.pack_into("<I", b, hs - 4, zlib.crc32(bytes(b[: hs - 4])))
    return bytes(b)


def _mutate_bytes(b: bytearray, rng, other: bytes) -> bytearray:
    op = int(rng.integers(0, 9))
    n = len(b)
    i = int(rng.integers(0, n)) if n else 0
    if op == 0 and n:  # flip a bit
        b[i] ^= 1 << int(rng.integers(0, 8))
    elif op == 1 and n:  # set a byte
        b[i] = int(rng.integers(0, 256))
    elif op == 2 and n >= 4:  # an interesting 32-bit value
        j = min(i, n - 4)
        b[j:j + 4] = struct.pack("<I", int(rng.choice(INTERESTING_U32)))
    elif op == 3:  # insert
        b[i:i] = bytes(rng.integers(0, 256, int(rng.integers(1, 9)), dtype=np.uint8))
    elif op == 4 and n:  # delete
        del b[i:i + int(rng.integers(1, 9))]
    elif op == 5 and n:  # duplicate a stretch
        j = int(rng.integers(i, n + 1))
        b[j:j] = b[i:min(j, i + 32)]
    elif op == 6:  # truncate
        del b[i:]
    elif op == 7:  # splice with another file
        j = int(rng.integers(0, len(other) + 1))
        b[i:] = other[j:]
    elif op == 8 and n:  # add a small delta
        b[i] = (b[i] + int(rng.integers(-4, 5))) % 256
    return b


def _raw_mutation(data: bytes, rng) -> bytes | None:
    """Decompress the payload, change raw bytes in place, compress again and make every size
    and checksum consistent: the mutation reaches the column checks."""
    if len(data) < 60 or not 60 <= struct.unpack_from("<I", data, 12)[0] <= len(data):
        return None  # not laid out like an .isoph file: nothing to decompress
    hs, head, payload = _split(data)
    code = head[27]
    if code == 3:  # range coding: change coded bytes in place, fix the payload CRC
        coded = bytearray(payload)
        if not coded:
            return None
        for _ in range(int(rng.integers(1, 4))):
            coded[int(rng.integers(0, len(coded)))] = int(rng.integers(0, 256))
        head = bytearray(head)
        struct.pack_into("<I", head, 48, zlib.crc32(bytes(coded)))
        return _refresh(bytes(head) + bytes(coded), payload_too=False)
    try:
        if code == 0:
            raw = payload
        elif code == 1:
            raw = zlib.decompress(payload)
        else:
            raw = lzma.decompress(payload, format=lzma.FORMAT_RAW,
                                  filters=[{"id": lzma.FILTER_LZMA2, "dict_size": 1 << 23}])
    except (zlib.error, lzma.LZMAError):
        return None
    raw = bytearray(raw)
    if not raw:
        return None
    for _ in range(int(rng.integers(1, 4))):
        i = int(rng.integers(0, len(raw)))
        kind = int(rng.integers(0, 3))
        if kind == 0:
            raw[i] = int(rng.integers(0, 256))
        elif kind == 1:
            raw[i] ^= 1 << int(rng.integers(0, 8))
        else:
            raw[i] = (raw[i] + int(rng.integers(-2, 3))) % 256
    raw = bytes(raw)
    payload = {0: raw, 1: zlib.compress(raw)}.get(code) or lzma.compress(
        raw, format=lzma.FORMAT_RAW, filters=[{"id": lzma.FILTER_LZMA2, "preset": 6, "dict_size": 1 << 23}])
    head = bytearray(head)
    struct.pack_into("<QQI", head, 32, len(payload), len(raw), zlib.crc32(payload))
    return _refresh(bytes(head) + payload, payload_too=False)


def mutate(data: bytes, other: bytes, seed: int, mode: str) -> bytes:
    rng = np.random.default_rng(seed)
    if mode == "raw":
        out = _raw_mutation(data, rng)
        if out is not None:
            return out
    b = bytearray(data)
    for _ in range(int(rng.integers(1, 5))):
        b = _mutate_bytes(b, rng, other)
    if mode == "header crc":
        return _refresh(bytes(b), payload_too=False)
    if mode == "both crcs":
        return _refresh(bytes(b), payload_too=True)
    return bytes(b)


@budget(400)
@given(st.integers(0, 2**32 - 1), st.integers(0, 2**16), st.integers(0, 2**16),
       st.sampled_from(["none", "header crc", "both crcs", "raw", "raw"]))
def test_mutated_real_files(seeds, seed, which, other, mode):
    data = mutate(seeds[which % len(seeds)], seeds[other % len(seeds)], seed, mode)
    check_isoph(data, f"mutated ({mode})", seed=seed)


def _outcome(data: bytes, compact: bool):
    """isoph.loads with the points compact (int32 off the range coder, then float32) or not:
    the image, or the error's type and message."""
    from isophote.format.isoph.header import guarded, parse_header
    from isophote.format.isoph.read import decode

    def parse():
        h = parse_header(data, len(data))
        return decode(h, memoryview(data)[h.header_size:], compact)

    try:
        return guarded(parse)
    except (FormatError, LimitError) as e:
        return type(e).__name__, str(e)


@budget(150)
@given(st.integers(0, 2**32 - 1), st.integers(0, 2**16), st.sampled_from(["raw", "raw", "both crcs"]))
def test_compact_loads_refuse_and_accept_what_full_loads_do(seeds, seed, which, mode):
    """A mutated real file loaded compact (its range-coded points decoded as int32, then
    float32) gives the error the float64 load gives, or the same values: the decoder checks
    every value against the format's limit before it stores it, so none wraps."""
    data = mutate(seeds[which % len(seeds)], seeds[0], seed, mode)
    full, small = _outcome(data, False), _outcome(data, True)
    if isinstance(full, tuple):
        assert small == full
        return
    assert not isinstance(small, tuple), small
    for a, b in zip(full.channels, small.channels):
        assert np.array_equal(a.points, b.points) and np.array_equal(a.cap_xy, b.cap_xy)
        assert np.array_equal(a.offsets, b.offsets) and np.array_equal(a.border, b.border)
        assert np.array_equal(a.cap_value, b.cap_value) and np.array_equal(a.parent, b.parent)
    COUNTS["compact: same values"] += 1


def test_truncations_and_flips_of_an_encoder_file_at_every_byte(seeds):
    """Every prefix of a real file, and the file with each byte in turn inverted: a
    FormatError every time (the checksums make a single corrupted byte always visible)."""
    data = seeds[9]  # the 9 x 10 grey + alpha image, zlib
    assert 500 < len(data) < 3000
    for n in range(len(data)):
        with pytest.raises(FormatError):
            isoph.loads(data[:n])
    for i in range(len(data)):
        bad = bytearray(data)
        bad[i] ^= 0xFF
        with pytest.raises(FormatError):
            isoph.loads(bytes(bad))
    COUNTS["every byte: FormatError"] += 2 * len(data)


def test_files_on_disk(tmp_path, seeds):
    """The path readers (load, read_info) on truncated, empty, directory and missing files."""
    p = tmp_path / "f.isoph"
    for n in (0, 1, 15, 16, 60, len(seeds[0]) - 1):
        p.write_bytes(seeds[0][:n])
        for reader in (isoph.load, isoph.read_info):
            with pytest.raises(FormatError) as e:
                reader(p)
            assert str(p) in str(e.value) and "\n" not in str(e.value)
    for path in (tmp_path, tmp_path / "missing.isoph"):
        with pytest.raises(FormatError):
            isoph.load(path)


# =============================================================================================
# Memory: the declared sizes are checked before allocation, renders are limited
# =============================================================================================


def test_render_refuses_huge_outputs():
    vi = VectorImage(40, 30, "grey", (Channel.empty("Y", [127.5]),))
    for kw in (dict(scale=1000), dict(width=100_000, height=100_000), dict(width=1_000_000)):
        with pytest.raises(LimitError, match="max_pixels|max-pixels"):
            vi.render(**kw)
    assert vi.render(width=40, max_pixels=1200).shape == (30, 40)
    with pytest.raises(LimitError):
        vi.render(width=41, max_pixels=1200)
    huge = VectorImage(isoph.MAX_WIDTH, isoph.MAX_HEIGHT, "grey", (Channel.empty("Y", [127.5]),))
    with pytest.raises(LimitError):
        isoph.loads(isoph.dumps(huge)).render()  # 2**40 pixels at scale 1


_RENDER_HUGE_CANVAS = r"""
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))
from isophote.errors import LimitError
from isophote.format import isoph
from isophote.model import Channel, VectorImage
side = int(sys.argv[1])
vi = VectorImage(side, side, "grey", (Channel.empty("Y", [127.5]),))
data = isoph.dumps(vi)
assert len(data) < 200
try:
    out = isoph.loads(data).render(width=16)
except LimitError as e:
    print("LimitError", e)
else:
    print("rendered", out.shape)
"""


@pytest.mark.parametrize("side", [
    isoph.MAX_WIDTH,  # asked for terabytes of distance nodes before they were checked (fixed)
    10_000,  # 10**8 distance nodes passed the first check and took > 10 GB (fixed: max_pixels / 8)
])
def test_render_memory_is_bounded_for_a_tiny_file_with_a_huge_canvas(side):
    """A 93-byte file declaring a huge canvas, rendered at 16 x 16: a LimitError or a render
    within 2 GB. Run in a child with a 2 GB address-space limit, so that a failure cannot
    take the machine with it."""
    r = subprocess.run([sys.executable, "-c", _RENDER_HUGE_CANVAS, str(side)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr.strip().splitlines()[-1:]


# =============================================================================================
# Images: any array encodes or fails cleanly; image files fail cleanly
# =============================================================================================


@st.composite
def images(draw):
    h, w = draw(st.integers(1, 10)), draw(st.integers(1, 10))
    c = draw(st.sampled_from([None, 1, 2, 3, 4]))
    shape = (h, w) if c is None else (h, w, c)
    dtype = draw(st.sampled_from(["uint8", "uint16", "float64", "bool"]))
    kind = draw(st.sampled_from(["constant", "noise", "binary", "few values", "gradient", "on levels"]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    top = {"uint8": 255, "uint16": 65535, "float64": 255.0, "bool": 1}[dtype]
    if kind == "constant":
        a = np.full(shape, draw(st.sampled_from([0, top, top // 2 if dtype != "float64" else 127.5, 1])))
    elif kind == "noise":
        a = rng.integers(0, top + 1, shape) if dtype != "float64" else rng.uniform(0, 255, shape)
    elif kind == "binary":
        a = rng.integers(0, 2, shape) * top
    elif kind == "few values":
        a = rng.choice(np.array([0, top // 3, top // 2, top]), shape)
    elif kind == "gradient":
        a = np.broadcast_to(np.linspace(0, top, w)[None, :, None] if c else np.linspace(0, top, w)[None, :],
                            shape).copy()
    else:  # samples exactly on the paper preset's levels (127.5 + 10 k): the tie rule
        a = rng.choice(np.array([107.5, 117.5, 127.5, 137.5]), shape)
        dtype = "float64"
    return kind, np.asarray(a).astype(dtype)


@budget(60)
@given(images())
def test_any_image_encodes_deterministically(case):
    kind, a = case
    vi = isophote.encode(a)
    b = isoph.dumps(vi)
    assert isoph.dumps(isophote.encode(a.copy())) == b, "encode is not deterministic"
    back = isoph.loads(b)
    assert back.equals(vi)
    out = back.render()
    assert out.shape == (a.shape if a.ndim == 3 and a.shape[2] > 1 else a.shape[:2])
    if kind == "constant":
        scale = {np.dtype(np.uint16): 1 / 257, np.dtype(bool): 255.0}.get(a.dtype, 1.0)
        want = np.asarray(a, np.float64) * scale
        # 8-bit rounding, after the encoder's 1/QUANT-grey-level grid for cap values (16-bit input)
        assert np.abs(out.astype(np.float64).reshape(want.shape) - want).max() <= 0.5 + 0.5 / QUANT + 1e-9
    COUNTS[f"images: {kind}"] += 1


BAD_ARRAYS = {
    "NaN": np.full((3, 3), np.nan),
    "infinity": np.full((3, 3), np.inf),
    "negative": np.full((3, 3), -1.0),
    "over 255": np.full((3, 3), 256.0),
    "no rows": np.zeros((0, 4)),
    "no columns": np.zeros((4, 0, 3)),
    "5 channels": np.zeros((3, 3, 5)),
    "4-D": np.zeros((2, 2, 2, 2)),
    "1-D": np.zeros(5),
    "strings": np.array([["a", "b"]]),
    "objects": np.array([[None, 1]], dtype=object),
    "complex": np.zeros((2, 2), complex),  # was cast to float, imaginary part dropped (fixed)
}


@pytest.mark.parametrize("array", list(BAD_ARRAYS.values()), ids=list(BAD_ARRAYS))
def test_bad_arrays_are_input_errors(array):
    with pytest.raises(InputError) as e:
        isophote.encode(array)
    assert "\n" not in str(e.value)


IMAGE_SEEDS = [".png", ".jpg", ".gif", ".tif", ".bmp", ".webp", ".ppm"]


@pytest.fixture(scope="module")
def image_seeds(tmp_path_factory):
    from PIL import Image

    d = tmp_path_factory.mktemp("img")
    a = _smooth(9, 11, 3).astype(np.uint8)
    out = {}
    for ext in IMAGE_SEEDS:
        Image.fromarray(a).save(d / ("s" + ext))
        out[ext] = (d / ("s" + ext)).read_bytes()
    frames = [Image.fromarray(a), Image.fromarray(255 - a)]
    frames[0].save(d / "anim.png", save_all=True, append_images=frames[1:])
    out[".apng"] = (d / "anim.png").read_bytes()
    return out


def _fix_png_crcs(b: bytes) -> bytes:
    """Recompute every chunk CRC of a (mutated) PNG, so the decoder sees the mutation."""
    if not b.startswith(b"\x89PNG\r\n\x1a\n"):
        return b
    out, i = bytearray(b[:8]), 8
    while i + 12 <= len(b):
        (n,) = struct.unpack_from(">I", b, i)
        if i + 12 + n > len(b):
            break
        body = b[i + 4: i + 8 + n]
        out += b[i:i + 4] + body + struct.pack(">I", zlib.crc32(body))
        i += 12 + n
    return bytes(out + b[i:])


@budget(300)
@given(st.sampled_from(IMAGE_SEEDS + [".apng"]), st.integers(0, 2**32 - 1), st.booleans())
def test_mutated_image_files(tmp_path_factory, image_seeds, ext, seed, fix_crcs):
    rng = np.random.default_rng(seed)
    b = bytearray(image_seeds[ext])
    for _ in range(int(rng.integers(1, 4))):
        b = _mutate_bytes(b, rng, image_seeds[".png"])
    data = _fix_png_crcs(bytes(b)) if fix_crcs else bytes(b)
    p = tmp_path_factory.getbasetemp() / ("mutated" + (".png" if ext == ".apng" else ext))
    p.write_bytes(data)
    try:
        r = read_image(p)
    except (InputError, LimitError) as e:
        assert "\n" not in str(e)
        COUNTS[f"image files: {type(e).__name__}"] += 1
        return
    assert r.pixels.ndim == 3 and r.pixels.shape[2] in (1, 2, 3, 4)
    assert r.pixels.dtype == np.float64 and np.all((r.pixels >= 0) & (r.pixels <= 255))
    COUNTS["image files: read"] += 1


# =============================================================================================
# The command line: exit 2 with one line, nothing lost, the same bytes every time
# =============================================================================================


@pytest.fixture
def files(tmp_path):
    png = tmp_path / "in.png"
    write_image(png, _smooth(14, 18, 3))
    out = tmp_path / "in.isoph"
    assert cli.main(["encode", str(png), "-o", str(out), "-q"]) == 0
    return png, out


def _run(capsys, *argv):
    rc = cli.main([str(a) for a in argv])
    captured = capsys.readouterr()
    return rc, captured.out, captured.err


def _assert_one_line_refusal(rc, err):
    assert rc == 2, (rc, err)
    assert err.startswith("isophote: ") and err.count("\n") == 1 and "Traceback" not in err, err


def test_cli_render_of_mutated_files_exits_2_and_writes_nothing(files, tmp_path, capsys):
    _, good = files
    data = good.read_bytes()
    bad = tmp_path / "bad.isoph"
    out = tmp_path / "out.png"
    rng = np.random.default_rng(0)
    for trial in range(40):
        bad.write_bytes(mutate(data, data, int(rng.integers(0, 2**32)), ["none", "header crc", "raw"][trial % 3]))
        for argv in (["render", bad, "-o", out], ["info", bad], ["contours", bad, "-o", out]):
            rc, _, err = _run(capsys, *argv)
            if rc == 0:  # a mutation that still makes a valid file (rare): fine, start again
                out.unlink(missing_ok=True)
                continue
            _assert_one_line_refusal(rc, err)
            assert not out.exists()
        COUNTS["cli: mutated files"] += 1
    assert sorted(os.listdir(tmp_path)) == ["bad.isoph", "in.isoph", "in.png"]  # no temporary files


def test_cli_error_is_one_line_even_for_a_path_with_a_newline(files, tmp_path, capsys):
    _, good = files
    odd = tmp_path / "two\nlines.isoph"
    odd.write_bytes(good.read_bytes()[:-1])
    _assert_one_line_refusal(*_run(capsys, "render", odd, "-o", tmp_path / "o.png")[::2])
    _assert_one_line_refusal(*_run(capsys, "info", odd)[::2])


def test_cli_failure_leaves_an_existing_output_untouched(files, tmp_path, capsys):
    png, good = files
    out = tmp_path / "keep.png"
    out.write_bytes(b"the previous render")
    before = os.stat(out)
    bad = tmp_path / "bad.isoph"
    bad.write_bytes(good.read_bytes()[:-3])
    for argv in (["render", bad, "-o", out], ["render", good, "-o", out, "--max-pixels", "10"],
                 ["render", good, "-o", out, "--scale", "1000"]):
        _assert_one_line_refusal(*_run(capsys, *argv)[::2])
        assert out.read_bytes() == b"the previous render" and os.stat(out).st_mtime_ns == before.st_mtime_ns
    text = tmp_path / "text.png"
    text.write_text("not an image")
    iso = tmp_path / "keep.isoph"
    iso.write_bytes(b"the previous encode")
    _assert_one_line_refusal(*_run(capsys, "encode", text, "-o", iso)[::2])
    assert iso.read_bytes() == b"the previous encode"


def test_cli_never_modifies_its_inputs_and_refuses_output_onto_input(files, tmp_path, capsys):
    png, iso = files
    snap = {p: (p.read_bytes(), os.stat(p).st_mtime_ns) for p in (png, iso)}
    assert _run(capsys, "encode", png, "-o", tmp_path / "b.isoph", "-q")[0] == 0
    assert _run(capsys, "render", iso, "-o", tmp_path / "b.png", "-q")[0] == 0
    assert _run(capsys, "info", iso)[0] == 0
    assert _run(capsys, "contours", iso, "-o", tmp_path / "c.png", "-q")[0] == 0
    for argv in (["encode", png, "-o", png], ["render", iso, "-o", iso],
                 ["encode", png, "-o", tmp_path / "." / "in.png"]):
        _assert_one_line_refusal(*_run(capsys, *argv)[::2])
    link = tmp_path / "link.png"
    os.symlink(png, link)
    _assert_one_line_refusal(*_run(capsys, "encode", link, "-o", png)[::2])
    for p, (data, mtime) in snap.items():
        assert p.read_bytes() == data and os.stat(p).st_mtime_ns == mtime


def test_cli_same_input_same_bytes(files, tmp_path, capsys):
    png, _ = files
    for i in (1, 2):
        assert _run(capsys, "encode", png, "-o", tmp_path / f"e{i}.isoph", "-q")[0] == 0
        for ext in (".png", ".tif", ".jpg", ".webp"):
            assert _run(capsys, "render", tmp_path / f"e{i}.isoph", "-o", tmp_path / f"r{i}{ext}", "-q",
                        "--scale", "1.5")[0] == 0
        assert _run(capsys, "render", tmp_path / f"e{i}.isoph", "-o", tmp_path / f"d{i}.png", "-q",
                    "--depth", "16", "--fill", "flat")[0] == 0
    for a, b in [("e1.isoph", "e2.isoph"), ("d1.png", "d2.png")] + [(f"r1{x}", f"r2{x}") for x in
                                                                      (".png", ".tif", ".jpg", ".webp")]:
        assert (tmp_path / a).read_bytes() == (tmp_path / b).read_bytes(), a


def test_same_bytes_across_processes(files, tmp_path):
    """Two fresh interpreters (different hash seeds, thread timing) write identical files."""
    png, _ = files
    outs = []
    for i, hashseed in enumerate(("1", "2")):
        iso, ren = tmp_path / f"p{i}.isoph", tmp_path / f"p{i}.png"
        script = (f"from isophote.cli import main; "
                  f"assert main(['encode', {str(png)!r}, '-o', {str(iso)!r}, '-q']) == 0; "
                  f"assert main(['render', {str(iso)!r}, '-o', {str(ren)!r}, '-q']) == 0")
        r = subprocess.run([sys.executable, "-c", script], env=dict(os.environ, PYTHONHASHSEED=hashseed),
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        outs.append((iso.read_bytes(), ren.read_bytes()))
    assert outs[0] == outs[1]
