"""The SVG profile (src/isophote/format/svg.py): exact round trips, renders identical to the
.isoph's, edits made the way drawing programs make them, clean failures on bad files, and
the preview as viewers show it: tests/format/test_svg_preview.py."""

from __future__ import annotations

import gzip
import io
import os
import re
import shutil
import subprocess

import numpy as np
import pytest

import isophote
from isophote.errors import FormatError, LimitError
from isophote.format import svg
from isophote.format.svg import read as svg_read
from isophote.geometry import signed_areas
from isophote.format.isoph import loads as isoph_loads, dumps as isoph_dumps
from isophote.model import Channel, VectorImage
from isophote.render import render_float

Q = 64


# ---- fixtures -------------------------------------------------------------------------------


def _synthetic(w=28, h=20):
    """A gradient with a bright disc and a dark dot: contours of many levels, nested
    contours, caps, and contours closed along the border."""
    y, x = np.mgrid[0:h, 0:w]
    r = 30 + 190 * x / (w - 1)
    g = 220 - 170 * y / (h - 1)
    b = 60 + 150 * ((x - w / 2) ** 2 + (y - h / 2) ** 2 < 30) - 50 * ((x - 5) ** 2 + (y - 5) ** 2 < 4)
    return np.clip(np.stack([r, g, b], axis=2), 0, 255)


@pytest.fixture(scope="module")
def small():
    return isophote.encode(_synthetic())


@pytest.fixture(scope="module")
def crop():
    """A 64x64 crop of a corpus photograph (the cat's face), encoded."""
    skimage_data = pytest.importorskip("skimage.data")
    return isophote.encode(skimage_data.chelsea()[90:154, 170:234].astype(np.float64))


@pytest.fixture(scope="module")
def grey():
    y, x = np.mgrid[0:18, 0:22]
    return isophote.encode(40 + 150 * np.exp(-((x - 11) ** 2 + (y - 9) ** 2) / 30.0))


def _random_channel(rng, name, w, h, on_grid=True):
    """A valid channel that no encoder would write: parents after children, caps in any
    order, several per contour, off-grid coordinates when asked."""
    n_levels = int(rng.integers(1, 12))
    levels = np.cumsum(rng.uniform(0.25, 20, n_levels)) + rng.uniform(-10, 10)
    c = int(rng.integers(1, 9))
    chains = []
    for _ in range(c):
        n = int(rng.integers(1, 6))
        t = np.sort(rng.uniform(0, 2 * np.pi, 3 * n))
        r = rng.uniform(0.5, max(w, h) / 3) * rng.uniform(0.6, 1.4, 3 * n)
        p = np.c_[rng.uniform(0, w) + r * np.cos(t), rng.uniform(0, h) + r * np.sin(t)]
        p = np.vstack([p, p[:1]])
        chains.append(np.rint(p * Q) / Q if on_grid else p)
    offsets = np.zeros(c + 1, np.int64)
    offsets[1:] = np.cumsum([len(ch) for ch in chains])
    s = int(sum((len(ch) - 1) // 3 for ch in chains))
    order = rng.permutation(c)
    parent = np.full(c, -1, np.int32)
    for i in range(1, c):
        if rng.random() < 0.75:
            parent[order[i]] = order[rng.integers(0, i)]
    k = int(rng.integers(0, c + 3))
    xy = rng.uniform(-1, w + 1, (k, 2))
    val = rng.uniform(-20, 280, k)
    return Channel(
        name=name,
        levels=levels.astype(np.float64),
        contour_level=rng.integers(0, n_levels, c).astype(np.int32),
        offsets=offsets,
        points=np.concatenate(chains),
        border=rng.random(s) < 0.2,
        parent=parent,
        cap_band=rng.integers(0, n_levels + 1, k).astype(np.int32),
        cap_contour=rng.integers(-1, c, k).astype(np.int32),
        cap_xy=np.rint(xy * Q) / Q if on_grid else xy,
        cap_value=np.rint(val * Q) / Q if on_grid else val,
        base_band=int(rng.integers(0, n_levels + 1)),
    )


def _random_image(seed, colour="yuv", alpha=False, on_grid=True):
    rng = np.random.default_rng(seed)
    names = ("Y", "U", "V") if colour == "yuv" else ("Y",)
    names += ("A",) if alpha else ()
    w, h = int(rng.integers(3, 30)), int(rng.integers(3, 30))
    chans = tuple(_random_channel(rng, n, w, h, on_grid) for n in names)
    return VectorImage(width=w, height=h, colour=colour, channels=chans, source_depth=8,
                       meta={"seed": seed, "note": "<&>\"\uffff\u00e9\U0001f600", "list": [1.5, None]})


def _path_element(text, channel, k):
    """(start, end) of contour k's <path .../> in channel's layer."""
    layer = text.index(f'iso:channel="{channel}"')
    m = re.compile(r'<path iso:c="%d [^"]*"[^>]*/>' % k).search(text, layer)
    assert m is not None
    return m.start(), m.end()


# ---- round trips ----------------------------------------------------------------------------


def test_round_trip_is_exact(small):
    text = svg.to_svg(small)
    back = svg.from_svg(text)
    assert back.equals(small)
    for a, b in zip(back.channels, small.channels):
        for f in ("levels", "contour_level", "offsets", "points", "border", "parent",
                  "cap_band", "cap_contour", "cap_xy", "cap_value"):
            assert getattr(a, f).dtype == getattr(b, f).dtype, f
    assert back.meta == small.meta
    # and through .isoph bytes too: the SVG loses nothing the binary format keeps
    assert isoph_loads(isoph_dumps(back)).equals(small)


def _with_tone(vi, name, knots):
    from dataclasses import replace

    return replace(vi, channels=tuple(replace(ch, tone=np.asarray(knots, np.float64)) if ch.name == name else ch
                                      for ch in vi.channels))


def test_tone_curve_round_trips(small):
    # knots off any grid, a flat stretch, the ends of the scale: every number exact
    vi = _with_tone(small, "Y", [[0, 0], [17.5, 3.25], [100.1, 100.1], [200.0, 254.9], [254.75, 255], [255, 255]])
    vi = _with_tone(vi, "U", [[0.0, 1 / 3], [255.0, 254.0]])
    text = svg.to_svg(vi)
    assert text.count("iso:tone=") == 2
    back = svg.from_svg(text)
    assert back.equals(vi)
    assert back.channel("V").tone is None
    assert back.channel("Y").tone.dtype == np.float64
    assert np.array_equal(back.channel("U").tone, vi.channel("U").tone)
    assert np.array_equal(render_float(back), render_float(vi))  # the curve is applied
    assert not np.array_equal(render_float(back), render_float(small))
    # no tone curve: no attribute, and None comes back
    text = svg.to_svg(small)
    assert "iso:tone" not in text
    assert all(ch.tone is None for ch in svg.from_svg(text).channels)


def test_cap_ramp_round_trips(small):
    from dataclasses import replace

    from isophote.model import DOME

    chans = {"Y": DOME, "U": 3.25}
    vi = replace(small, channels=tuple(replace(ch, cap_ramp=chans.get(ch.name, ch.cap_ramp)) for ch in small.channels))
    text = svg.to_svg(vi)
    assert 'iso:cap-ramp="dome"' in text and 'iso:cap-ramp="3.25"' in text and text.count("iso:cap-ramp") == 2
    back = svg.from_svg(text)
    assert back.equals(vi) and back.channel("Y").cap_ramp == DOME and back.channel("V").cap_ramp == 2.0
    assert np.array_equal(render_float(back), render_float(vi))
    assert "iso:cap-ramp" not in svg.to_svg(small)
    for bad in ("0", "-1", "dome dome", "1 2", "nan", "x"):
        _bad(text.replace('iso:cap-ramp="3.25"', f'iso:cap-ramp="{bad}"'))


@pytest.mark.parametrize("tone", [
    "0 0 255", "0 0", "x 0 255 255", "0 0 nan 255", "5 0 4 255", "0 9 255 8", "0 0 300 255",
    "-1 0 255 255", "0 0 255 1e999",
])
def test_malformed_tone_curves_are_refused(small, tone):
    text = svg.to_svg(_with_tone(small, "Y", [[0, 0], [255, 255]]))
    assert 'iso:tone="0 0 255 255"' in text
    _bad(text.replace('iso:tone="0 0 255 255"', f'iso:tone="{tone}"'))


@pytest.mark.parametrize("knots", [
    [[0, 0]], [[5, 0], [4, 255]], [[0, 9], [255, 8]], [[0, 0], [300, 255]], [[0, 0], [np.nan, 1]],
    [0, 255],
])
def test_writer_refuses_a_bad_tone_curve(small, knots):
    with pytest.raises(ValueError):
        svg.to_svg(_with_tone(small, "Y", knots))


def test_too_many_tone_knots_are_refused(monkeypatch, small):
    text = svg.to_svg(_with_tone(small, "Y", [[0, 0], [100, 50], [255, 255]]))
    monkeypatch.setattr(svg_read, "MAX_TONE_KNOTS", 2)
    with pytest.raises(LimitError):
        svg.from_svg(text)


def test_corpus_crop_round_trip_and_identical_render(crop):
    back = svg.from_svg(svg.to_svg(crop))
    assert back.equals(crop)
    assert np.array_equal(render_float(back), render_float(crop))


@pytest.mark.parametrize("seed", range(12))
def test_random_images_round_trip(seed):
    vi = _random_image(seed, colour=("yuv", "grey")[seed % 2], alpha=seed % 3 == 0, on_grid=seed % 4 != 1)
    text = svg.to_svg(vi)
    back = svg.from_svg(text)
    assert back.equals(vi)
    assert back.meta == vi.meta


def test_grey_image_and_svgz(grey, tmp_path):
    p1, p2, p3 = tmp_path / "a.svgz", tmp_path / "b.svgz", tmp_path / "c.svg"
    svg.save_svg(grey, p1)
    svg.save_svg(grey, p2)
    svg.save_svg(grey, p3)
    assert p1.read_bytes() == p2.read_bytes()  # deterministic gzip (mtime 0)
    assert p1.read_bytes()[:2] == b"\x1f\x8b" and p3.read_bytes()[:5] == b"<?xml"
    assert gzip.decompress(p1.read_bytes()) == p3.read_bytes()
    assert svg.load_svg(p1).equals(grey) and svg.load_svg(p3).equals(grey)
    assert svg.is_svg(p1.read_bytes()[:16]) and svg.is_svg(p3.read_bytes()[:16])
    assert not svg.is_svg(isoph_dumps(grey)[:16])
    # a grey image's preview is grey
    fills = re.findall(r'fill="#([0-9a-f]{6})"', p3.read_text())
    assert fills and all(f[0:2] == f[2:4] == f[4:6] for f in fills)


def test_document_shape(small):
    text = svg.to_svg(small)
    w, h = small.width, small.height
    assert f'viewBox="0 0 {w} {h}"' in text and 'version="1.1"' in text
    # the preview: Y, U and V polylines, composed by the YUV -> RGB filter, above the hidden data
    assert text.count('id="isophote-preview"') == 1 and text.count("mix-blend-mode:lighten") == 2
    assert text.count('filter="url(#isophote-yuv)"') == 1 and 'shape-rendering="crispEdges"' in text
    assert "crispEdges" not in svg.to_svg(small, crisp=False)
    head, data = text.split('id="isophote-preview"')[1].split('<g id="isophote-Y"')
    assert " c" not in head and "c-" not in head and "C" not in head.replace("Cross", "")  # lines only
    assert data.count("display:none") == len(small.channels) and 'fill="#' not in data
    # one painted path per depth and fill, every contour in one of them
    y = small.channel("Y")
    assert text.count("<path iso:c=") == sum(ch.n_contours for ch in small.channels)
    assert 0 < head.count("<path ") <= sum(ch.n_contours for ch in small.channels)
    assert head.count("z") == sum(ch.n_contours for ch in small.channels)
    # curves: the data paths themselves painted (the editor's layout), in painter's order
    curves = svg.to_svg(small, lines=False)
    assert "isophote-preview" not in curves and curves.count("display:none") == 0
    assert curves.count("mix-blend-mode:lighten") == 2 and svg.from_svg(curves).equals(small)
    order = [int(m) for m in re.findall(r'<path iso:c="(\d+) ', curves)[: y.n_contours]]
    seen = set()
    for k in order:
        p = int(y.parent[k])
        assert p < 0 or p in seen
        seen.add(k)


# ---- edits ----------------------------------------------------------------------------------


def _contour_with_cap(vi, channel="Y"):
    ch = vi.channel(channel)
    counts = np.bincount(ch.cap_contour[ch.cap_contour >= 0], minlength=ch.n_contours)
    border = np.array([ch.border_flags(k).any() for k in range(ch.n_contours)])
    candidates = np.flatnonzero((counts > 0) & ~border)
    assert candidates.size, "fixture has no interior contour with a cap"
    return int(candidates[0])


def test_transform_on_a_path_moves_exactly_that_contour_and_its_caps(small):
    text = svg.to_svg(small)
    k = _contour_with_cap(small)
    a, b = _path_element(text, "Y", k)
    dx, dy = 3.5, -2.25  # source pixels; the layer's units are 1/64 px
    edited = text[:a] + f'<path transform="translate({dx * Q} {dy * Q})"' + text[a + 5 : b] + text[b:]
    back = svg.from_svg(edited)
    y0, y1 = small.channel("Y"), back.channel("Y")
    assert np.array_equal(y1.chain(k), y0.chain(k) + [dx, dy])
    others = np.ones(y0.points.shape[0], bool)
    others[y0.offsets[k] : y0.offsets[k + 1]] = False
    assert np.array_equal(y1.points[others], y0.points[others])
    mine = y0.cap_contour == k
    assert np.array_equal(y1.cap_xy[mine], y0.cap_xy[mine] + [dx, dy])
    assert np.array_equal(y1.cap_xy[~mine], y0.cap_xy[~mine])
    for name in ("U", "V"):
        assert back.channel(name).equals(small.channel(name))
    # the render changes, and only around the old and the new place of the contour
    before, after = render_float(small, fill="flat"), render_float(back, fill="flat")
    diff = np.any(before != after, axis=2)
    assert diff.any()
    pts = np.vstack([y0.chain(k), y1.chain(k)])
    x_lo, y_lo = np.floor(pts.min(axis=0)) - 1
    x_hi, y_hi = np.ceil(pts.max(axis=0)) + 1
    ii, jj = np.nonzero(diff)
    assert ii.min() >= y_lo and ii.max() <= y_hi and jj.min() >= x_lo and jj.max() <= x_hi


def test_group_transforms_compose(small):
    """A contour wrapped in groups with rotate, scale, skew and matrix transforms: the
    control points go through the composed map (as a viewer draws them)."""
    text = svg.to_svg(small)
    k = _contour_with_cap(small)
    a, b = _path_element(text, "Y", k)
    wrap_open = '<g transform="rotate(90 640 640)"><g transform="matrix(1 0 0 1 64 -128) scale(2,1)">'
    edited = text[:a] + wrap_open + text[a:b] + "</g></g>" + text[b:]
    back = svg.from_svg(edited)
    p = small.channel("Y").chain(k) * Q
    # inner first: scale(2, 1), then translate(64, -128), then rotate 90 about (640, 640)
    p = p * [2, 1] + [64, -128]
    p = np.c_[640 - (p[:, 1] - 640), 640 + (p[:, 0] - 640)] / Q
    got = back.channel("Y").chain(k)
    # a mirror-free map keeps the orientation, so the chain is not reversed
    assert np.allclose(got, p, atol=1e-9)
    assert svg.parse_transform("skewX(45)") == pytest.approx((1, 0, 1, 1, 0, 0))
    assert svg.parse_transform("skewY(45) translate(2)") == pytest.approx((1, 1, 0, 1, 2, 2))


def test_mirroring_keeps_the_orientation(small):
    text = svg.to_svg(small)
    k = _contour_with_cap(small)
    a, b = _path_element(text, "Y", k)
    cx = float(small.channel("Y").chain(k)[:, 0].mean()) * Q
    edited = text[:a] + f'<path transform="translate({2 * cx} 0) scale(-1 1)"' + text[a + 5 : b] + text[b:]
    back = svg.from_svg(edited)
    y0, y1 = small.channel("Y"), back.channel("Y")
    mirrored = y0.chain(k) * [-1, 1] + [2 * cx / Q, 0]
    assert np.allclose(y1.chain(k), mirrored[::-1])  # reversed back: >= side on the left
    area = lambda ch, i: signed_areas(ch.chain(i), np.array([0, len(ch.chain(i))]))[0]
    assert np.sign(area(y1, k)) == np.sign(area(y0, k))


def _inkscape_style(chain_local, markers_local):
    """Path data as Inkscape writes it after baking a transform: relative commands with
    commas, the caps' markers as relative movetos after the closepath."""
    p = np.asarray(chain_local)
    parts = [f"m {p[0, 0]:.8g},{p[0, 1]:.8g} c"]
    for i in range(0, len(p) - 1, 3):
        start = p[i]
        parts.append(" ".join(f"{x - start[0]:.8g},{y - start[1]:.8g}" for x, y in p[i + 1 : i + 4]))
    d = " ".join(parts) + " z"
    cur = p[0]
    for m in markers_local:
        d += f" m {m[0] - cur[0]:.8g},{m[1] - cur[1]:.8g}"
        cur = m
    return d


def test_caps_follow_a_transform_baked_into_the_path_data(small):
    """Inkscape stores a rotation or flip of a path by rewriting its data; the caps travel
    in that data as markers, so they turn with their contour."""
    text = svg.to_svg(small)
    y = small.channel("Y")
    k = _contour_with_cap(small)
    mine = np.flatnonzero(y.cap_contour == k)
    a, b = _path_element(text, "Y", k)
    centre = np.array([640.0, 448.0])  # local units
    maps = (("rotate 90", np.array([[0.0, -1.0], [1.0, 0.0]])), ("flip", np.array([[-1.0, 0.0], [0.0, 1.0]])))
    for name, lin in maps:
        chain = (y.chain(k) * Q - centre) @ lin.T + centre
        marks = (y.cap_xy[mine] * Q - centre) @ lin.T + centre
        edited = text[:a] + re.sub(r' d="[^"]*"', f' d="{_inkscape_style(chain, marks)}"', text[a:b]) + text[b:]
        back = svg.from_svg(edited).channel("Y")
        got = back.chain(k)
        expect = chain / Q if name != "flip" else (chain / Q)[::-1]  # a flip is reversed back
        assert np.allclose(got, expect, atol=1e-9), name
        assert np.allclose(back.cap_xy[mine], marks / Q, atol=1e-9), name


def test_caps_fall_back_to_their_offset_when_markers_are_gone(small):
    text = svg.to_svg(small)
    y = small.channel("Y")
    k = _contour_with_cap(small)
    mine = np.flatnonzero(y.cap_contour == k)
    a, b = _path_element(text, "Y", k)
    shift = np.array([5.0, 3.0])
    chain = (y.chain(k) + shift) * Q
    edited = text[:a] + re.sub(r' d="[^"]*"', f' d="{_inkscape_style(chain, [])}"', text[a:b]) + text[b:]
    back = svg.from_svg(edited).channel("Y")
    assert np.allclose(back.cap_xy[mine], y.cap_xy[mine] + shift, atol=1 / Q)


def test_real_inkscape_edits(small, tmp_path):
    """Where Inkscape is installed: open, edit with its own actions, save; read back."""
    exe = shutil.which("inkscape")
    if exe is None:
        pytest.skip("Inkscape not installed")
    text = svg.to_svg(small)
    y = small.channel("Y")
    k = _contour_with_cap(small)
    mine = np.flatnonzero(y.cap_contour == k)
    a, _ = _path_element(text, "Y", k)
    src = tmp_path / "in.svg"
    src.write_text(text[:a] + '<path id="target"' + text[a + 5 :])
    env = {**os.environ, "HOME": str(tmp_path)}

    def edit(action):
        out = tmp_path / "out.svg"
        acts = f"select-by-id:target;{action};export-filename:{out};export-overwrite;export-do"
        subprocess.run([exe, f"--actions={acts}", str(src)], check=True, capture_output=True, timeout=120, env=env)
        return svg.from_svg(out.read_text())

    assert edit("select-clear").equals(small)  # opened and saved: nothing lost
    for action in ("object-rotate-90-cw", "object-flip-horizontal", "object-align:left page"):
        back = edit(action)
        y1 = back.channel("Y")
        chain = y1.chain(k)
        lo, hi = chain.min(axis=0), chain.max(axis=0)
        assert not np.array_equal(chain, y.chain(k)), action
        assert np.all((back.channel("Y").cap_xy[mine] >= lo) & (back.channel("Y").cap_xy[mine] <= hi)), action
        area = signed_areas(chain, np.array([0, len(chain)]))[0]
        assert np.sign(area) == np.sign(signed_areas(y.chain(k), np.array([0, len(y.chain(k))]))[0])
        others = np.ones(y.n_contours, bool)
        others[k] = False
        assert all(np.array_equal(y1.chain(i), y.chain(i)) for i in np.flatnonzero(others))


def test_rewritten_path_data_with_other_commands(small):
    """What an editor writes after node editing: relative commands, lines, H/V, S, Q, T,
    commas and minus signs as separators. More segments: border flags from the frame."""
    text = svg.to_svg(small)
    y = small.channel("Y")
    k = next(i for i in range(y.n_contours) if y.border_flags(i).any())
    a, b = _path_element(text, "Y", k)
    w, h = small.width * Q, small.height * Q
    # a new shape: a box along the left edge of the frame, drawn with every kind of command
    d = (f"m 0,0 H {w // 2} q 64,64 128,0 t 128,0 s 64,-64 128,0 L {w // 2 + 384},{h // 2} "
         f"c 0,64 -64,128 -128,128 V {h} h -{w // 2 + 256} Z")
    edited = text[:a] + re.sub(r' d="[^"]*"', f' d="{d}"', text[a:b]) + text[b:]
    back = svg.from_svg(edited)
    chain = back.channel("Y").chain(k)
    flags = back.channel("Y").border_flags(k)
    assert np.array_equal(chain[0], chain[-1])
    assert len(flags) == (len(chain) - 1) // 3 == 9  # H, q, t, s, L, c, V, h, closing line
    starts = chain[:-1:3]
    on_frame = [bool(np.all(chain[3 * i : 3 * i + 4, 0] == 0) or np.all(chain[3 * i : 3 * i + 4, 1] == 0)
                     or np.all(chain[3 * i : 3 * i + 4, 1] == small.height)) for i in range(len(flags))]
    assert list(flags) == on_frame and any(on_frame) and not all(on_frame)
    assert starts.shape[0] == len(flags)
    render_float(back, fill="flat")  # renders


def test_parse_path_commands():
    (c,) = svg.parse_path("M0 0L3 0 3 3z")
    assert c.shape == (10, 2)
    assert np.allclose(c[[0, 3, 6, 9]], [[0, 0], [3, 0], [3, 3], [0, 0]])
    assert np.allclose(c[1], [1, 0]) and np.allclose(c[2], [2, 0])  # a line is a straight cubic
    (c,) = svg.parse_path("m1 1 h2 v2 h-2 z")
    assert np.allclose(c[[0, 3, 6, 9, 12]], [[1, 1], [3, 1], [3, 3], [1, 3], [1, 1]])
    (c,) = svg.parse_path("M0 0 Q 1 2 2 0 T 4 0 Z")
    assert np.allclose(c[1:4], [[2 / 3, 4 / 3], [4 / 3, 4 / 3], [2, 0]])
    assert np.allclose(c[4:7], [[8 / 3, -4 / 3], [10 / 3, -4 / 3], [4, 0]])
    (c,) = svg.parse_path("M0 0 C 0 1 1 2 2 2 S 4 1 4 0 Z")
    assert np.allclose(c[4], [3, 2])  # reflection of the previous second control point
    # a full circle of radius 5 as two arcs; compact arc flags
    (c,) = svg.parse_path("M10 5 A5 5 0 1 1 0 5 a5 5 0 0,1 10,0z")
    t = np.linspace(0, 1, 9)
    n = (len(c) - 1) // 3
    for s in range(n):
        p0, p1, p2, p3 = c[3 * s : 3 * s + 4]
        pts = ((1 - t) ** 3)[:, None] * p0 + (3 * (1 - t) ** 2 * t)[:, None] * p1 \
            + (3 * (1 - t) * t**2)[:, None] * p2 + (t**3)[:, None] * p3
        assert np.allclose(np.hypot(pts[:, 0] - 5, pts[:, 1] - 5), 5, atol=2e-3)
    assert svg.parse_path("M0 0 a1 1 0 011 1z")[0].shape[1] == 2
    assert len(svg.parse_path("M0 0 1 0 1 1z M5 5 l1 0 0 1")) == 2
    assert np.allclose(svg.parse_path("M0,0 L1e1,0 .5.5z")[0][[3, 6]], [[10, 0], [0.5, 0.5]])


def test_deleted_contour_is_tolerated(small):
    text = svg.to_svg(small)
    y = small.channel("Y")
    k = int(np.flatnonzero(np.bincount(y.parent[y.parent >= 0], minlength=y.n_contours))[0])
    a, b = _path_element(text, "Y", k)
    back = svg.from_svg(text[:a] + text[b:])
    y1 = back.channel("Y")
    assert y1.n_contours == y.n_contours - 1
    assert np.array_equal(y1.chain(k), y.chain(k + 1))
    assert not np.any(y1.cap_contour == -2)
    render_float(back, fill="flat")


def test_additions_without_isophote_data_are_ignored(small):
    text = svg.to_svg(small)
    i = text.index("</svg>")
    edited = text[:i] + '<g><path d="M0 0 L5 5" stroke="red"/><text x="1" y="1">hi</text></g>' + text[i:]
    assert svg.from_svg(edited).equals(small)


# ---- malformed files ------------------------------------------------------------------------


def _bad(text_or_bytes):
    with pytest.raises((FormatError, LimitError)):
        svg.from_svg(text_or_bytes)


def test_truncations_fail_cleanly(small):
    text = svg.to_svg(small)
    for n in list(range(0, 300, 7)) + list(range(300, len(text) - 1, max(1, len(text) // 97))):
        _bad(text[:n])
    raw = gzip.compress(text.encode(), mtime=0)
    for n in range(0, len(raw) - 1, max(1, len(raw) // 41)):
        _bad(raw[:n])


@pytest.mark.parametrize("mutate", [
    lambda t: "not xml at all",
    lambda t: "<html/>",
    lambda t: '<svg xmlns="http://www.w3.org/2000/svg"/>',  # not an isophote SVG
    lambda t: t.replace('iso:format="1"', 'iso:format="2"'),
    lambda t: t.replace('iso:colour="yuv"', 'iso:colour="cmyk"'),
    lambda t: t.replace('iso:width="', 'iso:width="-'),
    lambda t: t.replace('iso:width="', 'iso:width="99999999'),
    lambda t: t.replace('iso:source-depth="8"', 'iso:source-depth="12"'),
    lambda t: t.replace('iso:channel="V"', 'iso:channel="U"'),
    lambda t: t.replace('iso:channel="V"', 'iso:channel="X"'),
    lambda t: re.sub(r'iso:levels="[^"]*"', 'iso:levels="5 3"', t, count=1),
    lambda t: re.sub(r'iso:levels="[^"]*"', 'iso:levels="nan"', t, count=1),
    lambda t: re.sub(r'iso:levels="[^"]*"', 'iso:levels="1e999"', t, count=1),
    lambda t: re.sub(r'iso:base-band="[^"]*"', 'iso:base-band="999"', t, count=1),
    lambda t: re.sub(r'iso:c="(\d+) ', r'iso:c="0 ', t),  # duplicates
    lambda t: re.sub(r'iso:c="(\d+) \d+ ', r'iso:c="\1 999 ', t, count=1),  # level out of range
    lambda t: re.sub(r'iso:c="(\d+) (\d+) -?\d+ ', r'iso:c="\1 \2 -7 ', t, count=1),
    lambda t: re.sub(r'iso:c="(\d+) (\d+) (-?\d+) ', r'iso:c="\1 \2 \1 ', t, count=1),  # own parent
    lambda t: re.sub(r'iso:c="[^"]*"', 'iso:c="x"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="M0 0 C 1 2 3"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="M0 0 L nan 2 z"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="M0 0 L 1e999 2 z"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="M0 0 L 9e15 2 z"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="M0 0 L 1 2 z M 5 5 L 6 6 z"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="M0 0 z"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="0 0 L 1 1"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="M0 0 L 1 1 # 2"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="M0 0 A 1 1 0 2 0 5 5 z"', t, count=1),
    lambda t: re.sub(r' d="[^"]*"', ' d="M0 0c1 1 1 1 1 1 1 1 1 1 1--1z"', t, count=1),
    lambda t: t.replace("<path ", '<path transform="rotate(x)" ', 1),
    lambda t: t.replace("<path ", '<path transform="scale(1e308) scale(1e308)" ', 1),
    lambda t: t.replace("<path ", '<path transform="translate(1 2 3)" ', 1),
    lambda t: t.replace("<path ", '<path transform="matrix(1 0 0 1 0 0) junk" ', 1),
    lambda t: t.replace("<path ", "<rect ", 1),
    lambda t: re.sub(r'iso:caps="[^"]*"', 'iso:caps="1 2 3"', t, count=1),
    lambda t: re.sub(r'iso:caps="[^"]*"', 'iso:caps="0 999 1 1 5"', t, count=1),
    lambda t: re.sub(r'iso:caps="[^"]*"', 'iso:caps="-5 1 1 1 5"', t, count=1),
    lambda t: re.sub(r'iso:caps="[^"]*"', 'iso:caps="-1 1 1 1 1e300"', t, count=1),
    lambda t: re.sub(r'iso:caps="[^"]*"', 'iso:caps="-1 1.5 1 1 1"', t, count=1),
    lambda t: re.sub(r'iso:c="(\d+) (\d+) (-?\d+) (-?\d+) \d+"', r'iso:c="\1 \2 \3 \4"', t, count=1),
    lambda t: t.replace("</svg>", '<path iso:c="0 0 -1 1 2" d="M0 0 L1 1z"/></svg>'),  # outside a layer
    lambda t: t.replace("<path ", '<g iso:channel="A" iso:levels="1" iso:base-band="0"/><path ', 1),
    lambda t: t.replace("<svg ", '<!DOCTYPE svg [<!ENTITY a "aaaaaaaaaa">]>\n<svg ', 1),
    lambda t: t.replace("<svg ", "<svg>" * 3 + "<svg ", 1),
    lambda t: t.replace("</svg>", "<metadata><iso:meta>[1,2]</iso:meta></metadata></svg>"),
    lambda t: t.replace("</svg>", "<metadata><iso:meta>{nope</iso:meta></metadata></svg>"),
    lambda t: t.encode("utf-16"),
    lambda t: b"\x1f\x8b" + b"\x00" * 30,
    lambda t: 12345,
])
def test_malformed_files_raise_format_error(small, mutate):
    # the data paths come first without the preview's polylines (which carry no data:
    # test_preview_polylines_are_not_data)
    text = svg.to_svg(small, lines=False)
    if "iso:caps=" not in text:  # the fixture has caps on Y
        pytest.fail("fixture lost its caps")
    bad = mutate(text)
    if isinstance(bad, str):
        assert bad != text
    _bad(bad)


def test_preview_polylines_are_not_data(small):
    """The reader takes nothing from the preview group: emptied, garbled or gone, the same image."""
    text = svg.to_svg(small)
    a = text.index('<g id="isophote-preview"')
    b = text.index('<g id="isophote-Y"')
    assert svg.from_svg(text).equals(small)
    assert svg.from_svg(text[:a] + text[b:]).equals(small)
    garbled = text[:a] + re.sub(r' d="[^"]*"', ' d="M0 0 L nan 1e999 z"', text[a:b]) + text[b:]
    assert garbled != text and svg.from_svg(garbled).equals(small)


def test_border_flags_must_be_binary(small):
    text = svg.to_svg(small)
    m = re.search(r'iso:b="([01]+)"', text)
    assert m is not None
    _bad(text[: m.start(1)] + "2" * len(m.group(1)) + text[m.end(1) :])


def test_oversized_input_is_refused(monkeypatch, small):
    text = svg.to_svg(small)
    monkeypatch.setattr(svg_read, "MAX_SVG_BYTES", len(text) - 1)
    with pytest.raises(LimitError):
        svg.from_svg(text)
    with pytest.raises(LimitError):
        svg.from_svg(gzip.compress(text.encode()))


def test_writer_refuses_a_broken_image(small):
    y = small.channel("Y")
    cyclic = y.parent.copy()
    cyclic[0] = 0
    from dataclasses import replace

    bad = replace(small, channels=(replace(y, parent=cyclic),) + small.channels[1:])
    with pytest.raises(ValueError):
        svg.to_svg(bad)


def test_load_svg_names_the_file(tmp_path):
    p = tmp_path / "x.svg"
    p.write_text("<svg")
    with pytest.raises(FormatError, match="x.svg"):
        svg.load_svg(p)
    with pytest.raises(FormatError, match="cannot read"):
        svg.load_svg(tmp_path / "missing.svg")
