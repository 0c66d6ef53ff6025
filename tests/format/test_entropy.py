"""The range coder of .isoph (src/isophote/_kernels/entropy.py) against its plain-Python twin
(entropy_ref.py): the same bytes and the same decoded values on random inputs, valid or not.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import isophote
from isophote.format._coder import entropy as E
from isophote.format._coder import entropy_ref as R
from isophote.format import isoph
from isophote.format.isoph import layout as isoph_layout, rangecoded as isoph_range, write as isoph_write

from test_format import random_image, smooth_contour_set


# ---- integers --------------------------------------------------------------------------------


def ref_ints(values, models, signed) -> bytes:
    enc, mo = R.Encoder(), {}
    for v, m in zip(values, models):
        model = mo.setdefault(m, R.IntModel())
        (model.put if signed else model.put_uint)(enc, int(v))
    return enc.finish()


def ref_decode_ints(data, models, signed):
    dec, mo = R.Decoder(data), {}
    out = []
    for m in models:
        model = mo.setdefault(m, R.IntModel())
        out.append((model.get if signed else model.get_uint)(dec))
    return out, dec.status()


def random_values(rng, n, signed):
    kind = rng.integers(0, 4)
    if kind == 0:  # small, skewed: what residuals look like
        v = np.rint(rng.laplace(0, rng.uniform(0.2, 40), n)).astype(np.int64)
    elif kind == 1:  # any magnitude up to the limit
        v = (rng.random(n) * 2.0 ** rng.integers(0, E.KMAX, n)).astype(np.int64)
        v = np.minimum(v, E.MAX_UINT)
    elif kind == 2:  # constant runs: probabilities go to their extremes
        v = np.full(n, int(rng.integers(0, 3)), np.int64)
    else:
        v = rng.choice(np.array([0, 1, 2, E.MAX_UINT, E.MAX_UINT - 1, 1 << 20], np.int64), n)
    if signed:
        v = np.where(rng.random(n) < 0.5, -np.abs(v), np.abs(v))
    else:
        v = np.abs(v)
    return v


@pytest.mark.parametrize("signed", [True, False])
def test_ints_match_the_reference(signed):
    rng = np.random.default_rng(1)
    for trial in range(40):
        n = int(rng.integers(0, 400))
        values = random_values(rng, n, signed)
        models = rng.integers(0, 3, n).astype(np.int64)
        coded = E.encode_ints(values, models, signed).tobytes()
        assert coded == ref_ints(values, models, signed), trial
        back, status = E.decode_ints(np.frombuffer(coded, np.uint8).copy(), models, signed)
        assert status == E.OK and np.array_equal(back, values)
        ref_back, ref_status = ref_decode_ints(coded, models.tolist(), signed)
        assert ref_status == "ok" and ref_back == values.tolist()


def test_probabilities_stay_inside_their_range():
    """After thousands of equal bits, a probability is still strictly inside (0, 1): the
    opposite bit can always be coded."""
    values = np.r_[np.zeros(20000, np.int64), [E.MAX_UINT], np.zeros(5, np.int64)]
    models = np.zeros(values.shape[0], np.int64)
    coded = E.encode_ints(values, models, False)
    assert len(coded) < 200
    back, status = E.decode_ints(coded, models, False)
    assert status == E.OK and np.array_equal(back, values)


def test_ints_decoder_on_garbage_matches_the_reference():
    """Random bytes decode to the same values in both, and end with the same verdict."""
    rng = np.random.default_rng(2)
    for _ in range(100):
        data = rng.integers(0, 256, int(rng.integers(0, 40)), dtype=np.uint8)
        models = rng.integers(0, 2, int(rng.integers(0, 30))).astype(np.int64)
        back, status = E.decode_ints(data, models, True)
        ref_back, ref_status = ref_decode_ints(data.tobytes(), models.tolist(), True)
        assert back.tolist() == ref_back
        assert {E.OK: "ok", E.E_SHORT: "short", E.E_LONG: "long"}[status] == ref_status


# ---- version 3's chord frame --------------------------------------------------------------


def test_chord_frame_is_an_exact_integer_rotation():
    """The lifting rotation onto a chord: the same integers in the kernel and the reference,
    exactly undone, and close to the true rotation (along = v . d / |d|, across = d x v / |d|)."""
    rng = np.random.default_rng(5)
    specials = [(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1), (5, 5), (-5, 5), (-7, -3), (3, -7),
                (2**31 - 1, 1), (-(2**31), 2**31 - 1), (1, -(2**31))]
    for trial in range(3000):
        if trial < len(specials):
            dx, dy = specials[trial]
        else:
            dx, dy = (int(v) for v in rng.integers(-(2 ** int(rng.integers(1, 32))), 2 ** 31, 2))
        scale = 2 ** int(rng.integers(0, 41))
        vx, vy = (int(v) for v in rng.integers(-scale, scale + 1, 2))
        frame = R.chord_frame(dx, dy)
        a, c = R.to_frame(frame, vx, vy)
        assert R.from_frame(frame, a, c) == (vx, vy)
        sg, p, q = E._frame(dx, dy)
        assert (sg, p, q) == frame
        assert E._to_frame(sg, p, q, vx, vy) == (a, c)
        assert E._from_frame(sg, p, q, a, c) == (vx, vy)
        if (dx, dy) != (0, 0) and scale < 2**30:
            length = np.hypot(dx, dy)
            along, across = (vx * dx + vy * dy) / length, (dx * vy - dy * vx) / length
            assert abs(a - along) <= 2 + 1e-9 * scale and abs(c - across) <= 2 + 1e-9 * scale


def test_chord_frame_of_a_chord_is_its_length():
    for dx, dy in [(3, 4), (-3, 4), (-3, -4), (3, -4), (0, 7), (0, -7), (-7, 0), (640, 1)]:
        a, c = R.to_frame(R.chord_frame(dx, dy), dx, dy)
        assert (a, c) == (round(np.hypot(dx, dy)), 0), (dx, dy, a, c)


# ---- channels --------------------------------------------------------------------------------


def ref_fields(ch, info, version=4) -> dict:
    """A checked channel (isoph_layout.Checked) as the reference coder's plain fields."""
    pts = ch.stored >> info.s_p
    chains, t = [], 0
    for n in ch.nseg.tolist():
        chains.append([tuple(p) for p in pts[t : t + 3 * n].tolist()])
        t += 3 * n
    return dict(level=ch.level.tolist(), nseg=ch.nseg.tolist(), parent=ch.parent.tolist(), chains=chains,
                border=ch.border.astype(int).tolist(), g=info.g, cap_contour=ch.cap_contour.tolist(),
                cap_band=ch.cap_band.tolist(), cap_xy=[tuple(p) for p in (ch.cq >> info.s_c).tolist()],
                cap_value=(ch.vq >> info.s_v).tolist(), s_p=info.s_p, s_c=info.s_c, s_v=info.s_v,
                levels=info.levels.tolist(), base_band=info.base_band, version=version)


VERSIONS = (2, 3, 4, 5)  # the range-coded layouts: every one that a reader reads


def kernel_decode(data, *args, workers=None):
    """The kernels' decoder of a layout (5: rangecoded.decode_parts, its parts in threads)."""
    version = args[-1]
    if version >= 5:
        return isoph_range.decode_parts(data, *args, workers=workers)
    return E.decode_channel(data, *args)


def check_channel(c, versions=VERSIONS):
    """For each layout: the kernel's bytes are the reference's; both decode them back to the
    channel."""
    for version in versions:
        info = check_channel_version(c, version)
    return info


def check_channel_version(c, version):
    ch = isoph_write.checked_channel(c)
    coded = isoph_range.range_channel(ch, version)
    info = ch.info
    assert coded == R.encode_channel(ref_fields(ch, info, version))
    args = (info.n_contours, info.n_segments, info.n_caps, info.g, info.s_p, info.s_c, info.s_v)
    ref = R.decode_channel(coded, *args, info.levels.tolist(), info.base_band, version)
    out = kernel_decode(np.frombuffer(coded, np.uint8).copy(), *args, info.levels, info.base_band, version)
    assert out[0] == E.OK
    level, nseg, parent, q, border, cap_contour, cap_band, cq, vq = out[3:]
    assert level.tolist() == ref["level"] == ch.level.tolist()
    assert parent.tolist() == ref["parent"] == ch.parent.tolist()
    assert nseg.tolist() == ref["nseg"] == ch.nseg.tolist()
    closed = isoph_layout.closed_points(ch.stored, ch.offsets)
    assert np.array_equal(q, closed) and [list(p) for chain in ref["chains"] for p in chain] == closed.tolist()
    assert border.astype(bool).tolist() == [bool(b) for b in ref["border"]] == ch.border.tolist()
    assert cap_contour.tolist() == ref["cap_contour"] and cap_band.tolist() == ref["cap_band"]
    assert np.array_equal(cq, ch.cq) and [list(p) for p in ref["cap_xy"]] == ch.cq.tolist()
    assert vq.tolist() == ref["cap_value"] == ch.vq.tolist()
    return info


def test_channels_of_random_images_match_the_reference():
    for seed in range(12):
        for c in random_image(seed, "yuv+alpha").channels:
            check_channel(c)


def test_channels_on_coarse_grids_match_the_reference():
    """Coordinates on coarser grids (shifts > 0) and anchors on a sample grid (g > 0)."""
    vi = isophote.encode(np.clip(np.add.outer(np.arange(20) * 9.0, np.arange(24) * 4.0)
                                 + 60 * (np.hypot(*np.mgrid[-10:10, -12:12]) < 6), 0, 255))
    info = check_channel(vi.channels[0])
    assert info.g > 0 and info.s_c > 0, (info.g, info.s_c)
    rng = np.random.default_rng(3)
    for shift in (1, 3, 6):
        base = random_image(int(rng.integers(0, 1000)), "grey", n_contours=6).channels[0]
        from dataclasses import replace

        step = 2.0 ** shift / 64
        coarse = replace(base, points=np.round(base.points / step) * step,
                         cap_xy=np.round(base.cap_xy / step) * step, cap_value=np.round(base.cap_value / step) * step)
        info = check_channel(coarse)
        assert info.s_p >= shift and info.s_c >= shift and info.s_v >= shift


def test_smooth_contours_match_the_reference():
    check_channel(smooth_contour_set(n=40).channels[0])


def test_extreme_coordinates_match_the_reference():
    """Chains spanning the whole coordinate range (chords and handles near 2**31 units, the
    chord frame's shears at their largest) code alike and come back exactly."""
    from dataclasses import replace

    rng = np.random.default_rng(6)
    for _ in range(4):
        base = random_image(int(rng.integers(0, 1000)), "grey", n_contours=5).channels[0]
        span = (2.0**24 - 1) / np.abs(base.points).max()
        pts = np.clip(np.rint((base.points - base.points.mean(0)) * span * 2 * 64) / 64, -(2.0**24) + 1, 2.0**24 - 1)
        check_channel(replace(base, points=pts))


def test_version_3_codes_photographic_contours_smaller():
    """On contours fitted to a noisy image, as photographs are (not random points), layout 3
    spends fewer bytes. (On noise-free synthetic images the two are within a few bytes.)"""
    yy, xx = np.mgrid[0:96, 0:96]
    img = 128 + 60 * np.sin(xx / 7.0 + np.cos(yy / 9.0)) * np.cos(yy / 11.0) + 20 * np.sin(xx * yy / 300.0)
    img += 3 * np.random.default_rng(0).standard_normal(img.shape)
    vi = isophote.encode(np.clip(img, 0, 255))
    ch = isoph_write.checked_channel(vi.channels[0])
    sizes = [len(isoph_range.range_channel(ch, version)) for version in VERSIONS]
    assert sizes[1] < sizes[0], sizes


def test_version_4_codes_coarse_handles_smaller():
    """The encoder puts handles on coarse grids where the ribbon allows (encoder/fit.py),
    and layout 4 codes them divided by their grid: fewer bytes than layout 3 on the same
    contours, and both come back exactly (check_channel). On handles with no coarse grid
    (random 1/64 points) layout 4 spends only the shifts' bits more."""
    yy, xx = np.mgrid[0:96, 0:96]
    img = 128 + 60 * np.sin(xx / 7.0 + np.cos(yy / 9.0)) * np.cos(yy / 11.0) + 20 * np.sin(xx * yy / 300.0)
    img += 3 * np.random.default_rng(0).standard_normal(img.shape)
    vi = isophote.encode(np.clip(img, 0, 255))
    check_channel(vi.channels[0])
    ch = isoph_write.checked_channel(vi.channels[0])
    v3, v4 = (len(isoph_range.range_channel(ch, version)) for version in (3, 4))
    assert v4 < 0.9 * v3, (v3, v4)
    rand = isoph_write.checked_channel(random_image(5, "grey", n_contours=20).channels[0])
    r3, r4 = (len(isoph_range.range_channel(rand, version)) for version in (3, 4))
    assert r3 <= r4 <= r3 + rand.info.n_segments // 8 + 8, (r3, r4)


def decode_both(data: bytes, c, s, k, g, s_p, s_c, s_v, levels, base_band, version=4):
    out = kernel_decode(np.frombuffer(data, np.uint8).copy(), c, s, k, g, s_p, s_c, s_v,
                        np.asarray(levels, np.float64), base_band, version)
    try:
        ref = R.decode_channel(data, c, s, k, g, s_p, s_c, s_v, list(levels), base_band, version)
    except R.Invalid as e:
        ref = e.args[0]
    return out, ref


STATUS_NAMES = {E.E_RANK: "rank", E.E_PARENT: "parent", E.E_LEVEL: "level", E.E_NSEG: "nseg",
                E.E_NSEG_SHORT: "nseg short", E.E_POINT: "point", E.E_CAP_CONTOUR: "cap contour",
                E.E_CAP_XY: "cap xy", E.E_CAP_VALUE: "cap value", E.E_SHORT: "short", E.E_LONG: "long",
                E.E_SHIFT: "handle shift", E.E_PARTS: "parts"}


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(st.binary(max_size=64), st.integers(0, 6), st.integers(0, 12), st.integers(0, 4), st.integers(0, 16),
       st.integers(0, 6), st.integers(0, 6), st.integers(0, 6), st.integers(0, 4), st.sampled_from(VERSIONS))
def test_channel_decoder_on_garbage_matches_the_reference(data, c, extra, k, g, s_p, s_c, s_v, n_levels,
                                                          version):
    """Random bytes as a channel: both decoders stop at the same broken rule, or both decode
    the same arrays."""
    s = c + extra
    levels = [10.0 * i for i in range(n_levels)]
    out, ref = decode_both(data, c, s, k, g, s_p, s_c, s_v, levels, min(1, n_levels), version)
    if out[0] != E.OK:
        assert STATUS_NAMES[out[0]] == ref
        return
    assert isinstance(ref, dict)
    assert out[3].tolist() == ref["level"] and out[5].tolist() == ref["parent"]
    assert out[6].tolist() == [list(p) for chain in ref["chains"] for p in chain]
    assert out[8].tolist() == ref["cap_contour"] and out[11].tolist() == ref["cap_value"]


def test_handle_shift_beyond_the_largest_is_refused(monkeypatch):
    """A version 4 channel whose handle shift is above MAX_HANDLE_SHIFT (written by the
    reference coder with its limit raised): both decoders stop at the handle-shift rule,
    and format/isoph.py words it."""
    from dataclasses import replace

    base = random_image(7, "grey", n_contours=3).channels[0]
    # anchors on multiples of 3/64 px and handles at the chords' thirds: every handle
    # residual is 0, which every shift divides, so the coder writes its largest shift
    pts = np.round(base.points * 64 / 3) * 3 / 64
    for o0, o1 in zip(base.offsets[:-1], base.offsets[1:]):
        c = pts[o0:o1]  # one closed chain: P0, Ca, Cb, P1, ..., Pm = P0
        a, n = c[0:-1:3].copy(), c[3::3].copy()
        c[1::3], c[2::3] = a + (n - a) / 3, n - (n - a) / 3
    ch = isoph_write.checked_channel(replace(base, points=pts, border=np.zeros_like(base.border)))
    info = ch.info
    monkeypatch.setattr(R, "MAX_HANDLE_SHIFT", E.MAX_HANDLE_SHIFT + 1)
    fields = ref_fields(ch, info, 4)
    coded = R.encode_channel(fields)
    monkeypatch.setattr(R, "MAX_HANDLE_SHIFT", E.MAX_HANDLE_SHIFT)
    out, ref = decode_both(coded, info.n_contours, info.n_segments, info.n_caps, info.g, info.s_p, info.s_c,
                           info.s_v, info.levels.tolist(), info.base_band, 4)
    assert out[0] == E.E_SHIFT and ref == "handle shift"
    assert isoph_range.RANGE_ERRORS[E.E_SHIFT].format(where=out[1]) == f"a handle shift in contour {out[1]} is above 5"


@pytest.mark.parametrize("version", VERSIONS)
def test_mutated_channels_decode_alike(version):
    """Real coded channels with a byte changed: the same verdict from both decoders."""
    vi = isophote.encode(np.clip(np.add.outer(np.arange(12) * 15.0, np.arange(14) * 9.0), 0, 255))
    ch = isoph_write.checked_channel(vi.channels[0])
    coded = isoph_range.range_channel(ch, version)
    info = ch.info
    rng = np.random.default_rng(4)
    verdicts = set()
    for _ in range(60):
        bad = bytearray(coded)
        bad[int(rng.integers(0, len(bad)))] = int(rng.integers(0, 256))
        if rng.random() < 0.3:
            bad = bad[: int(rng.integers(0, len(bad)))]
        out, ref = decode_both(bytes(bad), info.n_contours, info.n_segments, info.n_caps, info.g, info.s_p,
                               info.s_c, info.s_v, info.levels.tolist(), info.base_band, version)
        name = STATUS_NAMES.get(out[0], "ok")
        verdicts.add(name)
        assert name == (ref if isinstance(ref, str) else "ok")
    assert len(verdicts) > 2, verdicts


# ---- layout 5: the points in parts -------------------------------------------------------------


def test_parts_follow_the_segment_counts():
    """A part ends after the contour that brings it to part_segments or more; both coders
    cut alike, and the spec's PART_SEGMENTS is theirs."""
    nseg = np.array([3, 1, 1, 5, 2, 2, 9, 1], np.int64)
    assert E.part_starts(nseg, 4).tolist() == R.part_starts(nseg.tolist(), 4) == [0, 2, 4, 6, 7, 8]
    assert E.part_starts(nseg, 100).tolist() == [0, 8]  # one part
    assert E.part_starts(nseg, 0).tolist() == [0, 8]  # layouts 2 to 4
    assert E.part_starts(np.zeros(0, np.int64), 4).tolist() == [0, 0]
    from pathlib import Path

    spec = (Path(__file__).parents[2] / "docs" / "format.md").read_text(encoding="utf-8")
    assert E.PART_SEGMENTS == R.PART_SEGMENTS == 1 << 18 and "`PART_SEGMENTS` = 2¹⁸" in spec


def _parted(monkeypatch, part_segments=6):
    """A grey channel of many contours, coded in layout 5 with parts of part_segments."""
    monkeypatch.setattr(E, "PART_SEGMENTS", part_segments)
    vi = isophote.encode(np.clip(128 + 90 * np.sin(np.add.outer(np.arange(24) / 3.0, np.arange(28) / 4.0))
                                 * np.cos(np.arange(28) / 5.0), 0, 255))
    ch = isoph_write.checked_channel(vi.channels[0])
    return vi, ch, isoph_range.range_channel(ch, 5)


def test_parts_code_as_the_spec_says_and_decode_in_any_number_of_threads(monkeypatch):
    vi, ch, coded = _parted(monkeypatch)
    info = ch.info
    fields = ref_fields(ch, info, 5)
    fields["part_segments"] = 6
    assert coded == R.encode_channel(fields)
    # the writer's parts side by side (range_channel) are the same coded one after another
    pts = ch.stored >> info.s_p
    for workers in (1, 3):
        seq, _ = isoph_range.code_channel(ch.level, ch.nseg, ch.parent, pts, ch.border.astype(np.uint8), info.g,
                                          ch.cap_contour, ch.cap_band, ch.cq >> info.s_c, ch.vq >> info.s_v,
                                          info.s_p, info.s_c, info.s_v, info.levels, info.base_band, 5,
                                          workers=workers)
        assert seq == coded
    parts = int.from_bytes(coded[-4:], "little") + 1
    assert parts == len(E.part_starts(ch.nseg, 6)) - 1 > 4
    args = (info.n_contours, info.n_segments, info.n_caps, info.g, info.s_p, info.s_c, info.s_v, info.levels,
            info.base_band, 5)
    data = np.frombuffer(coded, np.uint8).copy()
    outs = [isoph_range.decode_parts(data, *args, workers=w) for w in (1, 2, 8)]
    assert all(o[0] == E.OK for o in outs)
    for o in outs[1:]:
        assert all(np.array_equal(a, b) for a, b in zip(o[3:], outs[0][3:]))
    closed = isoph_layout.closed_points(ch.stored, ch.offsets)
    assert np.array_equal(outs[0][6], closed) and outs[0][5].tolist() == ch.parent.tolist()
    ref = R.decode_channel(coded, *args[:7], info.levels.tolist(), info.base_band, 5, part_segments=6)
    assert [list(p) for chain in ref["chains"] for p in chain] == closed.tolist()
    # the whole file: written in parts, read back the same image
    assert isoph.loads(isoph.dumps(vi)).equals(vi)


def test_parts_cost_their_fresh_probabilities_only(monkeypatch):
    """Each later part starts its probabilities afresh: a few bytes a part more than one
    stream, the table's 4 a part, and nothing else."""
    _, ch, one = _parted(monkeypatch, 1 << 18)
    _, _, many = _parted(monkeypatch, 6)
    v4 = isoph_range.range_channel(ch, 4)
    parts = int.from_bytes(many[-4:], "little")
    assert len(one) == len(v4) + 4  # one part: version 4's stream and a count of 0
    assert len(v4) + 4 + 4 * parts < len(many) < len(v4) + 4 + 4 * parts + 40 * parts


@pytest.mark.parametrize("seed", range(3))
def test_mutated_parts_decode_alike(monkeypatch, seed):
    """Layout 5 channels of many parts with a byte changed or cut short: the same verdict
    from both decoders, whichever stream or table the change hits."""
    _, ch, coded = _parted(monkeypatch)
    info = ch.info
    rng = np.random.default_rng(seed)
    verdicts = set()
    for _ in range(40):
        bad = bytearray(coded)
        at = int(rng.integers(0, len(bad)))
        bad[at] = int(rng.integers(0, 256))
        if rng.random() < 0.3:
            bad = bad[: int(rng.integers(0, len(bad)))]
        args = (info.n_contours, info.n_segments, info.n_caps, info.g, info.s_p, info.s_c, info.s_v)
        out = isoph_range.decode_parts(np.frombuffer(bytes(bad), np.uint8).copy(), *args, info.levels,
                                       info.base_band, 5, workers=2)
        try:
            R.decode_channel(bytes(bad), *args, info.levels.tolist(), info.base_band, 5, part_segments=6)
            ref = "ok"
        except R.Invalid as e:
            ref = e.args[0]
        name = STATUS_NAMES.get(out[0], "ok")
        verdicts.add(name)
        assert name == ref, (at, len(bad))
    assert "parts" in verdicts and len(verdicts) > 2, verdicts


def test_accounting_codes_the_same_bytes_and_counts_them(monkeypatch):
    """encode_channel's accounting (the coding study's bits per model) changes no byte, and
    the bits it counts add up to the stream's length; so do code_channel's, parts and all."""
    vi = isophote.encode(np.clip(128 + 90 * np.sin(np.add.outer(np.arange(24) / 3.0, np.arange(28) / 4.0)), 0, 255))
    ch = isoph_write.checked_channel(vi.channels[0])
    coded = isoph_range.range_channel(ch, 4)
    info = ch.info
    pts = ch.stored >> info.s_p
    out, bits = E.encode_channel(ch.level, ch.nseg, ch.parent, np.ascontiguousarray(pts), ch.border.astype(np.uint8),
                                 info.g, ch.cap_contour, ch.cap_band, np.ascontiguousarray(ch.cq >> info.s_c),
                                 ch.vq >> info.s_v, info.s_p, info.s_c, info.s_v, info.levels, info.base_band, 4, True)
    assert out.tobytes() == coded
    assert abs(bits.sum() - 8 * len(coded)) < 0.02 * 8 * len(coded) + 40
    _, ch, parted = _parted(monkeypatch)
    info = ch.info
    pts = ch.stored >> info.s_p
    args = (ch.level, ch.nseg, ch.parent, pts, ch.border.astype(np.uint8), info.g, ch.cap_contour, ch.cap_band,
            ch.cq >> info.s_c, ch.vq >> info.s_v, info.s_p, info.s_c, info.s_v, info.levels, info.base_band, 5)
    out, bits = isoph_range.code_channel(*args, account=True)
    _, plain = isoph_range.code_channel(*args)
    streams = int.from_bytes(parted[-4:], "little") + 1
    table = 4 * streams  # the parts' sizes and count: no model's
    assert out == parted and not plain.any() and streams > 4
    # each stream ends with up to 4 bytes of flush beyond the bits its models spent
    assert 8 * (len(parted) - table - 4 * streams) - 40 < bits.sum() < 8 * (len(parted) - table)
