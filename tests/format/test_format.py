"""Tests of the .isoph format (src/isophote/format/isoph.py, docs/format.md).

The file builder ``spec_file`` below is a second, independent implementation of the layout,
written from the specification with plain Python loops (the range-coded channels through the
plain-Python twin of the coder, _kernels/entropy_ref.py): it must produce the very bytes
``dumps`` produces, and it crafts files whose fields lie but whose checksums are right.
"""

from __future__ import annotations

import json
import lzma
import struct
import zlib

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from isophote.format._coder import entropy_ref
from isophote.errors import FormatError, InputError, IsophoteError, LimitError
from isophote.format import isoph
from isophote.format.isoph import header as isoph_header
from isophote.model import Channel, VectorImage

Q = 64  # the 1/64 grid, typed out rather than imported: the spec says 64


# ---- random valid images ------------------------------------------------------------------


def random_chain(rng, w, h, n=None):
    """A closed chain of n cubic segments on the 1/64 grid, roughly a wobbly circle."""
    n = int(rng.integers(1, 9)) if n is None else n
    cx, cy = rng.uniform(0, w), rng.uniform(0, h)
    r = rng.uniform(0.5, max(w, h) / 3)
    t = np.sort(rng.uniform(0, 2 * np.pi, 3 * n))
    rr = r * rng.uniform(0.6, 1.4, 3 * n)
    p = np.c_[cx + rr * np.cos(t), cy + rr * np.sin(t)]
    p = np.vstack([p, p[:1]])
    return np.rint(p * Q) / Q


def random_tree(rng, c):
    """Parents of c contours forming a forest, in a random (not parents-first) order."""
    order = rng.permutation(c)
    parent = np.full(c, -1, np.int32)
    for i in range(1, c):
        if rng.random() < 0.75:
            parent[order[i]] = order[rng.integers(0, i)]
    return parent


def random_channel(rng, name="Y", w=40, h=30, n_contours=None, n_levels=None) -> Channel:
    n_levels = int(rng.integers(1, 30)) if n_levels is None else n_levels
    levels = np.cumsum(rng.uniform(0.25, 20, n_levels)) + rng.uniform(-10, 10)
    c = int(rng.integers(0, 12)) if n_contours is None else n_contours
    chains = [random_chain(rng, w, h) for _ in range(c)]
    offsets = np.zeros(c + 1, np.int64)
    offsets[1:] = np.cumsum([len(ch) for ch in chains])
    s = int(sum((len(ch) - 1) // 3 for ch in chains))
    k = int(rng.integers(0, c + 2))
    return Channel(
        name=name,
        levels=levels.astype(np.float64),
        contour_level=rng.integers(0, n_levels, c).astype(np.int32) if n_levels else np.zeros(0, np.int32),
        offsets=offsets,
        points=np.concatenate(chains) if chains else np.zeros((0, 2)),
        border=rng.random(s) < 0.2,
        parent=random_tree(rng, c),
        cap_band=rng.integers(0, n_levels + 1, k).astype(np.int32),
        cap_contour=rng.integers(-1, c, k).astype(np.int32),
        cap_xy=np.rint(rng.uniform(-1, w + 1, (k, 2)) * Q) / Q,
        cap_value=np.rint(rng.uniform(-20, 280, k) * Q) / Q,
        base_band=int(rng.integers(0, n_levels + 1)),
    )


LAYOUTS = {
    "grey": ("grey", ("Y",)),
    "grey+alpha": ("grey", ("Y", "A")),
    "yuv": ("yuv", ("Y", "U", "V")),
    "yuv+alpha": ("yuv", ("Y", "U", "V", "A")),
}


def random_tone(rng) -> np.ndarray:
    """A monotone tone curve: 2 .. 40 knots, x strictly increasing, y non-decreasing."""
    k = int(rng.integers(2, 41))
    x = np.cumsum(rng.uniform(0.01, 20, k)) - 10
    y = np.cumsum(np.where(rng.random(k) < 0.2, 0.0, rng.uniform(0, 12, k)))
    return np.c_[x, y]


def random_image(seed, layout="yuv", tone=True, **kw) -> VectorImage:
    rng = np.random.default_rng(seed)
    colour, names = LAYOUTS[layout]
    w, h = int(rng.integers(1, 200)), int(rng.integers(1, 200))
    chans = tuple(random_channel(rng, n, w, h, **kw) for n in names)
    if tone:  # from a generator of its own, so that the rest does not depend on it
        trng = np.random.default_rng(seed + 7919)
        chans = tuple(replace(c, tone=random_tone(trng)) if trng.random() < 0.4 else c for c in chans)
    return VectorImage(w, h, colour, chans, source_depth=int(rng.choice([8, 16])),
                       meta={"seed": seed, "note": "café"})


def small_image() -> VectorImage:
    """A few hundred bytes: for cutting at every length."""
    return random_image(3, "grey", n_contours=3, n_levels=4)


# ---- an independent writer, from the specification ----------------------------------------


def zz(v: int) -> int:
    return 2 * v if v >= 0 else -2 * v - 1


def planes(values, width: int) -> bytes:
    """A column as byte planes, least significant first, written from the spec's wording."""
    return b"".join(bytes((v >> (8 * j)) & 0xFF for v in values) for j in range(width))


def spec_channel(ch: Channel) -> dict:
    """A model Channel as the plain fields of the spec (integers on the grid)."""
    q = [(int(round(x * Q)), int(round(y * Q))) for x, y in ch.points]
    chains = [q[ch.offsets[k] : ch.offsets[k + 1] - 1] for k in range(ch.n_contours)]  # no closing point
    return dict(
        name=ch.name, levels=[float(v) for v in ch.levels],
        contour_level=[int(v) for v in ch.contour_level], chains=chains,
        parent=[int(v) for v in ch.parent], border=[bool(b) for b in ch.border],
        cap_band=[int(v) for v in ch.cap_band], cap_contour=[int(v) for v in ch.cap_contour],
        cap_xy=[(int(round(x * Q)), int(round(y * Q))) for x, y in ch.cap_xy],
        cap_value=[int(round(v * Q)) for v in ch.cap_value], base_band=int(ch.base_band),
        tone=None if ch.tone is None else [(float(x), float(y)) for x, y in ch.tone],
    )


def spec_sections(c: dict) -> bytes:
    """One channel's raw payload; ``nseg`` may lie about the chains' segment counts."""
    if "sections" in c:
        return c["sections"]
    levels = [zz(lev - prev) for prev, lev in zip([0] + c["contour_level"], c["contour_level"])]
    nseg = c.get("nseg", [len(chain) // 3 for chain in c["chains"]])
    parent = [0 if p == -1 else zz(k - p) for k, p in enumerate(c["parent"])]
    points = []
    px, py = 0, 0  # one stream of differences over all chains, from (0, 0)
    for chain in c["chains"]:
        for x, y in chain:
            points += [zz(x - px), zz(y - py)]
            px, py = x, y
    cc = [zz(v - prev) for prev, v in zip([-1] + c["cap_contour"], c["cap_contour"])]
    cap_xy = []
    for (x, y), k in zip(c["cap_xy"], c["cap_contour"]):
        # From the first point of its contour (any origin will do for an invalid contour).
        ox, oy = c["chains"][k][0] if 0 <= k < len(c["chains"]) else (0, 0)
        cap_xy += [zz(x - ox), zz(y - oy)]
    bits = c["border"]
    border = bytes(sum(1 << j for j, b in enumerate(bits[i : i + 8]) if b) for i in range(0, len(bits), 8))
    return (planes(levels, 2) + planes([n - 1 for n in nseg], 4) + planes(parent, 4) + planes(points, 4)
            + planes(c["cap_band"], 2) + planes(cc, 4)
            + planes(cap_xy, 4)
            + planes([zz(v) for v in c["cap_value"]], 4) + border)


def grid_shift(values, most=6) -> int:
    """The largest s <= most such that every value is a multiple of 2**s (0 for none)."""
    s = 0
    while values and s < most and all(v % (1 << (s + 1)) == 0 for v in values):
        s += 1
    return s


def spec_range(c: dict, version: int = 5) -> tuple:
    """One channel's range-coded bytes in ``version``'s layout and its grids (s_p, g, s_c,
    s_v), as the spec says: the coarsest grids that lose nothing; the anchor grid g scoring
    best at 2 g (on-grid anchor coordinates) - 3 (anchors), if that is > 0. A dict may set
    any of them."""
    coords = [v for chain in c["chains"] for p in chain for v in p]
    s_p = c.get("s_p", grid_shift(coords))
    s_c = c.get("s_c", grid_shift([v for p in c["cap_xy"] for v in p]))
    s_v = c.get("s_v", grid_shift(c["cap_value"]))
    chains = [[(x >> s_p, y >> s_p) for x, y in chain] for chain in c["chains"]]
    anchors = [v for chain in chains for p in chain[0::3] for v in p]
    g, best = 0, 0
    for gg in range(1, 17):
        score = 2 * gg * sum(1 for v in anchors if v % (1 << gg) == 0) - 3 * (len(anchors) // 2)
        if score > best:
            g, best = gg, score
    g = c.get("g", g)
    fields = dict(level=c["contour_level"], nseg=c.get("nseg", [len(ch) // 3 for ch in chains]),
                  parent=c["parent"], chains=chains, border=[int(b) for b in c["border"]], g=g,
                  cap_contour=c["cap_contour"], cap_band=c["cap_band"],
                  cap_xy=[(x >> s_c, y >> s_c) for x, y in c["cap_xy"]],
                  cap_value=[v >> s_v for v in c["cap_value"]], s_p=s_p, s_c=s_c, s_v=s_v,
                  levels=c["levels"], base_band=c.get("base_band", 0), version=version)
    return entropy_ref.encode_channel(fields), (s_p, g, s_c, s_v)


def spec_file(channels, *, width=40, height=30, colour=0, depth=8, compression=0, xy_quant=64,
              value_quant=64, version=5, reserved=0, meta=b"", raw_extra=b"", raw_size=None,
              header_extra=b"", payload_size=None, file_extra=b"", payload=None) -> bytes:
    """A file from spec-level fields; every field can lie, the checksums are always right.

    Counts default to the true ones; a channel dict may override n_contours, n_segments,
    n_caps, n_levels, n_tone, cap_ramp (and give raw ``sections``; for compression 3, ``coded``
    bytes, ``coded_size`` and the grids s_p, g, s_c, s_v). ``version=1`` writes version 1's
    header; ``version=2`` version 2's (version 3's less cap_ramp) and range-coded layout.
    """
    raw = b"".join(spec_sections(c) for c in channels) + raw_extra
    grids, coded = [], []
    for c in channels:
        if compression == 3 and "coded" not in c:
            data, gr = spec_range(c, version)
        else:
            data, gr = c.get("coded", b""), (0, 0, 0, 0)
        coded.append(data)
        grids.append(tuple(c.get(k, v) for k, v in zip(("s_p", "g", "s_c", "s_v"), gr)))
    if payload is not None:
        payload = payload(raw)  # a function of the raw payload
    elif compression == 1:
        payload = zlib.compress(raw, 6)
    elif compression == 2:
        payload = lzma.compress(raw, format=lzma.FORMAT_RAW,
                                filters=[{"id": lzma.FILTER_LZMA2, "preset": 6, "dict_size": 1 << 23}])
    elif compression == 3:
        payload = b"".join(coded)
    else:
        payload = raw
    body = struct.pack(
        "<IIBBBBHHQQII", width, height, colour, depth, len(channels), compression, xy_quant,
        value_quant, len(payload) if payload_size is None else payload_size,
        len(raw) if raw_size is None else raw_size, zlib.crc32(payload), len(meta),
    ) + meta
    for c, data, (s_p, g, s_c, s_v) in zip(channels, coded, grids):
        n_contours = c.get("n_contours", len(c.get("chains", [])))
        n_segments = c.get("n_segments", sum(len(ch) // 3 for ch in c.get("chains", [])))
        n_caps = c.get("n_caps", len(c.get("cap_band", [])))
        tone = c.get("tone") or []
        if version == 1:
            body += struct.pack("<cHHIII", c["name"].encode(), c.get("n_levels", len(c["levels"])),
                                c.get("base_band", 0), n_contours, n_segments, n_caps)
        else:
            body += struct.pack("<cHHIIIHBBBBQ", c["name"].encode(), c.get("n_levels", len(c["levels"])),
                                c.get("base_band", 0), n_contours, n_segments, n_caps,
                                c.get("n_tone", len(tone)), s_p, g, s_c, s_v, c.get("coded_size", len(data)))
        body += struct.pack(f"<{len(c['levels'])}d", *c["levels"])
        body += b"".join(struct.pack("<dd", x, y) for x, y in tone)
        if version >= 3:
            body += struct.pack("<d", c.get("cap_ramp", 2.0))
    body += header_extra
    head = b"\x89ISOPH\r\n" + struct.pack("<HHI", version, reserved, 16 + len(body) + 4) + body
    return head + struct.pack("<I", zlib.crc32(head)) + payload + file_extra


def one_channel(**over) -> dict:
    """A small valid grey channel as spec fields: two nested contours and one cap."""
    c = dict(
        name="Y", levels=[50.0, 100.0, 150.0], contour_level=[0, 1],
        chains=[[(64, 64), (640, 64), (1280, 64), (1280, 640), (1280, 1280), (64, 1280)],
                [(320, 320), (640, 320), (960, 320)]],
        parent=[-1, 0], border=[False, True, False],
        cap_band=[2], cap_contour=[1], cap_xy=[(500, 500)], cap_value=[170 * 64],
    )
    c.update(over)
    return c


RAW_SIZE = 10 * 2 + 24 * 3 + 18 * 1 + 1  # one_channel(): C = 2, S = 3, K = 1


def reference_rounded(vi: VectorImage) -> VectorImage:
    """vi with coordinates and cap values rounded to the 1/64 grids, canonical dtypes."""
    chans = tuple(
        Channel(
            ch.name, np.asarray(ch.levels, np.float64), np.asarray(ch.contour_level, np.int32),
            np.asarray(ch.offsets, np.int64), np.rint(ch.points * Q) / Q, np.asarray(ch.border, bool),
            np.asarray(ch.parent, np.int32), np.asarray(ch.cap_band, np.int32),
            np.asarray(ch.cap_contour, np.int32), np.rint(ch.cap_xy * Q) / Q,
            np.rint(ch.cap_value * Q) / Q, ch.base_band, ch.tone,
        )
        for ch in vi.channels
    )
    return VectorImage(vi.width, vi.height, vi.colour, chans, vi.source_depth, vi.meta)


# ---- round trips ---------------------------------------------------------------------------


def test_channels_one_at_a_time_and_in_chunks_give_the_same_bytes(monkeypatch):
    """The writer's memory bounds (stored points quantised a chunk of rows at a time, the
    closing points left out as they come; channels checked and coded one at a time) change
    no byte."""
    from isophote.format.isoph import layout as isoph_layout, write as isoph_write

    vi = random_image(2, "yuv+alpha")
    want = {c: isoph.dumps(vi, compression=c) for c in ("range", "zlib")}
    ch = vi.channels[0]
    q = np.rint(ch.points * Q).astype(np.int64)
    monkeypatch.setattr(isoph_write, "QUANTISE_CHUNK", 5)  # chunk edges inside and at chain ends
    monkeypatch.setattr(isoph_write, "ONE_AT_A_TIME_POINTS", 1)
    for c, data in want.items():
        assert isoph.dumps(vi, compression=c) == data
    # the writer of an image it may consume: the same bytes, made in the points' own memory
    for c, data in want.items():
        own = replace(vi, channels=tuple(replace(x, points=x.points.copy()) for x in vi.channels))
        held = [own]
        assert isoph_write.dumps_held(held, compression=c) == data and held == []
        assert not np.array_equal(own.channels[0].points, ch.points)  # consumed: no copy was made
    with pytest.raises(ValueError, match="exactly one"):
        isoph_write.dumps_held([vi, vi])
    with pytest.raises(ValueError, match="compression must be"):
        isoph_write.dumps_held([vi], compression="gzip")
    checked = isoph_write.checked_channel(ch)
    keep = np.ones(q.shape[0], bool)
    keep[ch.offsets[1:] - 1] = False
    assert np.array_equal(checked.stored, q[keep])
    assert np.array_equal(isoph_layout.closed_points(checked.stored, checked.offsets), q)
    # a chain left open is still found, wherever the chunks fall
    pts = ch.points.copy()
    pts[ch.offsets[2] - 1] += 1.0
    with pytest.raises(ValueError, match="contour 1 is not closed"):
        isoph.dumps(replace(vi, channels=(replace(ch, points=pts),) + vi.channels[1:]))


@pytest.mark.parametrize("compression", ["range", "lzma", "zlib", "none"])
@pytest.mark.parametrize("layout", list(LAYOUTS))
def test_round_trip_exact(layout, compression):
    for seed in range(4):
        vi = random_image(seed, layout)
        out = isoph.loads(isoph.dumps(vi, compression=compression))
        assert out.equals(vi)
        assert out.meta == vi.meta
        assert [c.name for c in out.channels] == list(LAYOUTS[layout][1])
        for ch in out.channels:  # canonical dtypes, closed chains
            assert ch.points.dtype == np.float64 and ch.offsets.dtype == np.int64
            assert ch.parent.dtype == np.int32 and ch.border.dtype == bool
            if ch.n_contours:
                assert np.array_equal(ch.points[ch.offsets[:-1]], ch.points[ch.offsets[1:] - 1])
            assert ch.tone is None or (ch.tone.dtype == np.float64 and ch.tone.shape[1] == 2)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(list(LAYOUTS)))
def test_round_trip_property(seed, layout):
    vi = random_image(seed, layout)
    b = isoph.dumps(vi)
    assert isoph.loads(b).equals(vi)
    assert isoph.dumps(isoph.loads(b)) == b


def test_dumps_is_deterministic():
    vi = random_image(11, "yuv+alpha")
    a, b = isoph.dumps(vi), isoph.dumps(random_image(11, "yuv+alpha"))
    assert a == b
    assert isoph.dumps(isoph.loads(a)) == a


@pytest.mark.parametrize("compression,code", [("none", 0), ("zlib", 1), ("lzma", 2), ("range", 3)])
def test_spec_writer_gives_the_same_bytes(compression, code):
    """The independent implementation of the spec and dumps agree byte for byte, on random
    images and on the encoder's (anchors on the sample grid, caps on the half-pixel grid)."""
    for vi in [random_image(1, "grey"), random_image(2, "yuv"), random_image(5, "yuv+alpha"), encoded_image()]:
        meta = json.dumps(vi.meta, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode() if vi.meta else b""
        colour = {"grey": 0, "yuv": 1}[vi.colour]
        expected = spec_file([spec_channel(c) for c in vi.channels], width=vi.width, height=vi.height,
                             colour=colour, depth=vi.source_depth, compression=code, meta=meta)
        assert isoph.dumps(vi, compression=compression) == expected


def encoded_image() -> VectorImage:
    """The encoder's output for a small RGB image: grids as the encoder makes them."""
    import isophote

    yy, xx = np.mgrid[0:20, 0:26]
    rgb = np.stack([xx * 9.0, 255 - yy * 11.0, 128 + 90 * ((xx - 13) ** 2 + (yy - 10) ** 2 < 40)], -1)
    return isophote.encode(np.clip(rgb, 0, 255))


def test_empty_channels_round_trip():
    vi = VectorImage(7, 5, "yuv", (Channel.empty("Y", [10.0, 20.0]), Channel.empty("U", []),
                                   Channel.empty("V", [127.5])))
    out = isoph.loads(isoph.dumps(vi))
    assert out.equals(vi) and out.meta == {}
    info = isoph.read_info(isoph.dumps(vi))
    assert [c["contours"] for c in info["channels"]] == [0, 0, 0]


def test_off_grid_values_come_back_rounded():
    rng = np.random.default_rng(8)
    vi = random_image(8, "yuv")
    chans = []
    for ch in vi.channels:
        p = ch.points + rng.uniform(-0.5, 0.5, ch.points.shape) / Q
        p[ch.offsets[1:] - 1] = p[ch.offsets[:-1]]  # keep the chains closed
        chans.append(Channel(ch.name, ch.levels, ch.contour_level, ch.offsets, p, ch.border,
                             ch.parent, ch.cap_band, ch.cap_contour,
                             ch.cap_xy + rng.uniform(-0.5, 0.5, ch.cap_xy.shape) / Q,
                             ch.cap_value + rng.uniform(-0.5, 0.5, ch.cap_value.shape) / Q, ch.base_band))
    vi2 = VectorImage(vi.width, vi.height, vi.colour, tuple(chans), vi.source_depth)
    out = isoph.loads(isoph.dumps(vi2))
    assert out.equals(reference_rounded(vi2))
    for a, b in zip(out.channels, vi2.channels):
        assert np.abs(a.points - b.points).max(initial=0) <= 0.5 / Q
        assert np.abs(a.cap_value - b.cap_value).max(initial=0) <= 0.5 / Q
        assert np.array_equal(a.levels, b.levels)  # levels are exact float64


def test_repetitive_payload_is_stored_not_a_bomb():
    """100000 identical contours compress beyond the 64:1 limit: written stored."""
    n = 100_000
    chain = np.array([[1, 1], [2, 1], [2, 2], [1, 1]], np.float64)
    ch = Channel("Y", np.array([10.0]), np.zeros(n, np.int32), np.arange(n + 1, dtype=np.int64) * 4,
                 np.tile(chain, (n, 1)), np.zeros(n, bool), np.full(n, -1, np.int32),
                 np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros((0, 2)), np.zeros(0))
    vi = VectorImage(4, 4, "grey", (ch,))
    b = isoph.dumps(vi)
    assert isoph.read_info(b)["compression"] == "none"
    assert isoph.loads(b).equals(vi)
    # the range coder shifted the stored points (in the points' own memory) before the
    # ratio sent the file stored: shifted back, the same bytes
    from isophote.format.isoph.write import dumps_held

    assert dumps_held([replace(vi, channels=(replace(ch, points=ch.points.copy()),))]) == b


def test_deep_nesting_and_reverse_order_parents():
    """A 20000-deep nest, parents after children: checked without recursion."""
    n = 20000
    rng = np.random.default_rng(0)
    chains = [random_chain(rng, 50, 50, 1) for _ in range(n)]
    base = Channel("Y", np.array([1.0]), np.zeros(n, np.int32),
                   np.r_[0, np.cumsum([4] * n)].astype(np.int64), np.concatenate(chains),
                   np.zeros(n, bool), np.r_[np.arange(1, n), -1].astype(np.int32),
                   np.zeros(0, np.int32), np.zeros(0, np.int32), np.zeros((0, 2)), np.zeros(0))
    vi = VectorImage(50, 50, "grey", (base,))
    assert isoph.loads(isoph.dumps(vi)).equals(vi)


# ---- corruption ----------------------------------------------------------------------------


@pytest.mark.parametrize("compression", ["range", "lzma", "zlib", "none"])
def test_truncation_at_every_length(compression):
    b = isoph.dumps(small_image(), compression=compression)
    assert 100 < len(b) < 2000
    for n in range(len(b)):
        with pytest.raises(FormatError):
            isoph.loads(b[:n])
        with pytest.raises(FormatError):
            isoph.read_info(b[:n])


def test_trailing_bytes_are_rejected():
    b = isoph.dumps(small_image())
    with pytest.raises(FormatError, match=r"1 unexpected byte\(s\) after the payload"):
        isoph.loads(b + b"\x00")


@pytest.mark.parametrize("compression", ["range", "lzma", "none"])
def test_single_byte_flips_are_detected(compression):
    vi = random_image(21, "yuv", n_contours=4)
    b = isoph.dumps(vi, compression=compression)
    rng = np.random.default_rng(1234)
    for _ in range(300):
        bad = bytearray(b)
        i = int(rng.integers(0, len(b)))
        bad[i] ^= int(rng.integers(1, 256))
        try:
            out = isoph.loads(bytes(bad))
        except FormatError:
            continue
        assert out.equals(vi), f"flip at {i} gave a different image"  # CRC-32: never reached


def refresh_header_crc(b: bytearray) -> bytes:
    hs = struct.unpack_from("<I", b, 12)[0]
    if 20 <= hs <= len(b):
        struct.pack_into("<I", b, hs - 4, zlib.crc32(bytes(b[: hs - 4])))
    return bytes(b)


def test_header_fuzz_with_valid_checksum():
    """Header bytes changed and the checksum fixed: a clean error or a valid image."""
    b = isoph.dumps(random_image(4, "yuv", n_contours=3), compression="zlib")
    hs = struct.unpack_from("<I", b, 12)[0]
    rng = np.random.default_rng(99)
    for _ in range(400):
        bad = bytearray(b)
        for _ in range(int(rng.integers(1, 3))):
            bad[int(rng.integers(8, hs - 4))] ^= int(rng.integers(1, 256))
        try:
            isoph.loads(refresh_header_crc(bad))
            isoph.read_info(refresh_header_crc(bad))
        except (FormatError, LimitError):
            pass


def test_payload_fuzz_with_valid_checksum():
    """Raw payload bytes changed and the payload CRC fixed: a clean error or a valid image."""
    vi = random_image(6, "yuv", n_contours=6)
    rng = np.random.default_rng(7)
    chans = [spec_channel(c) for c in vi.channels]
    raw = bytearray(b"".join(spec_sections(c) for c in chans))
    valid = 0
    for trial in range(400):
        bad = bytearray(raw)
        for _ in range(int(rng.integers(1, 4))):
            bad[int(rng.integers(0, len(bad)))] = int(rng.integers(0, 256))
        if trial % 4 == 0:  # also shorten or lengthen the raw payload
            bad = bad[: len(bad) - 1] if trial % 8 == 0 else bad + bytes([int(rng.integers(0, 256))])
        parts = [dict(c, sections=b"") for c in chans]
        parts[0]["sections"] = bytes(bad)
        f = spec_file(parts, width=vi.width, height=vi.height, colour=1)
        try:
            out = isoph.loads(f)
        except (FormatError, LimitError) as e:
            assert "malformed .isoph file (" not in str(e), e  # every problem has its own check
            continue
        valid += 1
        assert isoph.loads(isoph.dumps(out)).equals(out)  # whatever loads is a valid image
    assert valid < 400


# ---- lying fields, crafted with correct checksums -----------------------------------------


def range_coded(c: dict) -> bytes:
    return spec_range(c)[0]


LIES = {
    # name: (spec_file arguments, exception, message fragment)
    "bad magic": (None, FormatError, "bad magic"),
    "version 6": (dict(version=6), FormatError, "version 6"),
    "reserved": (dict(reserved=1), FormatError, "reserved"),
    "width 0": (dict(width=0), FormatError, "empty"),
    "width absurd": (dict(width=(1 << 20) + 1), LimitError, "exceeds"),
    "height absurd": (dict(height=2**32 - 1), LimitError, "exceeds"),
    "colour code": (dict(colour=7), FormatError, "colour code 7"),
    "depth": (dict(depth=12), FormatError, "depth 12"),
    "compression code": (dict(compression=9), FormatError, "compression code 9"),
    "range in version 1": (dict(compression=3, version=1), FormatError, "compression code 3 in version 1"),
    "quant": (dict(xy_quant=32), FormatError, "quanta 32/64"),
    "meta not json": (dict(meta=b"{nope"), FormatError, "meta is not valid"),
    "meta not utf8": (dict(meta=b'{"a":"\xff"}'), FormatError, "meta is not valid"),
    "meta not object": (dict(meta=b"[1,2]"), FormatError, "not an object"),
    "meta too deep": (dict(meta=b"[" * 30000 + b"]" * 30000), FormatError, "meta is not valid"),
    "meta too big": (dict(meta=b" " * 70000), LimitError, "meta"),
    "header extra": (dict(header_extra=b"\x00\x00"), FormatError, "unexpected byte(s)"),
    "file extra": (dict(file_extra=b"\x00"), FormatError, "unexpected byte(s) after the payload"),
    "payload size": (dict(payload_size=10**6), FormatError, "stored payload"),
    "raw size lies": (dict(raw_size=300), FormatError, "counts need"),
    "raw longer": (dict(compression=1, raw_extra=b"\x01", raw_size=RAW_SIZE), FormatError, "decompresses to more"),
    "raw shorter": ([one_channel(sections=spec_sections(one_channel())[:-1])], FormatError, "counts need"),
    "zlib raw shorter": (dict(compression=1, raw_size=RAW_SIZE + 1, raw_extra=b""), FormatError, "counts need"),
    "levels unsorted": ([one_channel(levels=[50.0, 40.0, 150.0])], FormatError, "strictly increasing"),
    "levels equal": ([one_channel(levels=[50.0, 50.0, 150.0])], FormatError, "strictly increasing"),
    "base band": ([one_channel(base_band=4)], FormatError, "base band 4"),
    "level NaN": ([one_channel(levels=[50.0, float("nan"), 150.0])], FormatError, "not finite"),
    "level inf": ([one_channel(levels=[50.0, 100.0, float("inf")])], FormatError, "not finite"),
    "too many levels": ([one_channel(n_levels=2000)], LimitError, "levels exceed"),
    "segments absurd": ([one_channel(n_segments=2**31)], LimitError, "segments exceed"),
    "caps absurd": ([one_channel(n_caps=2**30)], LimitError, "caps exceed"),
    "contours over segments": ([one_channel(n_contours=2**32 - 1)], FormatError, "only 3 segments"),
    "segments over payload": ([one_channel(n_segments=1000)], FormatError, "counts need"),
    "caps over payload": ([one_channel(n_caps=500)], FormatError, "counts need"),
    "segments miscounted": ([one_channel(nseg=[2, 2])], FormatError, "contours have 4 segments, the header declares 3"),
    "segments overflow": ([one_channel(nseg=[2**32, 1])], FormatError, "segments, the header declares"),
    "contours but no levels": ([one_channel(levels=[], contour_level=[0, 0], cap_band=[0])],
                               FormatError, "no levels"),
    "channel name": ([one_channel(name="X")], FormatError, "do not fit colour"),
    "grey with U": ([one_channel(), one_channel(name="U")], FormatError, "do not fit colour"),
    "level out of range": ([one_channel(contour_level=[0, 3])], FormatError, "contour level 3"),
    "level negative": ([one_channel(contour_level=[-1, 0])], FormatError, "contour level -1"),
    "parent out of range": ([one_channel(parent=[-1, 2])], FormatError, "parent 2"),
    "parent below -1": ([one_channel(parent=[-2, 0])], FormatError, "parent -2"),
    "parents cyclic": ([one_channel(parent=[1, 0])], FormatError, "cycle"),
    "cap band": ([one_channel(cap_band=[4])], FormatError, "cap band 4"),
    "cap contour high": ([one_channel(cap_contour=[2])], FormatError, "cap contour 2"),
    "cap contour low": ([one_channel(cap_contour=[-2])], FormatError, "cap contour -2"),
    "point beyond limit": ([one_channel(chains=[[(2**30 + 1, 0), (0, 0), (0, 0)], [(0, 0)] * 3])],
                           FormatError, "control point"),
    "sum beyond limit": ([one_channel(chains=[[(2**30 - 1, 0), (2**31 - 2, 0), (2**31 - 2, 0)],
                                              [(0, 0)] * 3])], FormatError, "control point"),
    "cap xy beyond limit": ([one_channel(cap_xy=[(0, -(2**30) - 1)])], FormatError, "cap position"),
    "cap value beyond limit": ([one_channel(cap_value=[2**30])], FormatError, "cap value"),
    "border padding": ([one_channel(sections=spec_sections(one_channel())[:-1] + b"\x0a")],
                       FormatError, "padding bits"),
    # tone curves (version 2)
    "tone one knot": ([one_channel(tone=[(0.0, 0.0)])], FormatError, "at least 2 knots"),
    "tone too many": ([one_channel(n_tone=5000)], LimitError, "tone knots exceed"),
    "tone count lies": ([one_channel(tone=[(0.0, 0.0), (1.0, 1.0)], n_tone=3)], FormatError, "header too short"),
    "tone NaN": ([one_channel(tone=[(0.0, 0.0), (float("nan"), 1.0)])], FormatError, "not finite"),
    "tone x not increasing": ([one_channel(tone=[(0.0, 0.0), (0.0, 1.0)])], FormatError, "strictly increasing"),
    "tone y decreasing": ([one_channel(tone=[(0.0, 5.0), (1.0, 4.0)])], FormatError, "monotone"),
    # grids and coded sizes
    "shift with zlib": ([one_channel(s_p=1)], FormatError, "must be 0 with compression"),
    "coded size with stored": ([one_channel(coded_size=3)], FormatError, "must be 0 with compression"),
    "point shift": (([one_channel(s_p=7)], 3), FormatError, "grid shifts 7/"),
    "anchor shift": (([one_channel(g=17)], 3), FormatError, "/17/"),
    "coded sizes lie": (([one_channel(coded_size=1)], 3), FormatError, "coded sizes add up"),
    # range-coded channels (version 3, compression 3): the plain-Python coder writes the lies
    "range level": (([one_channel(contour_level=[0, 3])], 3), FormatError, "contour level 3"),
    "range parent": (([one_channel(parent=[-1, 7])], 3), FormatError, "parent 7 (entry 1)"),
    "range cycle": (([one_channel(parent=[1, 0])], 3), FormatError, "cycle"),
    "range segments over": (([one_channel(nseg=[2, 2])], 3), FormatError, "more than 3 segments"),
    "range segments under": (([one_channel(nseg=[1, 1])], 3), FormatError, "contours have 2 segments"),
    "range cap contour": (([one_channel(cap_contour=[2])], 3), FormatError, "cap contour 2"),
    "range cap band": (([one_channel(cap_band=[4])], 3), FormatError, "cap band 4"),
    "range point": (([one_channel(chains=[[(2**30 + 64, 0), (0, 0), (0, 0)], [(0, 0)] * 3])], 3),
                    FormatError, "control point"),
    "range cap xy": (([one_channel(cap_xy=[(2**30, 0)])], 3), FormatError, "cap position"),
    "range cap value": (([one_channel(cap_value=[-(2**30)])], 3), FormatError, "cap value"),
    "range short": (([one_channel(coded=range_coded(one_channel())[:-1])], 3), FormatError, "ends early"),
    "range long": (([one_channel(coded=range_coded(one_channel()) + b"\x00")], 3), FormatError, "left over"),
}


@pytest.mark.parametrize("name", list(LIES))
def test_lying_fields_are_rejected(name):
    args, exc, fragment = LIES[name]
    if args is None:
        data = b"\x89ISOPX\r\n" + spec_file([one_channel()])[8:]
    elif isinstance(args, tuple):  # (channels, compression)
        data = spec_file(args[0], compression=args[1])
    elif isinstance(args, list):
        data = spec_file(args)
    else:
        data = spec_file([one_channel()], **args)
    with pytest.raises(exc) as info:
        isoph.loads(data)
    msg = str(info.value)
    assert "\n" not in msg and "malformed .isoph file (" not in msg
    if fragment:
        assert fragment in msg, msg


def test_valid_crafted_file_loads():
    """The crafting helper itself makes valid files when nothing lies."""
    vi = isoph.loads(spec_file([one_channel()]))
    ch = vi.channel("Y")
    assert ch.n_contours == 2 and ch.n_segments == 3 and list(ch.parent) == [-1, 0]
    assert list(ch.border) == [False, True, False]
    assert ch.cap_value[0] == 170.0 and tuple(ch.cap_xy[0]) == (500 / 64, 500 / 64)
    assert np.array_equal(ch.chain(1), np.array([[5, 5], [10, 5], [15, 5], [5, 5]], float))


def test_big_cycle_among_many_contours():
    c = one_channel(contour_level=[0] * 6, chains=[[(0, 0), (64, 0), (0, 64)]] * 6,
                    parent=[-1, 3, 1, 4, 2, 0], border=[False] * 6)
    with pytest.raises(FormatError, match="cycle"):
        isoph.loads(spec_file([c]))


LZMA_FILTERS = [{"id": lzma.FILTER_LZMA2, "preset": 6, "dict_size": 1 << 23}]


@pytest.mark.parametrize("code,payload", [
    (1, lambda raw: zlib.compress(raw)[:-4]),  # all the data, but no end (Adler-32 cut off)
    (1, lambda raw: zlib.compress(raw) + b"\x00"),  # data after the end of the stream
    (1, lambda raw: zlib.compress(raw)[:-12]),  # cut inside the data
    (1, lambda raw: b"\x78\x9c" + bytes(40)),  # not a deflate stream
    (2, lambda raw: lzma.compress(raw, format=lzma.FORMAT_RAW, filters=LZMA_FILTERS)[:-1]),  # no end marker
    (2, lambda raw: lzma.compress(raw, format=lzma.FORMAT_RAW, filters=LZMA_FILTERS) + b"\x00"),
    (2, lambda raw: bytes(range(1, 60))),
])
def test_bad_compressed_streams(code, payload):
    with pytest.raises(FormatError, match="decompress|does not end"):
        isoph.loads(spec_file([one_channel()], compression=code, payload=payload))


def test_expansion_limit():
    """A tiny payload may not declare a huge raw size (decompression bombs)."""
    c = one_channel(n_segments=100_000, n_caps=0, sections=b"")
    data = spec_file([c], compression=1, raw_size=10 * 2 + 24 * 100_000 + 100_000 // 8)  # what the counts need
    with pytest.raises(FormatError, match="64:1"):
        isoph.loads(data)
    c = one_channel(n_segments=100_000, n_caps=0, coded=b"\x00" * 8)  # range coding: the same bound
    data = spec_file([c], compression=3, raw_size=10 * 2 + 24 * 100_000 + 100_000 // 8)
    with pytest.raises(FormatError, match="64:1"):
        isoph.loads(data)


# ---- the writer refuses what the data model forbids ---------------------------------------


def broken(field, value, seed=2):
    vi = random_image(seed, "grey", n_contours=3, n_levels=5)
    ch = vi.channels[0]
    fields = {f: getattr(ch, f) for f in ("name", "levels", "contour_level", "offsets", "points", "border",
                                          "parent", "cap_band", "cap_contour", "cap_xy", "cap_value",
                                          "base_band", "tone")}
    fields[field] = value(fields) if callable(value) else value
    return VectorImage(vi.width, vi.height, "grey", (Channel(**fields),))


def open_chain(f):
    p = f["points"].copy()
    p[f["offsets"][1] - 1] += 1
    return p


@pytest.mark.parametrize("vi,exc", [
    (broken("points", open_chain), ValueError),
    (broken("parent", lambda f: np.array([1, 2, 0], np.int32)), ValueError),
    (broken("parent", lambda f: np.array([-1, 1, 0], np.int32)), ValueError),  # its own parent
    (broken("levels", lambda f: f["levels"][::-1].copy()), ValueError),
    (broken("offsets", lambda f: f["offsets"] + np.r_[0, 1, 1, 0]), ValueError),
    (broken("border", lambda f: f["border"][:-1]), ValueError),
    (broken("points", lambda f: f["points"] * np.nan), ValueError),
    (broken("points", lambda f: f["points"] + 1e8), LimitError),
    (broken("base_band", 6), ValueError),  # 5 levels: bands 0 .. 5
    (broken("tone", np.array([[0.0, 1.0]])), ValueError),  # one knot
    (broken("tone", np.array([[0.0, 1.0], [2.0, 0.5]])), ValueError),  # decreasing
    (broken("tone", np.array([[0.0, 1.0], [0.0, 2.0]])), ValueError),  # x repeated
    (broken("tone", np.array([0.0, 1.0, 2.0, 3.0])), ValueError),  # not (K, 2)
    (broken("tone", np.array([[0.0, 1.0], [np.inf, 2.0]])), ValueError),
    (broken("tone", np.c_[np.arange(5000.0), np.arange(5000.0)]), LimitError),
    (VectorImage(0, 5, "grey", (Channel.empty("Y", []),)), ValueError),
    (VectorImage(5, 5, "yuv", (Channel.empty("Y", []),)), ValueError),
    (VectorImage(5, 5, "grey", (Channel.empty("Y", []),), meta={"x": object()}), ValueError),
    (VectorImage(5, 5, "grey", (Channel.empty("Y", []),), meta={"x": "y" * 70000}), LimitError),
])
def test_writer_rejects_invalid_images(vi, exc):
    with pytest.raises(exc):
        isoph.dumps(vi)


def test_meta_is_json():
    vi = VectorImage(5, 5, "grey", (Channel.empty("Y", [1.0]),),
                     meta={"b": (1, 2), "a": np.float32(0.5), "c": np.arange(3), 4: "four"})
    assert isoph.loads(isoph.dumps(vi)).meta == {"a": 0.5, "b": [1, 2], "c": [0, 1, 2], "4": "four"}


# ---- files and read_info --------------------------------------------------------------------


def test_save_load_and_read_info(tmp_path):
    vi = random_image(13, "yuv+alpha")
    path = tmp_path / "a.isoph"
    isoph.save(vi, path)
    assert isoph.load(path).equals(vi)
    assert isoph.load(str(path)).equals(vi)
    for source in (path, str(path), path.read_bytes()):
        info = isoph.read_info(source)
        assert info["format_version"] == 5 and info["compression"] == "range"
        assert (info["width"], info["height"], info["colour"]) == (vi.width, vi.height, "yuv")
        assert info["source_depth"] == vi.source_depth
        assert info["bytes"] == path.stat().st_size
        assert info["meta"] == vi.meta
        assert [c["name"] for c in info["channels"]] == ["Y", "U", "V", "A"]
        for c, ch in zip(info["channels"], vi.channels):
            assert c["levels"] == list(ch.levels) and c["base_band"] == ch.base_band
            assert (c["contours"], c["segments"], c["caps"]) == (
                ch.n_contours, ch.n_segments, ch.cap_band.shape[0])
            assert c["tone_knots"] == (0 if ch.tone is None else ch.tone.shape[0])
    assert not [p for p in tmp_path.iterdir() if p.name != "a.isoph"]  # no temporary left


def test_read_info_does_not_read_the_payload(tmp_path):
    b = bytearray(isoph.dumps(random_image(14, "grey")))
    hs = struct.unpack_from("<I", b, 12)[0]
    b[hs:] = bytes(len(b) - hs)  # zero the payload, same length
    assert isoph.read_info(bytes(b))["width"] > 0
    with pytest.raises(FormatError, match="payload checksum"):
        isoph.loads(bytes(b))


def test_load_errors_name_the_file(tmp_path):
    with pytest.raises((FormatError, InputError), match="missing.isoph"):
        isoph.load(tmp_path / "missing.isoph")
    with pytest.raises(FormatError):
        isoph.load(tmp_path)  # a folder
    with pytest.raises(FormatError):
        isoph.read_info(tmp_path / "missing.isoph")
    p = tmp_path / "cut.isoph"
    p.write_bytes(isoph.dumps(small_image())[:-3])
    with pytest.raises(FormatError, match=r"cut\.isoph: truncated"):
        isoph.load(p)
    with pytest.raises(FormatError, match=r"cut\.isoph: truncated"):
        isoph.read_info(p)
    p.write_bytes(b"GIF89a" + bytes(100))
    with pytest.raises(FormatError, match="bad magic"):
        isoph.load(p)


def test_errors_are_isophote_errors():
    assert issubclass(FormatError, IsophoteError) and issubclass(LimitError, IsophoteError)


def test_package_doors(tmp_path):
    import isophote

    vi = random_image(15, "grey")
    vi.save(tmp_path / "b.isoph")
    assert isophote.load(tmp_path / "b.isoph").equals(vi)


# ---- compactness fingerprint -----------------------------------------------------------------


def smooth_contour_set(seed=0, n=400, w=640, h=480):
    """Photograph-like geometry: smooth closed curves of 4-12 px G1 segments whose handle
    lengths vary as a least-squares fit's do, on the 1/64 grid."""
    rng = np.random.default_rng(seed)
    chains = []
    for _ in range(n):
        r0 = rng.uniform(3, 60)
        cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        a = rng.standard_normal(6) * r0 * 0.15 / np.arange(1, 7)
        ph = rng.uniform(0, 2 * np.pi, 6)
        m = max(2, int(2 * np.pi * r0 / rng.uniform(4, 12)))
        t = np.linspace(0, 2 * np.pi, m, endpoint=False)
        r = r0 + sum(a[k] * np.cos((k + 1) * t + ph[k]) for k in range(6))
        p = np.c_[cx + r * np.cos(t), cy + r * np.sin(t)]
        tan = (np.roll(p, -1, 0) - np.roll(p, 1, 0)) / 6
        pts = [p[0]]
        for i in range(m):
            j = (i + 1) % m
            pts += [p[i] + tan[i] * rng.uniform(0.7, 1.3), p[j] - tan[j] * rng.uniform(0.7, 1.3), p[j]]
        ch = np.rint(np.array(pts) * Q) / Q
        ch[-1] = ch[0]
        chains.append(ch)
    c = len(chains)
    offsets = np.r_[0, np.cumsum([len(x) for x in chains])].astype(np.int64)
    s = int((offsets[-1] - c) // 3)
    k = c // 4
    channel = Channel("Y", np.arange(7.5, 250, 10.0), rng.integers(0, 25, c).astype(np.int32), offsets,
                      np.concatenate(chains), rng.random(s) < 0.05, random_tree(rng, c),
                      rng.integers(0, 26, k).astype(np.int32), rng.integers(-1, c, k).astype(np.int32),
                      np.rint(rng.uniform(0, [w, h], (k, 2)) * Q) / Q, np.rint(rng.uniform(0, 255, k) * Q) / Q)
    return VectorImage(w, h, "grey", (channel,))


def test_bytes_per_segment_fingerprint():
    vi = smooth_contour_set()
    s = vi.channels[0].n_segments
    per_segment = {c: len(isoph.dumps(vi, compression=c)) / s for c in ("range", "zlib", "lzma", "none")}
    # Measured 6.42 (range, the default) / 7.28 (zlib) / 7.06 (lzma) / 24.7 (stored): this
    # synthetic point data is near its entropy (random handle lengths, the low bits of
    # fitted coordinates are noise, no anchor grid), so a coding regression shows up as a
    # jump. Stored is exactly 24 B/segment + contours + caps.
    assert per_segment["range"] < 6.6 and per_segment["zlib"] < 7.6, per_segment
    assert per_segment["range"] < per_segment["lzma"] < per_segment["zlib"] < per_segment["none"], per_segment


def test_encoder_output_round_trips_exactly():
    """The encoder keeps its coordinates on the 1/64 grids, so its images come back equal."""
    import isophote

    yy, xx = np.mgrid[0:40, 0:48]
    rgb = np.stack([xx * 5.0, 255 - yy * 6.0, 128 + 100 * ((xx - 24) ** 2 + (yy - 20) ** 2 < 100)], -1)
    vi = isophote.encode(np.clip(rgb, 0, 255))
    assert sum(ch.n_segments for ch in vi.channels) > 0
    b = isoph.dumps(vi)
    assert isoph.loads(b).equals(vi)


def test_encoder_output_is_range_coded_compactly():
    """On the encoder's output (anchors on the sample grid, caps on the half-pixel grid) range
    coding is much smaller than the column layout under zlib: measured 0.80 of it here, 0.73
    on the corpus photographs (benchmarks/results/coding.md)."""
    from isophote.encoder import QUANT

    vi = encoded_image()
    info = isoph.read_info(isoph.dumps(vi))
    assert all(c["coded_bytes"] > 0 and c["point_grid"] == QUANT for c in info["channels"])
    ratio = len(isoph.dumps(vi)) / len(isoph.dumps(vi, compression="zlib"))
    assert ratio < 0.85, ratio


# ---- versions 2 and 3: tone curves, grids, range coding; version 1 and 2 files ---------------


def test_tone_round_trips_and_none_stays_none():
    vi = random_image(40, "yuv", tone=False)
    tone = np.array([[0.0, 0.0], [100.5, 80.25], [100.75, 80.25], [255.0, 255.0]])
    chans = (replace(vi.channels[0], tone=tone),) + vi.channels[1:]
    vi = VectorImage(vi.width, vi.height, vi.colour, chans, vi.source_depth)
    for compression in ("range", "zlib", "lzma", "none"):
        out = isoph.loads(isoph.dumps(vi, compression=compression))
        assert out.equals(vi)
        assert np.array_equal(out.channels[0].tone, tone) and out.channels[0].tone is not tone
        assert out.channels[1].tone is None and out.channels[2].tone is None
    info = isoph.read_info(isoph.dumps(vi))
    assert [c["tone_knots"] for c in info["channels"]] == [4, 0, 0]
    big = np.c_[np.arange(isoph.MAX_TONE_KNOTS) * 0.0625, np.arange(isoph.MAX_TONE_KNOTS) // 3]
    vi2 = VectorImage(vi.width, vi.height, "grey", (replace(vi.channels[0], name="Y", tone=big),))
    assert isoph.loads(isoph.dumps(vi2)).equals(vi2)


def test_cap_ramp_round_trips_and_older_versions_have_the_default():
    from isophote.model import CAP_RAMP, DOME

    vi = random_image(42, "yuv", tone=False)
    chans = (replace(vi.channels[0], cap_ramp=DOME), replace(vi.channels[1], cap_ramp=3.25)) + vi.channels[2:]
    vi = VectorImage(vi.width, vi.height, vi.colour, chans, vi.source_depth)
    for compression in ("range", "zlib", "lzma", "none"):
        out = isoph.loads(isoph.dumps(vi, compression=compression))
        assert out.equals(vi) and [c.cap_ramp for c in out.channels] == [DOME, 3.25, CAP_RAMP]
    assert [c["cap_ramp"] for c in isoph.read_info(isoph.dumps(vi))["channels"]] == ["dome", 3.25, 2.0]
    # a version 2 file has no cap_ramp: every channel has the default
    ch = one_channel()
    assert isoph.loads(spec_file([ch], version=2)).channels[0].cap_ramp == CAP_RAMP
    assert isoph.loads(spec_file([dict(ch, cap_ramp=float("inf"))])).channels[0].cap_ramp == DOME
    for bad in (0.0, -1.0, float("nan"), float("-inf")):
        with pytest.raises(FormatError, match="cap ramp"):
            isoph.loads(spec_file([dict(ch, cap_ramp=bad)]))
        with pytest.raises(ValueError, match="cap ramp"):  # the writer's error for a bad image
            isoph.dumps(VectorImage(vi.width, vi.height, "grey", (replace(vi.channels[0], name="Y", cap_ramp=bad),)))
    with pytest.raises(ValueError, match="cap_ramp"):
        isoph.dumps(VectorImage(vi.width, vi.height, "grey", (replace(vi.channels[0], name="Y", cap_ramp="x"),)))


def test_coarse_grids_are_found_and_cost_less():
    """Points on a 1/16 grid, caps on a 1/2 grid and values on a 1/4 grid: the writer codes
    them on those grids (exactly), in fewer bytes than the same on the 1/64 grid."""
    vi = random_image(41, "grey", n_contours=12)
    ch = vi.channels[0]
    coarse = replace(ch, points=np.round(ch.points * 16) / 16, cap_xy=np.round(ch.cap_xy * 2) / 2,
                     cap_value=np.round(ch.cap_value * 4) / 4)
    fine = replace(coarse, points=coarse.points + 1 / 64)  # every point off the 1/16 grid, chains closed
    sizes = {}
    for name, c in (("coarse", coarse), ("fine", fine)):
        v = VectorImage(vi.width, vi.height, "grey", (c,))
        b = isoph.dumps(v)
        assert isoph.loads(b).equals(v)
        sizes[name] = len(b)
        grid = isoph.read_info(b)["channels"][0]["point_grid"]
        assert grid == (16 if name == "coarse" else 64)
    assert sizes["coarse"] < sizes["fine"]


def test_version_1_files_are_read():
    """Files of format version 1 (isophote 0.1) load: the spec writer's, in every compression
    it had, and a file written by version 1's own writer."""
    vi = random_image(42, "yuv", tone=False)
    meta = json.dumps(vi.meta, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode()
    for code in (0, 1, 2):
        data = spec_file([spec_channel(c) for c in vi.channels], width=vi.width, height=vi.height,
                         colour=1, depth=vi.source_depth, compression=code, meta=meta, version=1)
        out = isoph.loads(data)
        assert out.equals(vi) and out.meta == vi.meta and isoph.read_info(data)["format_version"] == 1
    old = bytes.fromhex(V1_FILE)
    out = isoph.loads(old)
    assert out.equals(random_image(3, "yuv", tone=False, n_contours=2, n_levels=3))
    assert isoph.read_info(old)["format_version"] == 1
    assert isoph.read_info(isoph.dumps(out))["format_version"] == 5


# random_image(3, "yuv", n_contours=2, n_levels=3) as version 1's writer (isophote 0.1) wrote it
V1_FILE = (
    "8949534f50480d0a01000000d0000000a2000000120000000108030140004000a0010000000000002803000000000000"
    "31b1b013190000007b226e6f7465223a22636166c3a9222c2273656564223a337d590300020002000000070000000200"
    "00003a58c7bcfa8509c0e5d38916fec42940c8d43b53e8a138405503000000020000000e0000000200000026f6c09bef"
    "311e407eeff2ccf6bb2140ab4ee8f517693040560300030002000000070000000000000018aa91cde213314093e3476d"
    "ac223c406092cfce41bf434076e35247789c6361666060026230608250262def55f6ae9ccee1162ac72968face30eccd"
    "ac5fa26177abb36356872f706efc29b54668e7841b697baf9cb110106164e5e067e1e0656267e4e16510e117e7e7e166"
    "62e562e162e1900612ac6ccc4c2cdcaccc3c0c3400cc20b73342d842ea5396f032fb19c1e438a605b683680990a7d8d8"
    "503d1830657596f443f7c567a6342acfceb2bfce32fb32e399ff59f3d3f4e543b79473274f649cb2a0377485559e86c3"
    "2bc14dbd4bac3ee4af78cebd7acec55dae3baedbf5304b3f987d556a2fabe495d57bbf1799fa1975280599a97132f1b0"
    "b27031327072b1f13233093230723270323332313032b07233b2b033b2b3b130304b3272094bf1310005818889898501"
    "ac00c86165023a8e8509a801084131c2c4c4ca448b40a30500a51f166844242b95bcd136115486c94d288bac04330440"
    "de6146f3d3a7924c8dc2aa560d0bf79eec7937677ebd37c3c8f856fe399ffc73cb0373573cdcbca4b1f5b222270f47f2"
    "92202e7e2631161e36267e2636162e26666e660160483132d82bb0b2b2b070b3b1720039aca2a000a505000074eb5ddc"
)


def fingerprint(vi: VectorImage) -> str:
    """A hash of every decoded array (points, hierarchy, caps) of every channel."""
    import hashlib

    h = hashlib.sha256()
    for c in vi.channels:
        for a in (c.contour_level, c.offsets, c.points, c.border, c.parent, c.cap_band, c.cap_contour,
                  c.cap_xy, c.cap_value):
            h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def spec_range_round_trip(seed, version):
    """A random image through the spec writer's range-coded file of ``version``: it loads
    back equal. Returns (loaded image, file)."""
    vi = random_image(seed, "yuv+alpha")
    meta = json.dumps(vi.meta, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode()
    data = spec_file([spec_channel(c) for c in vi.channels], width=vi.width, height=vi.height,
                     colour=1, depth=vi.source_depth, compression=3, meta=meta, version=version)
    out = isoph.loads(data)
    assert out.equals(vi) and isoph.read_info(data)["format_version"] == version
    return out, data


def test_version_2_files_are_read():
    """Range-coded files of format version 2 load: the spec writer's (version 2's layout of
    the coded channels), and files written by version 2's own writer, one with fitted
    contours on an anchor grid."""
    for seed in (43, 44):
        out, data = spec_range_round_trip(seed, 2)
        assert isoph.dumps(out) != data  # written again as version 5: another layout
    old = bytes.fromhex(V2_FILE)
    assert isoph.read_info(old)["format_version"] == 2 and isoph.read_info(old)["compression"] == "range"
    assert isoph.loads(old).equals(random_image(3, "yuv", tone=False, n_contours=2, n_levels=3))
    old = bytes.fromhex(V2_FITTED_FILE)
    assert isoph.read_info(old)["format_version"] == 2
    assert isoph_header.parse_header(old, len(old)).channels[0].g > 0  # the anchor grid is on
    out = isoph.loads(old)
    assert fingerprint(out) == V2_FITTED_FINGERPRINT
    again = isoph.dumps(out)
    assert isoph.read_info(again)["format_version"] == 5 and isoph.loads(again).equals(out)


def test_version_3_files_are_read():
    """Range-coded files of format version 3 load: the spec writer's (version 3's layout,
    every handle coded on the 1/64 grid) and a file of fitted contours written by version
    3's own writer; written again they become version 5."""
    for seed in (45, 46):
        spec_range_round_trip(seed, 3)
    old = bytes.fromhex(V3_FILE)
    assert isoph.read_info(old)["format_version"] == 3
    out = isoph.loads(old)
    assert fingerprint(out) == V3_FINGERPRINT
    again = isoph.dumps(out)
    assert isoph.read_info(again)["format_version"] == 5 and isoph.loads(again).equals(out)


def test_version_4_files_are_read():
    """Range-coded files of format version 4 (one stream a channel, no parts) load: the spec
    writer's and a file of fitted contours written by version 4's own writer (isophote at
    ca64fb9); written again they become version 5, the same image."""
    for seed in (47, 48):
        spec_range_round_trip(seed, 4)
    old = bytes.fromhex(V4_FILE)
    assert isoph.read_info(old)["format_version"] == 4
    out = isoph.loads(old)
    assert sum(c.n_contours for c in out.channels) > 10 and fingerprint(out) == V4_FINGERPRINT
    again = isoph.dumps(out)
    assert isoph.read_info(again)["format_version"] == 5 and isoph.loads(again).equals(out)


# 128 + 60 sin(x / 2) cos(y / 3) + N(0, 4) (seed 3) on 12 x 14, encoded (paper preset) and
# written by version 4's writer, meta dropped
V4_FILE = (
    "8949534f50480d0a040000002b0100000c0000000e00000000080103400040008e02000000000000440e000000000000"
    "2a2335150000000059190007001600000089000000070000000000000505048e020000000000000000000000001e4000"
    "000000008031400000000000803b400000000000c042400000000000c047400000000000c04c400000000000e0504000"
    "000000006053400000000000e0554000000000006058400000000000e05a400000000000605d400000000000e05f4000"
    "0000000030614000000000007062400000000000b063400000000000f064400000000000306640000000000070674000"
    "00000000b068400000000000f069400000000000306b400000000000706c400000000000b06d400000000000f06e4000"
    "000000000000401d8b47e09c1b51a2f94960ebb5ec19f1fa16620736625bfa70520ffe0d4d3d1b9da846a273112f597a"
    "88bdc73f8c400ce0cfe0e1ff063c0c76bb3c9b771ec31a20b8fa29448361328d1b3798ae75e66570f7754d9ae19de7aa"
    "041067cdab7c6ceea6b45ff6865d711d42edf0e8543eedbcc504d78739c0d532614517839f4a1d23e75f28a460558abb"
    "dd772457c9b121741eaf7409f281a82e0d926f23f9fdd2bb6386834cd02aae704d381f49c2212ebc1b486c578c605f8e"
    "1e3ca2f559a1d7559ae9a342cd0c50850b5d4c328dd1f839d6944d5809cf454a38283174a625755557977d5d7e1000aa"
    "e29e4b9c085529c5369bed558ee36170a65d5e0f882411df6d1a86a41a48b4dc4b5866187c52ebf463a4e06c6b6cfebf"
    "77a4194a43fe3e35953a52fb1f7419d423595f2449643f4f855defbf30dcd1f894c8eafacd485a3cf0adc86c2b2f4ccd"
    "186f5973b669c04f78a404430022a939e91d7f0a593dd842b5a3b9588fd0e7e6557d3fead7ac5a4e0dc9aa0a7268b750"
    "80bd9759c45f90bb7bf0b8ee9194a8394029300791290c468523bae0b9cdfbd668ed89327582ac148b199ca1ae7752ac"
    "f778a952febfa95c3b041e437e3f4907756b66d938357029517101e39bedfd9455e1130c4b4a6c943ec2ae7eb66c2272"
    "8b2f5596066d26b55ae4361d58ba123e74c11753a3e67e7a129e4a30eb4497d38aa22bf21d7366fc307679de78670258"
    "0d5eef33edb898d0248acd5eb73463ee2f165e21bccc9245bb55ea7806f79411f7e2c7e982926e68b4b0d3c386aa7165"
    "9780a35285872f7963975d0d7c2284c7b1786057be31ed25faa5ff19d9b0361f8d7fe6a219f126e2d0d0fcdd8a225192"
    "1a4eae4cdf14f985d060916c8a5321287d642287e00c488901810c006d319d7d1bf5c76bdf6f0c8680"
)
V4_FINGERPRINT = "8d8740622ad50b30f83f70568941a50e9dce6ae2b3be926517721e0cfc7678e3"


# a 12 x 14 sine pattern with noise, encoded (balanced) and written by version 3's writer
V3_FILE = (
    "8949534f50480d0a03000000bb0100000e0000000c0000000008010340004000b3030000000000003d13000000000000"
    "3d671b4a00000000592b00090024000000b800000007000000000000070500b303000000000000000000000000f83f00"
    "00000000001e400000000000002b40000000000080334000000000008039400000000000803f400000000000c0424000"
    "00000000c045400000000000c048400000000000c04b400000000000c04e400000000000e05040000000000060524000"
    "00000000e0534000000000006055400000000000e0564000000000006058400000000000e059400000000000605b4000"
    "00000000e05c400000000000605e400000000000e05f400000000000b060400000000000706140000000000030624000"
    "00000000f062400000000000b06340000000000070644000000000003065400000000000f065400000000000b0664000"
    "0000000070674000000000003068400000000000f068400000000000b069400000000000706a400000000000306b4000"
    "00000000f06b400000000000b06c400000000000706d400000000000306e400000000000f06e400000000000b06f4000"
    "00000000000040f4f429339c9a51a3b18f2a7b9b4d019bc2848be48bdfcae13770c1910f83cfb0d874a87d0a9b1711c5"
    "00bdd330e4bd94c9aedf4dc27f571d9f1b09c5bf531d14cf9c7913a77fb956bef411a6139d1d319e833244aaeeaf38dc"
    "758f0078e393ff181c55c318b3b0b7ee730be30fb574f52655109e721f47ab4c590668aaca3ee6dbe4d033e2309fb3fc"
    "42072a03f7c094eb105e56d02f15cd9f2ebe102c356f9b7b49a527e1c0fc5940ce6ae4a68914d5e8ccb33d52699d8de5"
    "3cae9803155f73dc225100d7a8ffd4ff35d24766a2ab3a90263b79a4fc7add224c27a314502588601d290d9167796a2e"
    "9bd715da7090d3d71e786595ab5ef5724605bbc089db35e18db9f20e7b75e8b9a5ea681eadbdd6e137a39c76c097f2ed"
    "e3bd8a5febb215e3ba98603ddce8dc77095c23bb9da1edac8362023aba719a0adc8bdb5eccd910f5f3f40b32c6f3b2a5"
    "7e2b0f58380fbed74ff0d5c0a3d24333518283dad686099548c6bbcbf54bc89609598ce92a8f6e485eabc7bc07ab0212"
    "a5b4fd44a7d3af2b06e0bd0898557933e19d5944e973fe15c23a9b861986dbb0ed39bf939599ec4740c1c3287fd5dc47"
    "75c9a2c5ee5aff589e4fcad8c53f1f0a610dd4788a520061a0db0a925b29deefc35f2a4da59b83e6d0a6c6f758aa1205"
    "cedd67d088680bbaa716a4171f6a2a290b145921f58f5929baa169dbd17efff702fec61e58412854da4dca74b33922aa"
    "0db33ca108be0238967432550a5e724e36ed9f20ed0cfe534d34edcdda5252c402e0b03fa90024609dea2a36dc46c497"
    "a1baad15f48757e491ffea068963525050110f0608768da7a4c73e63064ccbfb1da1922822b02c1cbd83b57e857292e9"
    "cbc42b5c3aaa4c9b6f00ed746ef2d3da6eebc31f16073a2e24425135f734916391b8b3d16fd6db238f5189f4a2cbe28d"
    "af478927b84a699863e380776559df97d6095b40d7d2548b3f929d25bf1c9f3ac6209cbfeee662cdccf3e32e40d9748a"
    "335bbf373cfaa9032b961222e32487f43b9228d8be8d1308655f4f2703a3bd0b64dd15888479f0938ccde340c815f230"
    "4179cd83fa2fc518e5a6f61c79482dea66a5bcc5223c532630bb897bbae49932895d9a74988577c13d347dd024e69b78"
    "0fb554076775e99c7fa570a989060634e512114de37567510d27a676f64833861d6f1b3e7efae4a89e878c4fa76f9a75"
    "76b073248ceb9a278a2dc2247e3bf1602a597c2a99bdf394dbfbd2c37edaa8ac0fe7350637d1a4e4d1d069b5d49072cb"
    "a3a9cd5f404d7e8bcdaf63860d726551eeedec2c10d1c5ac728b00250f0fc34ff445d67f86b4bd34cb4f0037bc00"
)
V3_FINGERPRINT = "3df7e0535ab4839ff540939333c72b9961ffc5e3250fcf437bd4912d2b4dba5e"


# random_image(3, "yuv", tone=False, n_contours=2, n_levels=3) as version 2's writer wrote it
V2_FILE = (
    "8949534f50480d0a02000000fa000000a2000000120000000108030340004000c3010000000000002803000000000000"
    "117f0b6d190000007b226e6f7465223a22636166c3a9222c2273656564223a337d590300020002000000070000000200"
    "000000000000000084000000000000003a58c7bcfa8509c0e5d38916fec42940c8d43b53e8a138405503000000020000"
    "000e00000002000000000000000100d50000000000000026f6c09bef311e407eeff2ccf6bb2140ab4ee8f51769304056"
    "030003000200000007000000000000000000000200006a0000000000000018aa91cde213314093e3476dac223c406092"
    "cfce41bf43401e82eeae9565a4087840f2208e5e594aed9c14f96ea40a3d486bda6e650562aaaf43211d8d82535a2d71"
    "afc3ab3d103291d95d11310b3e3c441dc702a9147ad75e1942aad01effe152ee77fe4aec5085a2e748794b04b6960ab4"
    "c87b093ce2c455157517bcce0fae8f880b0c7eede3ed9c301c37d0aeccf9affe19e2f807b0d8e45792cd80cc00008dc8"
    "9ee9d091c576a27371674e2f0d8dbccbf7f19b28d12774714ebabebbaabdf6b41a76f7143f88cdb1522066ea656b1167"
    "b7b55d525e3dfc9de0417eb52c9d997e24af836ca55294f656a45be9c23af6d50b418db82d68cd7f841bee3a78fa9980"
    "bd59da3d98d556d3cc8799aa75fa3048546dde9e3d3b33aefac005145434616a2ba6cab9bc41f6d4fa0516cff6b0122f"
    "0ef2a409e0335ddcdc7f4d82d8ccd486fe679bfbd5807d93ca91447f5ee1c4e558d1eee4f9dd69bd6c82e8643db8523b"
    "c437cdedca5bc5dffd4a6cf42e2dc27f000000918a5db3cb72d2c5e73205055cd4d258cf6343d7891527164e8f60cc17"
    "5165d2f24e5acc8a4c9e934a34e7b4a985dbe295e0eb36857ff33e08ee61de4f2333cfafce1d8db05a0eed5bc551beb3"
    "a6c4013b1466f171c6b913c917592e6c36283de3795269994ec744b1d3"
)

# A 16 x 14 grey ramp with a disc, encoded (paper preset) and written by version 2's writer:
# 23 contours, 214 segments, anchor grid on; and the fingerprint of what it decodes to.
V2_FITTED_FILE = (
    "8949534f50480d0a0200000023010000100000000e00000000080103400040001d040000000000005915000000000000"
    "baff5f4900000000591900000017000000d6000000040000000000000505001d040000000000000000000000001e4000"
    "000000008031400000000000803b400000000000c042400000000000c047400000000000c04c400000000000e0504000"
    "000000006053400000000000e0554000000000006058400000000000e05a400000000000605d400000000000e05f4000"
    "0000000030614000000000007062400000000000b063400000000000f064400000000000306640000000000070674000"
    "00000000b068400000000000f069400000000000306b400000000000706c400000000000b06d400000000000f06e404b"
    "af96718d4891d8a4aa12d5063d5253a35aabd3569efa8d3928c21e81a875c4bde319943b7fa8e10a627c04b258ef88a5"
    "15c644aa2d484f2a29de2bc9171e27e9f1f8d0dd5d4514b997e3c6c392cfd15cc705bad9155a10495833d1e97765f821"
    "e43cbbdec6509af88ef783a8523214e5e1d61e83c5367e4a8308a8051beed57c1bf3650305df61b67571a1557f7a3c94"
    "09c28169d370ab3067793b66cdf6491d854f60f7c5325e7899a61151ca3f1faf95f8e9c95f49e72657caf5c24202d5c9"
    "94341572c11e2e4b697f852157e51982ece70fd3b13cbf36eec95c5ddba91827f81955a2c1d9a801588098230155ad17"
    "19d14e243b3480de2ea44b464625c00f32156a9f900babaf0f3a58bcdfa5d8770f1d35b4ddd34163ee6c5d5bb417ecf3"
    "4e299c689de90c547877a9da9f28ecac4ba5bf84c3f66ead9130ba4314ff111c8a4f00fdfccc58986413a4a6130eb107"
    "af2df32aba4b128ddd284deb0c06a13805e7931aa6401c2483d13710ea11cdcfc9c8ed00bc8b6e65fd744fa77f4a60f6"
    "318dd6a8fbcc3997931e405afcebce20543ab5234db8e915354ebf4330e9fd9ae62881404be23bd12d41e718e5de9186"
    "d19ac95e945f20ea19cb7390e0e23106d25cab7de367e0c39c55a68de3662356ad7fc0d84f5a403ebcc6341366247ce1"
    "e6675f3ee2687a45c97431c92d14da9bb5c64ad388c728382b64d192c94532bb871d73fbfa0e24766787047271cbeeeb"
    "81b1339b590c3afb58e956c201798a97953b47ea1f1c1361925efcb38b54070ac0e8d18e533f6b78e9c5be1935a09ca3"
    "a6b169de5478bad95422737f54e7b83fa7d0090154f6284484136372a17572a2f7770d4004046a4bce9cb2d014627fa1"
    "44fa800be0ecc61e98b25fc1236c52950e828645332026772006827161339ee043055942012b7360367872872537aa49"
    "a8ac5d3465189ed23b8a9c408b6e019007e1afc2cfc66368de6305bd3ac6f20f46364ca349a38e4221ed5eedd7246f8d"
    "a8d4306c47beed72c11ec5fada6b4be34eeed60386ae311e91948184a0516ca25d9b2476e4b42e4e55851f49be80be1d"
    "a1c286463363ca542dc368e29dbc4ba7857f865cfafb4b90ba2828b4c7c8e9aa849454ce0a43ede12b657c76da005fe1"
    "57e3be35bf2488cdbe864ddc160a4f1b5d680295c1aea2d1edc1191f8e81a495d28c137df6e3dc57befae238cc301636"
    "7a9cfea3c1f2cb89a86a7d4f58f46380d3df91dcd92307dc7e49ecd7431166a173b5546ef6c5387e137e84a597581648"
    "41a0b4c2d1423078779be259d7be7d3bc9c62ae3c94b100753bbdf3e5bf7bb1b05f1152bfc04537eda9fa2071e55d00f"
    "b09381d08625399ef3a8a5ab2b1c6835ef76b22c49fec97303d0cc09c9fb8dc4be7928bcd9f56506501b04559e491632"
    "2e7c8250d2246b9292f9b1940ec695cabe3bd52f5a290c18b02550ebdd9cec7459a453d888cfb99cec779d7eaa510000"
)
V2_FITTED_FINGERPRINT = "db0b8a442800ef24943de3a11126dc3aadc7feb9958f89b5e3c66f7613e66d16"


def test_range_payload_fuzz_with_valid_checksum():
    """Range-coded bytes changed (the payload CRC fixed): a clean error or a valid image, and
    every kind of error is reached by its own check."""
    vi = encoded_image()
    data = bytearray(isoph.dumps(vi))
    hs = struct.unpack_from("<I", data, 12)[0]
    rng = np.random.default_rng(8)
    outcomes = set()
    for _ in range(300):
        bad = bytearray(data)
        for _ in range(int(rng.integers(1, 3))):
            i = int(rng.integers(hs, len(bad)))
            bad[i] = int(rng.integers(0, 256))
        struct.pack_into("<I", bad, 48, zlib.crc32(bytes(bad[hs:])))
        head = bytes(bad[: hs - 4])
        struct.pack_into("<I", bad, hs - 4, zlib.crc32(head))
        try:
            out = isoph.loads(bytes(bad))
        except (FormatError, LimitError) as e:
            assert "malformed .isoph file (" not in str(e) and "\n" not in str(e), e
            outcomes.add(str(e).split(":")[1].split()[0] if ":" in str(e) else str(e))
            continue
        outcomes.add("valid")
        assert isoph.loads(isoph.dumps(out)).equals(out)
    assert len(outcomes) > 3, outcomes
