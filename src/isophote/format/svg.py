"""SVG: a VectorImage as an SVG 1.1 document that every viewer shows and isophote reads back.

This docstring is the specification of the isophote SVG profile.

What a file holds
=================
One document does two jobs:

- a PREVIEW that any browser, Inkscape or resvg shows as the photograph: the Y channel's
  contours filled flat (nonzero rule) with the mean colour of the isophote render inside
  each contour's region, stacked by the painter's algorithm (every parent before its
  children, so each contour paints its whole footprint and its children paint over it:
  no gaps between regions, and anti-aliased edges blend neighbouring region colours, never
  the background). A rectangle in the root region's colour lies underneath. The preview is
  opaque: an alpha channel is kept (losslessly, hidden) but not shown.
- the DATA: every contour of every channel, its level, its parent, its border flags, every
  cap annotation, the levels, base band and tone curve of each channel, and the image's
  size, colour, source depth and meta. The Y contours ARE the preview's paths (nothing is
  stored twice); U, V and A sit in hidden layers. ``from_svg(to_svg(vi))`` equals ``vi`` exactly
  (``VectorImage.equals``, dtypes included, for any valid image, on the 1/64 grid or not).

Layout::

    <svg xmlns="http://www.w3.org/2000/svg" xmlns:iso="urn:x-isophote:svg:1"
         xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"
         version="1.1" width="W" height="H" viewBox="0 0 W H"
         iso:format="1" iso:width="W" iso:height="H" iso:colour="yuv" iso:source-depth="8">
      <metadata><iso:meta>{"json":"object"}</iso:meta></metadata>     (only if meta)
      <defs><linearGradient id="isophote-g12" .../> ...</defs>      (preview only)
      <rect width="W" height="H" fill="#rrggbb"/>                      (preview only)
      <g id="isophote-Y" inkscape:groupmode="layer" inkscape:label="Y"
         transform="scale(0.015625)" iso:channel="Y" iso:levels="7.5 17.5 ..."
         iso:base-band="0" iso:caps="contour band x y value ..."
         [iso:tone="x0 y0 x1 y1 ..."] [iso:cap-ramp="R" or "dome"]>
        <path iso:c="k level parent orientation segments" [iso:b="0011..."]
              fill="#rrggbb" d="Mx yc dx dy dx dy dx dy ... z m dx dy ..."/>
        ...
      </g>
      <g id="isophote-U" ... style="display:none" fill="none" stroke="#..."> ... </g>
      ...
    </svg>

The canvas is ``iso:width`` x ``iso:height`` source pixels (model.py's coordinates; the
viewBox says the same to viewers). Inside a channel layer, coordinates are in 1/64 source
pixel (the layer's ``scale(0.015625)``): points on the encoder's 1/64 grid are integers, so
they print short and exactly, and relative ``c`` commands (differences of integers) are
exact too. A chain with any point off that grid is written with absolute ``C`` commands and
Python's shortest round-trip float repr of 64 x the coordinate (exact: scaling by a power of
two is exact). ``z`` closes the path; the last cubic already ends on the first point.

Per contour, ``iso:c`` holds five integers: the contour's index k in the channel, its level
index, its parent's index (-1: the frame), the sign of its signed area as written (+1, -1
or 0) and its number of segments as written. Paths are written parents first (painter's
order), not in index order; k restores the order. ``iso:b`` (only on contours that have
border segments) is one '0'/'1' per segment.

Caps: the layer's ``iso:caps`` lists the channel's caps in order, five numbers each:
``contour band x y value``. For the root region (contour -1), (x, y) is the cap's position
in the layer's units, exactly. A contour's caps also travel in its path data, as MARKERS:
after the closing ``z``, one moveto per cap, in cap order ("m dx dy", relative to the
chain's start and then to the previous marker; absolute "M x y" off the grid). A subpath
that is only a moveto draws nothing in the preview, but editors transform it with the rest
of the path (Inkscape bakes moves, rotations and flips into path data, markers included),
so caps turn and mirror with their contour. For those caps (x, y) is a fallback, the offset
from the contour's first point to the nearest layer unit, used when the markers are gone
(Inkscape's Simplify drops them). ``value`` and the levels are shortest round-trip decimals.

Tone: ``iso:tone`` (only on a channel that has a tone curve, model.py's Channel.tone) lists
the curve's knots as "x y" pairs in order, shortest round-trip decimals (exact): at least
two knots, at most MAX_TONE_KNOTS (.isoph's limit), every number in [0, 255], x strictly increasing, y
non-decreasing. No attribute: no tone curve. The preview's colours are taken from the
render, so they show the tone curve too.

Cap ramp: ``iso:cap-ramp`` (only on a channel whose Channel.cap_ramp is not model.py's
CAP_RAMP) is the ramp in pixels, a positive number, or "dome" for DOME (caps without a
plateau, as equalisation leaves them). No attribute: CAP_RAMP.

Preview colours: each Y region's mean over a 1x render of the image (by default the flat
fill), or, where the colour drifts across a region enough to matter (GRADIENT_MIN_GAIN), a
linear gradient (the best single-direction plane through the region's colours); the
gradients sit in ``<defs>`` and are not data.

Reading edited files
====================
What a drawing program may do, and what ``from_svg`` makes of it:

- transforms on a path, a group or a layer (matrix, translate, scale, rotate, skewX, skewY,
  any composition): applied to the control points (a cubic under an affine map is the map
  of its control points, exactly) and to the caps' markers.
- rewritten path data: absolute or relative M, L, H, V, C, S, Q, T, A and Z, with any
  number syntax SVG allows. Lines, quadratics and the implicit closing line become cubics
  (lines and quadratics exactly, arcs as quarter-turn pieces within 3e-4 of their radius). A contour must stay one
  subpath; an open one is closed with a line.
- more or fewer segments than written (node editing, simplifying): the stored border flags
  no longer match, so a segment is a border segment when all four control points lie on
  one edge of the frame (the encoder's border segments all do, and no others). A path with
  other markers than caps (some dropped) places its caps by the fallback offsets.
- mirroring and reversing: a contour whose signed area changed sign (a flip, a path
  reversal) is reversed back, so its >= side stays on its left (model.py's orientation).
- deleting a contour: the others are renumbered in order; children of a deleted contour
  hang from the frame (-1), caps of its region are dropped (the renderer uses neither
  parents nor cap contours, only band windings and cap positions).
- z-order, grouping, ids, styles, colours, layer visibility, other namespaces, and paths,
  shapes or text without ``iso:c`` (a drawing program's additions, the preview's rectangle
  and gradients): ignored.

Checked with Inkscape 1.2 (tests/test_svg.py, where it is installed): open and save keeps
the image exactly; rotate, flip and align (move) are honoured, caps included.

Validation
==========
Never trust a file. Every problem is a FormatError (a LimitError for a size over a limit)
with a one-line reason, never another exception type: text over MAX_SVG_BYTES (also after
gunzip, which stops reading at the limit), a DTD with entity declarations (refused before parsing: no
entity expansion at all), XML that does not parse, a root that is not an isophote SVG,
unknown format version, colour, depth or channel layout, bad numbers (not finite, beyond
the .isoph limits), malformed transforms or path data, duplicate contours, levels, parents,
bands out of range, parent cycles, tone curves that are not monotone or leave 0..255. The
work is linear in the size of the text.
"""

from __future__ import annotations

import gzip
import io
import json
import math
import os
import re
import xml.etree.ElementTree as ET
import zlib

import numpy as np

from ..errors import FormatError, LimitError
from ..imageio import atomic_write_bytes
from ..model import CAP_RAMP, DOME, Channel, VectorImage
from .isoph import (
    CAP_VALUE_LIMIT,
    CHANNEL_LAYOUTS,
    COLOUR_CODES,
    COORD_LIMIT,
    MAX_CAPS,
    MAX_HEIGHT,
    MAX_LEVELS,
    MAX_META_BYTES,
    MAX_SEGMENTS,
    MAX_TONE_KNOTS,
    MAX_WIDTH,
    QUANT,
    SOURCE_DEPTHS,
    _check_cap_ramp,
    _check_levels,
    _check_semantics,
    check_image_kind,
    _meta_bytes,
    _parse_meta,
)

# ---- constants of the profile --------------------------------------------------------------

SVG_FORMAT_VERSION = 1
NS_SVG = "http://www.w3.org/2000/svg"
NS_ISO = "urn:x-isophote:svg:1"
NS_INKSCAPE = "http://www.inkscape.org/namespaces/inkscape"
LOCAL_SCALE = QUANT  # layer units per source pixel: 64, so the 1/64 grid is the integers
MAX_SVG_BYTES = 1 << 30  # 1 GiB of text: ~30 times a 0.3 MP photograph's SVG; parse memory ~2x
MAX_COORD = COORD_LIMIT / QUANT  # |coordinate| in source pixels, as in .isoph (2**24)
MAX_CAP_VALUE = CAP_VALUE_LIMIT / QUANT
GZIP_MAGIC = b"\x1f\x8b"
CLOSE_SNAP = 1e-7  # relative distance under which a path's end counts as its start
GRADIENT_MIN_GAIN = 1e4  # squared error (0..255 scale, summed over RGB and pixels) a gradient must remove
UV_STROKES = {"U": "#2a7fff", "V": "#ff2a7f", "A": "#7f7f7f"}  # hidden layers' outline colours

__all__ = [
    "to_svg", "from_svg", "save_svg", "load_svg", "is_svg",
    "SVG_FORMAT_VERSION", "NS_ISO", "MAX_SVG_BYTES",
]

_S = "{%s}" % NS_SVG
_I = "{%s}" % NS_ISO


# =============================================================================================
# Public API
# =============================================================================================


def to_svg(vi: VectorImage, preview=None) -> str:
    """The isophote SVG document of ``vi`` (see the module docstring).

    Parameters
    ----------
    vi : VectorImage
    preview : (H, W, 3) or (H, W[, 1]) array on 0..255, optional
        A render of ``vi`` at 1x (RGB, or grey for a grey image; extra channels such as alpha
        are ignored) whose mean inside each Y region colours the preview. Default: the
        flat-fill render, ``render_float(vi, fill="flat")``. Pass the diffusion render
        if you have one: the colours are a little closer to the photograph.

    Returns
    -------
    str
        Deterministic for a given image and preview.

    Raises
    ------
    ValueError
        ``vi`` breaks the data model, or ``preview`` has the wrong shape.
    """
    try:
        _check_image(vi)
        # canonical JSON (sorted keys), then ASCII only: every character is legal in XML
        meta = json.dumps(json.loads(_meta_bytes(vi.meta)), sort_keys=True, separators=(",", ":")) if vi.meta else ""
    except (FormatError, LimitError) as e:
        raise ValueError(f"cannot write SVG: {e}") from None
    rgb = _preview_rgb(vi, preview)
    w, h = int(vi.width), int(vi.height)
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>\n',
        f'<svg xmlns="{NS_SVG}" xmlns:iso="{NS_ISO}" xmlns:inkscape="{NS_INKSCAPE}" '
        f'version="1.1" width="{w}" height="{h}" viewBox="0 0 {w} {h}" '
        f'iso:format="{SVG_FORMAT_VERSION}" iso:width="{w}" iso:height="{h}" '
        f'iso:colour="{vi.colour}" iso:source-depth="{int(vi.source_depth)}">\n',
    ]
    if meta:
        out.append(f"<metadata><iso:meta>{_escape(meta)}</iso:meta></metadata>\n")
    for ch in vi.channels:
        fills = None
        if ch.name == "Y":
            fills, root, defs = _region_fills(ch, rgb)
            if defs:
                out.append("<defs>\n" + "".join(defs) + "</defs>\n")
            out.append(f'<rect width="{w}" height="{h}" fill="{root}"/>\n')
        out.extend(_channel_layer(ch, fills))
    out.append("</svg>\n")
    return "".join(out)


def from_svg(data) -> VectorImage:
    """Read an isophote SVG (str, or bytes: UTF-8 or gzip-compressed SVGZ) back.

    Edits made in a drawing program are honoured as the module docstring describes.
    Raises FormatError (LimitError for sizes over a limit) for anything that is not a valid
    isophote SVG; never another exception type for bad data.
    """
    if isinstance(data, (bytes, bytearray, memoryview)):
        data = _text_of(bytes(data))
    elif not isinstance(data, str):
        raise FormatError(f"expected SVG text or bytes, got {type(data).__name__}")
    return _guarded(lambda: _Reader().read(data))


def save_svg(vi: VectorImage, path, preview=None, compress=None) -> None:
    """Write ``vi`` as SVG to ``path`` atomically.

    ``compress`` None: gzip (SVGZ) when the name ends in ``.svgz``. The gzip stream is
    deterministic (mtime 0, no file name).
    """
    data = to_svg(vi, preview=preview).encode("utf-8")
    if compress is None:
        compress = os.fspath(path).lower().endswith(".svgz")
    if compress:
        data = gzip.compress(data, compresslevel=9, mtime=0)
    atomic_write_bytes(path, data)


def load_svg(path) -> VectorImage:
    """Read an isophote .svg or .svgz file (gzip is recognised by its magic, not its name)."""
    where = f"{os.fspath(path)}: "
    try:
        with open(path, "rb") as f:
            raw = f.read(MAX_SVG_BYTES + 1)
    except OSError as e:
        raise FormatError(f"{where}cannot read: {e.strerror or e}") from None
    try:
        return from_svg(raw)
    except LimitError as e:
        raise LimitError(f"{where}{e}") from None
    except FormatError as e:
        raise FormatError(f"{where}{e}") from None


def is_svg(head: bytes) -> bool:
    """Whether the first bytes of a file look like SVG or SVGZ (for format sniffing)."""
    if head[:2] == GZIP_MAGIC:
        return True
    text = head.lstrip(b"\xef\xbb\xbf \t\r\n")
    return text.startswith((b"<?xml", b"<svg", b"<!--", b"<!DOCTYPE svg"))


# =============================================================================================
# Writing
# =============================================================================================


def _check_image(vi) -> None:
    check_image_kind(vi, too_big=FormatError)
    for ch in vi.channels:
        label = ch.name
        levels = np.asarray(ch.levels)
        if levels.ndim != 1 or levels.shape[0] > MAX_LEVELS:
            raise FormatError(f"channel {label}: levels must be 1-D, at most {MAX_LEVELS}")
        _check_levels(levels, label)
        c = ch.contour_level.shape[0]
        offs = ch.offsets
        if offs.shape != (c + 1,) or offs[0] != 0 or offs[-1] != ch.points.shape[0]:
            raise FormatError(f"channel {label}: offsets do not match the points")
        sizes = np.diff(offs)
        if c and (sizes.min() < 4 or np.any((sizes - 1) % 3)):
            raise FormatError(f"channel {label}: every chain must have 1 + 3n points, n >= 1")
        if ch.border.shape != (int(((sizes - 1) // 3).sum()),):
            raise FormatError(f"channel {label}: border must have one flag per segment")
        if not np.all(np.isfinite(ch.points)) or (ch.points.size and np.abs(ch.points).max() >= MAX_COORD):
            raise FormatError(f"channel {label}: a control point is not finite or too far out")
        if c and not np.array_equal(ch.points[offs[:-1]], ch.points[offs[1:] - 1]):
            raise FormatError(f"channel {label}: a contour is not closed")
        k = ch.cap_band.shape[0]
        if ch.cap_contour.shape != (k,) or ch.cap_xy.shape != (k, 2) or ch.cap_value.shape != (k,):
            raise FormatError(f"channel {label}: cap arrays must all have K = {k} entries")
        if not (np.all(np.isfinite(ch.cap_xy)) and np.all(np.isfinite(ch.cap_value))):
            raise FormatError(f"channel {label}: a cap position or value is not finite")
        if k and (np.abs(ch.cap_xy).max() >= MAX_COORD or np.abs(ch.cap_value).max() >= MAX_CAP_VALUE):
            raise FormatError(f"channel {label}: a cap position or value is beyond the format's limits")
        if ch.parent.shape != (c,):
            raise FormatError(f"channel {label}: parent must have one entry per contour")
        _check_semantics(label, levels.shape[0], ch.contour_level.astype(np.int64),
                         ch.parent.astype(np.int64), ch.cap_band.astype(np.int64),
                         ch.cap_contour.astype(np.int64))
        if not 0 <= int(ch.base_band) <= levels.shape[0]:
            raise FormatError(f"channel {label}: base band {ch.base_band} is outside [0, {levels.shape[0]}]")
        if ch.tone is not None:
            _check_tone(np.asarray(ch.tone), label)
        _check_cap_ramp(ch.cap_ramp, label)


def _check_tone(tone: np.ndarray, label: str) -> None:
    """A tone curve as model.py defines it (FormatError otherwise)."""
    if tone.ndim != 2 or tone.shape[1] != 2 or not 2 <= tone.shape[0] <= MAX_TONE_KNOTS:
        raise FormatError(f"channel {label}: a tone curve must be 2 to {MAX_TONE_KNOTS} (x, y) knots")
    if not np.all(np.isfinite(tone)) or tone.min() < 0.0 or tone.max() > 255.0:
        raise FormatError(f"channel {label}: a tone knot is not finite or outside 0..255")
    if not (np.all(np.diff(tone[:, 0]) > 0) and np.all(np.diff(tone[:, 1]) >= 0)):
        raise FormatError(f"channel {label}: a tone curve must have x strictly increasing, y non-decreasing")


def _escape(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace('"', "&quot;")


def _num(v: float) -> str:
    """Shortest text that reads back as exactly v (integers without a point)."""
    v = float(v)
    if v == int(v) and abs(v) < 2**53:
        return str(int(v))
    return repr(v)


def _nums(a: np.ndarray) -> list:
    """_num of every value, fast for the integers."""
    a = np.asarray(a, np.float64)
    whole = (np.rint(a) == a) & (np.abs(a) < 2.0**53)
    out = list(map(str, np.where(whole, a, 0).astype(np.int64).tolist()))
    for i in np.flatnonzero(~whole).tolist():
        out[i] = repr(float(a[i]))
    return out


def _channel_layer(ch: Channel, fills) -> list:
    """The <g> layer of one channel, as a list of strings."""
    label = ch.name
    c = ch.n_contours
    q = ch.points * LOCAL_SCALE  # exact (power of two)
    attrs = [
        f'id="isophote-{label}" inkscape:groupmode="layer" inkscape:label="{label}"',
        f'transform="scale({1 / LOCAL_SCALE!r})" iso:channel="{label}"',
        f'iso:levels="{" ".join(repr(float(x)) for x in ch.levels)}" iso:base-band="{int(ch.base_band)}"',
    ]
    caps = _caps_text(ch, q)
    if caps:
        attrs.append(f'iso:caps="{caps}"')
    if ch.tone is not None:
        attrs.append(f'iso:tone="{" ".join(_nums(np.asarray(ch.tone, np.float64).reshape(-1)))}"')
    if float(ch.cap_ramp) != CAP_RAMP:
        attrs.append(f'iso:cap-ramp="{"dome" if math.isinf(ch.cap_ramp) else repr(float(ch.cap_ramp))}"')
    if fills is None:
        attrs.append(f'style="display:none" fill="none" stroke="{UV_STROKES.get(label, "#000")}" '
                     f'stroke-width="{LOCAL_SCALE // 4}"')
    else:
        attrs.append('stroke="none"')
    out = [f"<g {' '.join(attrs)}>\n"]
    if c == 0:
        out.append("</g>\n")
        return out
    d = _path_data(q, ch.offsets, ch.cap_xy * LOCAL_SCALE, ch.cap_contour)
    so = ch.segment_offsets()
    area = np.sign(_signed_areas(ch.points, ch.offsets)).astype(np.int64)
    nseg = np.diff(so).tolist()
    level, parent = ch.contour_level.tolist(), ch.parent.tolist()
    border = ch.border
    has_border = np.add.reduceat(border.astype(np.int64), so[:-1]) > 0 if border.size else np.zeros(c, bool)
    for k in _painter_order(ch.parent).tolist():
        a = f'<path iso:c="{k} {level[k]} {parent[k]} {area[k]} {nseg[k]}"'
        if has_border[k]:
            a += ' iso:b="' + "".join("1" if f else "0" for f in border[so[k]:so[k + 1]].tolist()) + '"'
        if fills is not None:
            a += f' fill="{fills[k]}"'
        out.append(f'{a} d="{d[k]}"/>\n')
    out.append("</g>\n")
    return out


def _path_data(q: np.ndarray, offsets: np.ndarray, cap_local: np.ndarray, cap_contour: np.ndarray) -> list:
    """Path data of every chain, in local units, followed by its caps' markers.

    On the integer grid: "Mx y" and relative integer 'c' commands, "z", then one relative
    "m dx dy" per cap (from the chain's start, then from the previous marker). Off the grid:
    absolute 'C' commands and absolute "M x y" markers with exact floats.
    """
    c = offsets.shape[0] - 1
    r = np.rint(q)
    on_grid = (r == q) & (np.abs(q) < 2.0**52)
    chain_ok = np.logical_and.reduceat(np.all(on_grid, axis=1), offsets[:-1])
    qi = r.astype(np.int64)
    nseg = (np.diff(offsets) - 1) // 3
    first = np.repeat(offsets[:-1], nseg) + 3 * (np.arange(int(nseg.sum())) - np.repeat(np.cumsum(nseg) - nseg, nseg))
    rel = qi[first[:, None] + np.arange(1, 4)[None, :]] - qi[first][:, None, :]  # (S, 3, 2)
    tokens = list(map(str, rel.reshape(-1).tolist()))
    starts = list(map(str, qi[offsets[:-1]].reshape(-1).tolist()))
    so = np.concatenate([[0], np.cumsum(nseg)]) * 6
    # the caps' markers, per contour in cap order: relative integer steps where possible
    order = np.argsort(cap_contour, kind="stable")
    order = order[cap_contour[order] >= 0]
    cc = cap_contour[order].astype(np.int64)
    mk = cap_local[order]
    mk_ok = np.all((np.rint(mk) == mk) & (np.abs(mk) < 2.0**52), axis=1)
    chain_ok[cc[~mk_ok]] = False
    mi = np.rint(mk).astype(np.int64)
    prev = np.empty_like(mi)
    prev[1:] = mi[:-1]
    first_of = np.r_[True, cc[1:] != cc[:-1]] if cc.size else np.zeros(0, bool)
    prev[first_of] = qi[offsets[cc[first_of]]]
    steps = (mi - prev).tolist()
    bounds = np.searchsorted(cc, np.arange(c + 1)).tolist()
    out = []
    for k in range(c):
        lo, hi = bounds[k], bounds[k + 1]
        if chain_ok[k]:
            s = f"M{starts[2 * k]} {starts[2 * k + 1]}c{' '.join(tokens[so[k]:so[k + 1]])}z"
            s += "".join(f"m{dx} {dy}" for dx, dy in steps[lo:hi])
        else:
            pts = q[offsets[k]:offsets[k + 1]]
            s = f"M{_num(pts[0, 0])} {_num(pts[0, 1])}C" + " ".join(_num(v) for v in pts[1:].reshape(-1)) + "z"
            s += "".join(f"M{_num(x)} {_num(y)}" for x, y in mk[lo:hi].tolist())
        out.append(s.replace(" -", "-"))
    return out


def _caps_text(ch: Channel, q: np.ndarray) -> str:
    """The iso:caps attribute text ('' when there are no caps).

    Five numbers per cap: contour, band, x, y, value. For the root region (contour -1),
    (x, y) is the position in the layer's units, exactly. For a contour's cap the position
    travels in the contour's path data (a marker); (x, y) is only a fallback for editors
    that drop markers: the offset from the contour's first point, to the nearest unit.
    """
    k = ch.cap_band.shape[0]
    if k == 0:
        return ""
    cc = ch.cap_contour.astype(np.int64)
    local = ch.cap_xy * LOCAL_SCALE
    inner = cc >= 0
    p0 = np.zeros((k, 2))
    p0[inner] = q[ch.offsets[cc[inner]]]
    xy = np.where(inner[:, None], np.rint(local - p0), local)
    cols = [list(map(str, cc.tolist())), list(map(str, ch.cap_band.tolist())),
            _nums(xy[:, 0]), _nums(xy[:, 1]), _nums(ch.cap_value)]
    return " ".join(" ".join(t) for t in zip(*cols))


def _painter_order(parent: np.ndarray) -> np.ndarray:
    """Contour indices with every parent before its children: stable by depth."""
    c = parent.shape[0]
    depth = np.full(c, -1, np.int64)
    par = parent.tolist()
    dl = depth.tolist()
    for k in range(c):
        path = []
        j = k
        while j >= 0 and dl[j] < 0:
            path.append(j)
            j = par[j]
        d = dl[j] if j >= 0 else -1
        for j in reversed(path):
            d += 1
            dl[j] = d
    return np.argsort(np.asarray(dl, np.int64), kind="stable")


def _signed_areas(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(C,) exact signed areas of the closed cubic chains (shoelace sign convention)."""
    c = offsets.shape[0] - 1
    if c == 0:
        return np.zeros(0)
    nseg = (np.diff(offsets) - 1) // 3
    first = np.repeat(offsets[:-1], nseg) + 3 * (np.arange(int(nseg.sum())) - np.repeat(np.cumsum(nseg) - nseg, nseg))
    p = [points[first + i] for i in range(4)]

    def cross(a, b):
        return a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]

    seg = (6 * cross(p[0], p[1]) + 3 * cross(p[0], p[2]) + cross(p[0], p[3])
           + 3 * cross(p[1], p[2]) + 3 * cross(p[1], p[3]) + 6 * cross(p[2], p[3])) / 20.0
    return np.bincount(np.repeat(np.arange(c), nseg), weights=seg, minlength=c)


# ---- the preview's colours ------------------------------------------------------------------


def _preview_rgb(vi: VectorImage, preview) -> np.ndarray:
    """(H, W, 3) float RGB (grey repeated) on 0..255 to take the region colours from."""
    if preview is None:
        from ..render import render_float

        preview = render_float(vi, fill="flat")
    a = np.asarray(preview, dtype=np.float64)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[:2] != (vi.height, vi.width):
        raise ValueError(f"preview must be ({vi.height}, {vi.width}[, C]), got {a.shape}")
    n = 1 if vi.colour == "grey" else 3
    if a.shape[2] < n:
        raise ValueError(f"preview needs {n} colour channel(s), got {a.shape[2]}")
    a = a[..., :n]
    return np.repeat(a, 3, axis=2) if n == 1 else a


def _region_fills(ch: Channel, rgb: np.ndarray):
    """The preview's fill of every Y contour's region and of the root region, and the
    gradients they use: (fills (C,) list of str, root fill, list of <linearGradient> texts).

    A region's fill is the mean of ``rgb`` over its pixels. Where the colour drifts across
    a region, a linear gradient does better: the rank-1 least-squares plane (one direction
    for all three colours, which is what an SVG linear gradient can show) replaces the mean
    when it removes at least GRADIENT_MIN_GAIN of squared error from the region. A few dozen
    large regions of a photograph qualify, and they carry most of the gain (astronaut:
    +2.4 dB for 74 gradients, about 10 KB).
    """
    h, w = rgb.shape[:2]
    c = ch.n_contours
    labels = _region_labels(ch, w, h)
    ok = ((labels >= -1) & (labels < c)).ravel()
    lab = labels.ravel()[ok] + 1
    vals = rgb.reshape(-1, 3)[ok]
    yy, xx = np.divmod(np.flatnonzero(ok), w)
    px, py = xx + 0.5, yy + 0.5
    m = c + 1
    count = np.bincount(lab, minlength=m).astype(np.float64)
    n1 = np.maximum(count, 1.0)
    means = np.stack([np.bincount(lab, weights=vals[:, i], minlength=m) for i in range(3)], 1) / n1[:, None]
    # regions too small to hold a pixel centre: the pixel under the contour's centroid
    for r in np.flatnonzero(count == 0).tolist():
        cx, cy = (w / 2, h / 2) if r == 0 else ch.chain(r - 1).mean(axis=0)
        means[r] = rgb[min(max(int(cy), 0), h - 1), min(max(int(cx), 0), w - 1)]

    # planar least squares per region: position moments and colour-position covariances
    cx = np.bincount(lab, weights=px, minlength=m) / n1
    cy = np.bincount(lab, weights=py, minlength=m) / n1
    dx, dy = px - cx[lab], py - cy[lab]
    sxx = np.bincount(lab, weights=dx * dx, minlength=m)
    sxy = np.bincount(lab, weights=dx * dy, minlength=m)
    syy = np.bincount(lab, weights=dy * dy, minlength=m)
    det = sxx * syy - sxy * sxy
    fit = (count >= 3) & (det > 1e-9 * np.maximum(sxx * syy, 1e-300))
    cov = np.zeros((m, 3, 2))
    for i in range(3):
        r = vals[:, i] - means[lab, i]
        cov[:, i, 0] = np.bincount(lab, weights=dx * r, minlength=m)
        cov[:, i, 1] = np.bincount(lab, weights=dy * r, minlength=m)
    safe = np.where(fit, det, 1.0)
    gx = (syy[:, None] * cov[:, :, 0] - sxy[:, None] * cov[:, :, 1]) / safe[:, None]
    gy = (sxx[:, None] * cov[:, :, 1] - sxy[:, None] * cov[:, :, 0]) / safe[:, None]
    gain = np.where(fit, (gx * cov[:, :, 0] + gy * cov[:, :, 1]).sum(axis=1), 0.0)

    rgb8 = np.clip(np.rint(means), 0, 255).astype(np.int64).tolist()
    fills = [f"#{r:02x}{g:02x}{b:02x}" for r, g, b in rgb8]
    defs = []
    tmin = np.full(m, np.inf)
    tmax = np.full(m, -np.inf)
    chosen = np.flatnonzero(gain >= GRADIENT_MIN_GAIN)
    dirs = {}
    for r in chosen.tolist():
        s = np.array([[sxx[r], sxy[r]], [sxy[r], syy[r]]]) / count[r]
        ev, vec = np.linalg.eigh(s)
        root_s = vec @ np.diag(np.sqrt(ev)) @ vec.T
        inv_root = vec @ np.diag(1.0 / np.sqrt(ev)) @ vec.T
        g = np.stack([gx[r], gy[r]], axis=1)  # (3, 2)
        u, sig, vt = np.linalg.svd(g @ root_s)
        n = inv_root @ vt[0]  # colour = mean + slope * (n . (p - centre))
        dirs[r] = (n, sig[0] * u[:, 0])
    if dirs:
        sel = np.isin(lab, chosen)
        lr = lab[sel]
        nn = np.zeros((m, 2))
        for r, (n, _) in dirs.items():
            nn[r] = n
        t = nn[lr, 0] * dx[sel] + nn[lr, 1] * dy[sel]
        np.minimum.at(tmin, lr, t)
        np.maximum.at(tmax, lr, t)
    for r, (n, slope) in dirs.items():
        if not tmax[r] > tmin[r]:
            continue
        nn2 = float(n @ n)
        a = np.array([cx[r], cy[r]]) + n * tmin[r] / nn2
        b = a + n * (tmax[r] - tmin[r]) / nn2
        scale = 1.0 if r == 0 else LOCAL_SCALE  # the root's rectangle is in pixels
        gid = f"isophote-g{r - 1}" if r else "isophote-groot"
        x1, y1 = a * scale
        x2, y2 = b * scale
        defs.append(
            f'<linearGradient id="{gid}" gradientUnits="userSpaceOnUse" x1="{x1:.2f}" y1="{y1:.2f}" '
            f'x2="{x2:.2f}" y2="{y2:.2f}"><stop offset="0" stop-color="{_hex(means[r] + slope * tmin[r])}"/>'
            f'<stop offset="1" stop-color="{_hex(means[r] + slope * tmax[r])}"/></linearGradient>\n'
        )
        fills[r] = f"url(#{gid})"
    return fills[1:], fills[0], defs


def _hex(rgb) -> str:
    r, g, b = np.clip(np.rint(rgb), 0, 255).astype(np.int64).tolist()
    return f"#{r:02x}{g:02x}{b:02x}"


def _region_labels(ch: Channel, width: int, height: int) -> np.ndarray:
    """(H, W) int64: at each pixel centre, the innermost contour whose footprint holds it
    (-1: the root region), as painter's-order filling shows it.

    Each crossing of contour k adds its winding (normalised to +1 inside) times
    ``(k + 1) - (parent + 1)``; along the nested footprints over a pixel the sum telescopes
    to innermost + 1. Where contours of a damaged file cross, the sum can fall outside
    [0, C]; callers skip such pixels.
    """
    c = ch.n_contours
    if c == 0:
        return np.full((height, width), -1, np.int64)
    x0, y0, x1, y1, k = _flatten(ch, tol=0.05)
    sign = -np.sign(_signed_areas(ch.points, ch.offsets))  # shoelace > 0: inside winds -1
    weight = sign * ((np.arange(c) + 1) - (ch.parent.astype(np.int64) + 1))
    down = y1 > y0
    lo, hi = np.where(down, y0, y1), np.where(down, y1, y0)
    dw = np.where(down, 1.0, -1.0) * weight[k]
    i0 = np.clip(np.ceil(lo - 0.5), 0, height).astype(np.int64)
    i1 = np.clip(np.ceil(hi - 0.5), 0, height).astype(np.int64)
    n = np.maximum(i1 - i0, 0)
    e = np.repeat(np.arange(x0.shape[0]), n)
    i = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n) + i0[e]
    yc = i + 0.5
    x = x0[e] + (yc - y0[e]) * (x1[e] - x0[e]) / (y1[e] - y0[e])
    j = np.clip(np.floor(x + 0.5), 0, width).astype(np.int64)
    delta = np.bincount(i * (width + 1) + j, weights=dw[e], minlength=height * (width + 1))
    acc = np.cumsum(delta.reshape(height, width + 1)[:, :width], axis=1)
    return np.rint(acc).astype(np.int64) - 1


def _flatten(ch: Channel, tol: float):
    """Line edges (x0, y0, x1, y1, contour) within ``tol`` px of the chains."""
    from ..geometry import MAX_STEPS, segments

    segs, _ = segments(ch)
    nseg = (np.diff(ch.offsets) - 1) // 3
    owner = np.repeat(np.arange(ch.n_contours), nseg)
    p0, p1, p2, p3 = segs[:, 0], segs[:, 1], segs[:, 2], segs[:, 3]
    dd = np.maximum(np.hypot(*(p0 - 2 * p1 + p2).T), np.hypot(*(p1 - 2 * p2 + p3).T))
    n = np.clip(np.ceil(np.sqrt(0.75 * dd / tol)), 1, MAX_STEPS).astype(np.int64)
    seg = np.repeat(np.arange(len(segs)), n)
    t = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)

    def point(tt, s):
        u = 1.0 - tt
        return ((u**3)[:, None] * p0[s] + (3 * u * u * tt)[:, None] * p1[s]
                + (3 * u * tt * tt)[:, None] * p2[s] + (tt**3)[:, None] * p3[s])

    a = point(t / n[seg], seg)
    b = point((t + 1) / n[seg], seg)
    first = t == 0
    a[first] = p0[seg[first]]
    last = t == n[seg] - 1
    b[last] = p3[seg[last]]
    return a[:, 0], a[:, 1], b[:, 0], b[:, 1], owner[seg]


# =============================================================================================
# Reading
# =============================================================================================

_NUMBER = r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
_NUM_RE = re.compile(_NUMBER)
_INT_RE = re.compile(r"[-+]?[0-9]+")
_PATH_TOKEN = re.compile(r"([MmZzLlHhVvCcSsQqTtAa])|(" + _NUMBER + ")")
_SEPARATORS = re.compile(r"[\s,]*")
_TRANSFORM = re.compile(r"[\s,]*(matrix|translate|scale|rotate|skewX|skewY)\s*\(([^()]*)\)[\s,]*")
_ARGS = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "A": 7, "Z": 0}
_IDENTITY = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)
_FEED_CHUNK = 1 << 20


def _text_of(raw: bytes) -> str:
    """Decoded SVG text of file bytes (gunzipped, bounded)."""
    if raw[:2] == GZIP_MAGIC:
        try:
            with gzip.GzipFile(fileobj=io.BytesIO(raw)) as g:
                raw = g.read(MAX_SVG_BYTES + 1)
        except (OSError, EOFError, zlib.error) as e:
            raise FormatError(f"SVGZ does not decompress ({e})") from None
    if len(raw) > MAX_SVG_BYTES:
        raise LimitError(f"SVG text exceeds the {MAX_SVG_BYTES}-byte limit")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise FormatError(f"SVG is not UTF-8 text ({e.reason} at byte {e.start})") from None


def _guarded(parse):
    try:
        return parse()
    except (FormatError, LimitError):
        raise
    except (ValueError, IndexError, KeyError, OverflowError, TypeError, RecursionError, ET.ParseError) as e:
        raise FormatError(f"malformed isophote SVG ({type(e).__name__}: {e})") from None


def _compose(p, c):
    """Affine p after c; tuples (a, b, c, d, e, f): x' = a x + c y + e, y' = b x + d y + f."""
    a1, b1, c1, d1, e1, f1 = p
    a2, b2, c2, d2, e2, f2 = c
    return (a1 * a2 + c1 * b2, b1 * a2 + d1 * b2, a1 * c2 + c1 * d2, b1 * c2 + d1 * d2,
            a1 * e2 + c1 * f2 + e1, b1 * e2 + d1 * f2 + f1)


def _apply(m, pts: np.ndarray) -> np.ndarray:
    if m == _IDENTITY:
        return pts
    a, b, c, d, e, f = m
    x, y = pts[:, 0], pts[:, 1]
    return np.stack([a * x + c * y + e, b * x + d * y + f], axis=1)


def _cos_sin(deg: float):
    """cos and sin of an angle in degrees, exact at multiples of 90."""
    q = deg / 90.0
    if q == int(q):
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(q) % 4]
    r = math.radians(deg)
    return math.cos(r), math.sin(r)


def parse_transform(text: str):
    """An SVG transform list as an affine tuple (see _compose). FormatError when malformed."""
    m = _IDENTITY
    pos = 0
    text = text.strip()
    while pos < len(text):
        t = _TRANSFORM.match(text, pos)
        if t is None or t.end() == pos:
            raise FormatError(f"malformed transform {text[:60]!r}")
        pos = t.end()
        name, body = t.group(1), t.group(2)
        if _NUM_RE.sub("", body).strip(" \t\r\n,"):
            raise FormatError(f"malformed transform arguments {body[:60]!r}")
        args = [float(v) for v in _NUM_RE.findall(body)]
        if not all(math.isfinite(v) for v in args):
            raise FormatError("a transform argument is not finite")
        n = len(args)
        if name == "matrix" and n == 6:
            step = tuple(args)
        elif name == "translate" and n in (1, 2):
            step = (1.0, 0.0, 0.0, 1.0, args[0], args[1] if n == 2 else 0.0)
        elif name == "scale" and n in (1, 2):
            step = (args[0], 0.0, 0.0, args[1] if n == 2 else args[0], 0.0, 0.0)
        elif name == "rotate" and n in (1, 3):
            cs, sn = _cos_sin(args[0])
            step = (cs, sn, -sn, cs, 0.0, 0.0)
            if n == 3:
                cx, cy = args[1], args[2]
                step = _compose(_compose((1.0, 0.0, 0.0, 1.0, cx, cy), step), (1.0, 0.0, 0.0, 1.0, -cx, -cy))
        elif name == "skewX" and n == 1:
            step = (1.0, 0.0, math.tan(math.radians(args[0])), 1.0, 0.0, 0.0)
        elif name == "skewY" and n == 1:
            step = (1.0, math.tan(math.radians(args[0])), 0.0, 1.0, 0.0, 0.0)
        else:
            raise FormatError(f"transform {name} takes other arguments than {n}")
        m = _compose(m, step)
    if not all(math.isfinite(v) for v in m):
        raise FormatError("a transform is not finite")
    return m


def parse_path(d: str) -> list:
    """SVG path data as a list of subpaths, each a (1 + 3n, 2) float64 chain of cubics
    (absolute coordinates; lines, quadratics and arcs converted; every subpath closed by a
    line to its start where it does not end there). Subpaths that draw nothing are left
    out. FormatError when malformed."""
    return _parse_path(d)[0]


def _parse_path(d: str):
    """(subpaths as parse_path gives them, (m, 2) points of the subpaths that draw nothing:
    the markers that carry a contour's caps)."""
    tokens = _PATH_TOKEN.findall(d)
    if _PATH_TOKEN.sub("", d).strip(" \t\r\n\f,"):
        raise FormatError(f"malformed path data near {d[:40]!r}")
    subpaths = []
    markers = []
    cur = np.zeros(2)
    start = np.zeros(2)
    segs = []  # arrays (n, 3, 2) of the current subpath
    last_c = None  # previous cubic's second control point (for S)
    last_q = None  # previous quadratic's control point (for T)
    pos = 0
    n_tok = len(tokens)
    started = False  # a moveto began a subpath that finish() has not ended yet

    def finish():
        nonlocal segs, started
        body = np.concatenate(segs).reshape(-1, 2) if segs else np.zeros((0, 2))
        if body.shape[0]:
            end = body[-1]
            scale = max(1.0, float(np.abs(body).max()), float(np.abs(start).max()))
            if not np.array_equal(end, start):
                if np.abs(end - start).max() <= CLOSE_SNAP * scale:
                    body[-1] = start
                else:
                    body = np.vstack([body, _line(end, start).reshape(-1, 2)])
            subpaths.append(np.vstack([start[None, :], body]))
        elif started:
            markers.append(start.copy())
        segs = []
        started = False

    while pos < n_tok:
        cmd = tokens[pos][0]
        if not cmd:
            raise FormatError("path data must start with a command")
        pos += 1
        nums = []
        while pos < n_tok and not tokens[pos][0]:
            nums.append(tokens[pos][1])
            pos += 1
        up = cmd.upper()
        rel = cmd != up
        na = _ARGS[up]
        if up == "Z":
            if nums:
                raise FormatError("numbers after a closepath")
            finish()
            cur = start.copy()
            last_c = last_q = None
            continue
        if up == "A":
            nums = _split_arc_flags(nums)
        if not nums or len(nums) % na:
            raise FormatError(f"path command {cmd} needs a multiple of {na} numbers, got {len(nums)}")
        v = np.array([float(x) for x in nums], dtype=np.float64)
        if not np.all(np.isfinite(v)):
            raise FormatError("a path coordinate is not finite")
        v = v.reshape(-1, na)
        if up == "M":
            finish()
            started = True
            p = v[0] + (cur if rel else 0.0)
            cur = p.copy()
            start = p.copy()
            last_c = last_q = None
            if len(v) > 1:  # further pairs are implicit lines
                cur = _lines(segs, cur, v[1:], rel)
            continue
        if up == "C":
            r = v.reshape(-1, 3, 2)
            if rel:
                ends = cur + np.cumsum(r[:, 2], axis=0)
                starts = np.vstack([cur[None, :], ends[:-1]])
                r = starts[:, None, :] + r
            segs.append(r)
            cur = r[-1, 2].copy()
            last_c, last_q = r[-1, 1].copy(), None
            continue
        if up in ("L", "H", "V"):
            if up == "H":
                v = np.stack([v[:, 0], np.zeros(len(v)) if rel else np.full(len(v), np.nan)], 1)
            elif up == "V":
                v = np.stack([np.zeros(len(v)) if rel else np.full(len(v), np.nan), v[:, 0]], 1)
            cur = _lines(segs, cur, v, rel)
            last_c = last_q = None
            continue
        for row in v:  # S, Q, T, A: one at a time
            if up == "S":
                c1 = 2 * cur - last_c if last_c is not None else cur.copy()
                c2 = row[0:2] + (cur if rel else 0.0)
                p = row[2:4] + (cur if rel else 0.0)
                segs.append(np.stack([c1, c2, p])[None])
                last_c, last_q = c2, None
            elif up in ("Q", "T"):
                if up == "Q":
                    qc = row[0:2] + (cur if rel else 0.0)
                    p = row[2:4] + (cur if rel else 0.0)
                else:
                    qc = 2 * cur - last_q if last_q is not None else cur.copy()
                    p = row[0:2] + (cur if rel else 0.0)
                segs.append(np.stack([cur + 2.0 / 3.0 * (qc - cur), p + 2.0 / 3.0 * (qc - p), p])[None])
                last_c, last_q = None, qc
            else:
                p = row[5:7] + (cur if rel else 0.0)
                segs.append(_arc(cur, row[0], row[1], row[2], row[3] != 0, row[4] != 0, p))
                last_c = last_q = None
            cur = p.copy()
    finish()
    return subpaths, np.array(markers, np.float64).reshape(-1, 2)


_CANON_RE = re.compile(r"M(-?[0-9]{1,12}) (-?[0-9]{1,12})c([-0-9 ]+)z((?:m-?[0-9]{1,12}(?: |(?=-))-?[0-9]{1,12})*)")
_CONTOUR_RE = re.compile(r"(-?[0-9]{1,12}) (-?[0-9]{1,12}) (-?[0-9]{1,12}) (-?[0-9]{1,12}) (-?[0-9]{1,12})")
_CANON_MARK = re.compile(r"m(-?[0-9]+) ?(-?[0-9]+)")


def _canonical_chain_parts(d: str):
    """(start x, start y, relative integers (list, 6 per segment), markers (list of (x, y)))
    of path data laid out as the writer lays out a chain on the integer grid
    ("Mx yc<integers>z" ending on its start, then relative "m" markers), or None for
    anything else (the general parser then decides). Plain Python: it runs once per path."""
    m = _CANON_RE.fullmatch(d)
    if m is None:
        return None
    try:
        vals = list(map(int, m.group(3).replace("-", " -").split()))
    except ValueError:
        return None
    if not vals or len(vals) % 6 or sum(vals[4::6]) != 0 or sum(vals[5::6]) != 0:
        return None  # not whole segments, or does not end on its start
    x, y = int(m.group(1)), int(m.group(2))
    if max(max(vals), -min(vals), abs(x), abs(y)) >= COORD_LIMIT:
        return None  # the general parser reports what is out of range
    markers = []
    mx, my = x, y
    for a, b in _CANON_MARK.findall(m.group(4)):
        mx, my = mx + int(a), my + int(b)
        if max(abs(mx), abs(my)) >= COORD_LIMIT:
            return None
        markers.append((float(mx), float(my)))
    return x, y, vals, markers


def _canonical_chains(items: list) -> list:
    """The chains of many _canonical_chain_parts results, at once."""
    if not items:
        return []
    counts = np.array([len(t[2]) // 6 for t in items], np.int64)
    rel = np.array([v for t in items for v in t[2]], np.int64).reshape(-1, 3, 2)
    starts = np.array([(t[0], t[1]) for t in items], np.int64)
    owner = np.repeat(np.arange(len(items)), counts)
    first = np.cumsum(counts) - counts
    cs = np.cumsum(rel[:, 2], axis=0)  # |sum| < 2**28 * 2**30: no overflow
    before = cs[first] - rel[first, 2]
    ends = starts[owner] + cs - before[owner]
    seg_start = np.empty_like(ends)
    seg_start[1:] = ends[:-1]
    seg_start[first] = starts
    pts = np.empty((len(items) + 3 * rel.shape[0], 2), np.int64)
    pos = first * 3 + np.arange(len(items))  # each chain's first point
    pts[pos] = starts
    at = pos[owner] + 1 + 3 * (np.arange(rel.shape[0]) - first[owner])
    for j in range(3):
        pts[at + j] = seg_start + rel[:, j]
    return np.split(pts.astype(np.float64), pos[1:])


def _split_arc_flags(nums: list) -> list:
    """Arc arguments with flags written without separators ('a1 1 0 011 5') split."""
    out = []
    i = 0
    toks = list(nums)
    while i < len(toks):
        slot = len(out) % 7
        t = toks[i]
        if slot in (3, 4) and len(t) > 1 and t[0] in "01" and t[1:] and t[1] not in ".eE":
            out.append(t[0])
            toks[i] = t[1:]
            continue
        if slot in (3, 4) and t not in ("0", "1"):
            raise FormatError(f"arc flag must be 0 or 1, got {t!r}")
        out.append(t)
        i += 1
    return out


def _line(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(1, 3, 2): the straight cubic from a to b (controls at thirds)."""
    d = b - a
    return np.stack([a + d / 3.0, a + 2.0 * d / 3.0, b])[None]


def _lines(segs: list, cur: np.ndarray, v: np.ndarray, rel: bool) -> np.ndarray:
    """Append straight cubics through the points v (NaN: keep the current coordinate)."""
    for row in v:
        p = np.where(np.isnan(row), cur, row + (cur if rel else 0.0))
        segs.append(_line(cur, p))
        cur = p
    return cur


def _arc(p0, rx, ry, phi_deg, large, sweep, p1) -> np.ndarray:
    """(n, 3, 2) cubics of an SVG elliptical arc (SVG 1.1 F.6.5 endpoint to centre)."""
    rx, ry = abs(rx), abs(ry)
    if rx == 0 or ry == 0 or np.array_equal(p0, p1):
        return _line(p0, p1) if not np.array_equal(p0, p1) else np.zeros((0, 3, 2))
    cs, sn = _cos_sin(phi_deg)
    dx, dy = (p0 - p1) / 2.0
    x1 = cs * dx + sn * dy
    y1 = -sn * dx + cs * dy
    lam = (x1 / rx) ** 2 + (y1 / ry) ** 2
    if lam > 1:
        rx, ry = rx * math.sqrt(lam), ry * math.sqrt(lam)
    num = rx * rx * ry * ry - rx * rx * y1 * y1 - ry * ry * x1 * x1
    den = rx * rx * y1 * y1 + ry * ry * x1 * x1
    co = math.sqrt(max(0.0, num / den)) if den > 0 else 0.0
    if large == sweep:
        co = -co
    cxp, cyp = co * rx * y1 / ry, -co * ry * x1 / rx
    cx = cs * cxp - sn * cyp + (p0[0] + p1[0]) / 2
    cy = sn * cxp + cs * cyp + (p0[1] + p1[1]) / 2

    def ang(ux, uy, vx, vy):
        return math.atan2(ux * vy - uy * vx, ux * vx + uy * vy)

    t1 = ang(1, 0, (x1 - cxp) / rx, (y1 - cyp) / ry)
    dt = ang((x1 - cxp) / rx, (y1 - cyp) / ry, (-x1 - cxp) / rx, (-y1 - cyp) / ry)
    if not sweep and dt > 0:
        dt -= 2 * math.pi
    elif sweep and dt < 0:
        dt += 2 * math.pi
    n = max(1, int(math.ceil(abs(dt) / (math.pi / 2) - 1e-9)))
    h = dt / n
    kappa = 4.0 / 3.0 * math.tan(h / 4)
    out = np.empty((n, 3, 2))

    def pt(t):
        return np.array([cx + rx * math.cos(t) * cs - ry * math.sin(t) * sn,
                         cy + rx * math.cos(t) * sn + ry * math.sin(t) * cs])

    def deriv(t):
        return np.array([-rx * math.sin(t) * cs - ry * math.cos(t) * sn,
                         -rx * math.sin(t) * sn + ry * math.cos(t) * cs])

    for i in range(n):
        a, b = t1 + i * h, t1 + (i + 1) * h
        out[i, 0] = pt(a) + kappa * deriv(a)
        out[i, 1] = pt(b) - kappa * deriv(b)
        out[i, 2] = pt(b)
    out[-1, 2] = p1
    return out


def _attr_ints(text: str, what: str) -> list:
    parts = text.split()
    if not all(_INT_RE.fullmatch(p) for p in parts):
        raise FormatError(f"{what} must be integers, got {text[:60]!r}")
    return [int(p) for p in parts]


def _attr_floats(text: str, what: str) -> list:
    parts = text.split()
    if not all(_NUM_RE.fullmatch(p) for p in parts):
        raise FormatError(f"{what} must be numbers, got {text[:60]!r}")
    vals = [float(p) for p in parts]
    if not all(math.isfinite(v) for v in vals):
        raise FormatError(f"{what}: a number is not finite")
    return vals


def _one_chain(d: str, label: str, k: int):
    """(chain, markers) of a contour's path data, by the general parser."""
    subs, markers = _parse_path(d)
    if len(subs) != 1:
        raise FormatError(f"channel {label}: contour {k} draws {len(subs)} subpaths, not one closed chain")
    return subs[0], markers


class _ChannelData:
    """What the reader gathers for one channel layer."""

    def __init__(self, name, levels, base_band, caps, group_m, tone=None, cap_ramp=CAP_RAMP):
        self.name, self.levels, self.base_band = name, levels, base_band
        self.caps, self.group_m, self.tone, self.cap_ramp = caps, group_m, tone, cap_ramp
        # k -> [chain (None until built), level, parent, area sign, segments as written,
        #       border text, matrix, canonical parts, markers]
        self.contours = {}
        self.n_segments = 0


class _Reader:
    def read(self, text: str) -> VectorImage:
        if len(text) > MAX_SVG_BYTES:
            raise LimitError(f"SVG text exceeds the {MAX_SVG_BYTES}-byte limit")
        if "<!ENTITY" in text:
            raise FormatError("SVG declares XML entities (refused: entity expansion is not allowed)")
        parser = ET.XMLPullParser(events=("start", "end"))
        self.stack = []  # (matrix, channel) per open element
        self.root = None
        self.meta_text = None
        self.channels = []
        try:
            for i in range(0, len(text), _FEED_CHUNK):
                parser.feed(text[i:i + _FEED_CHUNK])
                self._events(parser)
            parser.close()
            self._events(parser)
        except ET.ParseError as e:
            raise FormatError(f"not well-formed XML ({e})") from None
        if self.root is None:
            raise FormatError("empty document")
        return self._image()

    def _events(self, parser) -> None:
        for event, el in parser.read_events():
            if event == "start":
                self._start(el)
            else:
                self.stack.pop()
                if el.tag == _I + "meta":
                    if self.meta_text is not None:
                        raise FormatError("more than one iso:meta element")
                    self.meta_text = "".join(el.itertext())
                el.clear()

    def _start(self, el) -> None:
        if self.root is None:
            self._root(el)
            self.stack.append((_IDENTITY, None))
            return
        m, chan = self.stack[-1]
        t = el.get("transform")
        if t is not None:
            m = _compose(m, parse_transform(t))
        name = el.get(_I + "channel")
        if name is not None:
            if chan is not None:
                raise FormatError(f"channel layer {name} lies inside channel layer {chan.name}")
            chan = self._channel(el, name, m)
        self.stack.append((m, chan))
        c = el.get(_I + "c")
        if c is not None:
            if el.tag != _S + "path":
                raise FormatError(f"an isophote contour must be a <path>, found <{el.tag.split('}')[-1]}>")
            if chan is None:
                raise FormatError("a contour path lies outside every channel layer")
            self._contour(el, c, chan, m)

    def _root(self, el) -> None:
        if el.tag != _S + "svg":
            ns, _, tag = el.tag[1:].partition("}") if el.tag.startswith("{") else ("", "", el.tag)
            raise FormatError(f"root element <{tag}> is not an SVG <svg> (namespace: {ns or 'none'})")
        version = el.get(_I + "format")
        if version is None:
            raise FormatError("not an isophote SVG (no iso:format attribute on the root)")
        if version != str(SVG_FORMAT_VERSION):
            raise FormatError(f"unsupported isophote SVG format {version!r} (this reader knows {SVG_FORMAT_VERSION})")
        self.root = el
        vals = {}
        for key in ("width", "height", "source-depth"):
            v = el.get(_I + key, "")
            if not _INT_RE.fullmatch(v.strip()):
                raise FormatError(f"iso:{key} must be an integer, got {v[:20]!r}")
            vals[key] = int(v)
        self.width, self.height, self.depth = vals["width"], vals["height"], vals["source-depth"]
        if self.width < 1 or self.height < 1:
            raise FormatError(f"image size {self.width} x {self.height} is empty")
        if self.width > MAX_WIDTH or self.height > MAX_HEIGHT:
            raise LimitError(f"image size {self.width} x {self.height} exceeds the {MAX_WIDTH} x {MAX_HEIGHT} limit")
        if self.depth not in SOURCE_DEPTHS:
            raise FormatError(f"source depth {self.depth} is not 8 or 16")
        self.colour = el.get(_I + "colour")
        if self.colour not in COLOUR_CODES:
            raise FormatError(f"unknown colour {self.colour!r} (grey or yuv)")

    def _channel(self, el, name, m) -> _ChannelData:
        if any(ch.name == name for ch in self.channels):
            raise FormatError(f"channel {name!r} appears twice")
        if name not in ("Y", "U", "V", "A"):
            raise FormatError(f"unknown channel {name[:10]!r}")
        levels = np.array(_attr_floats(el.get(_I + "levels", ""), f"channel {name} levels"), np.float64)
        if levels.shape[0] > MAX_LEVELS:
            raise LimitError(f"channel {name}: {levels.shape[0]} levels exceed the limit of {MAX_LEVELS}")
        _check_levels(levels, name)
        bb = _attr_ints(el.get(_I + "base-band", ""), f"channel {name} base band")
        if len(bb) != 1 or not 0 <= bb[0] <= levels.shape[0]:
            raise FormatError(f"channel {name}: base band must be one integer in [0, {levels.shape[0]}]")
        caps = _attr_floats(el.get(_I + "caps", ""), f"channel {name} caps")
        if len(caps) % 5:
            raise FormatError(f"channel {name}: caps must come in fives (contour band dx dy value)")
        if len(caps) // 5 > MAX_CAPS:
            raise LimitError(f"channel {name}: {len(caps) // 5} caps exceed the limit of {MAX_CAPS}")
        caps = np.array(caps, np.float64).reshape(-1, 5)
        if not (np.all(caps[:, :2] == np.rint(caps[:, :2])) and np.all(np.abs(caps[:, :2]) < 2**31)):
            raise FormatError(f"channel {name}: a cap's contour or band is not an integer")
        tone = None
        if el.get(_I + "tone") is not None:
            knots = _attr_floats(el.get(_I + "tone"), f"channel {name} tone")
            if len(knots) % 2:
                raise FormatError(f"channel {name}: tone knots must come in pairs (x y)")
            if len(knots) // 2 > MAX_TONE_KNOTS:
                raise LimitError(f"channel {name}: {len(knots) // 2} tone knots exceed the limit of {MAX_TONE_KNOTS}")
            tone = np.array(knots, np.float64).reshape(-1, 2)
            _check_tone(tone, name)
        cap_ramp = CAP_RAMP
        if el.get(_I + "cap-ramp") is not None:
            text = el.get(_I + "cap-ramp").strip()
            ramp = [DOME] if text == "dome" else _attr_floats(text, f"channel {name} cap ramp")
            if len(ramp) != 1:
                raise FormatError(f"channel {name}: iso:cap-ramp must be one number or \"dome\"")
            cap_ramp = _check_cap_ramp(ramp[0], name)
        ch = _ChannelData(name, levels, bb[0], caps, m, tone, cap_ramp)
        self.channels.append(ch)
        return ch

    def _contour(self, el, text, chan: _ChannelData, m) -> None:
        fast = _CONTOUR_RE.fullmatch(text)
        vals = list(map(int, fast.groups())) if fast else _attr_ints(text, f"channel {chan.name} iso:c")
        if len(vals) != 5:
            raise FormatError(f"channel {chan.name}: iso:c must hold k, level, parent, orientation, segments")
        k, level, parent, area, written = vals
        if k < 0 or k in chan.contours:
            raise FormatError(f"channel {chan.name}: contour {k} is negative or appears twice")
        d = el.get("d", "")
        parts = _canonical_chain_parts(d)
        if parts is None:
            chain, markers = _one_chain(d, chan.name, k)
            chan.n_segments += (chain.shape[0] - 1) // 3
        else:
            chain, markers = None, parts[3]  # the chain is built with the channel's others
            chan.n_segments += len(parts[2]) // 6
        if chan.n_segments > MAX_SEGMENTS:
            raise LimitError(f"channel {chan.name}: more than {MAX_SEGMENTS} segments")
        chan.contours[k] = [chain, level, parent, area, written, el.get(_I + "b"), m, parts, markers]

    def _image(self) -> VectorImage:
        names = tuple(ch.name for ch in self.channels)
        if names not in CHANNEL_LAYOUTS[self.colour]:
            raise FormatError(f"channels {','.join(names) or 'none'} do not fit colour {self.colour!r}")
        meta = {}
        if self.meta_text is not None:
            b = self.meta_text.encode("utf-8")
            if len(b) > MAX_META_BYTES:
                raise LimitError(f"meta of {len(b)} bytes exceeds the {MAX_META_BYTES}-byte limit")
            meta = _parse_meta(b)
        channels = tuple(self._build(ch) for ch in self.channels)
        return VectorImage(width=self.width, height=self.height, colour=self.colour,
                           channels=channels, source_depth=self.depth, meta=meta)

    def _build(self, cd: _ChannelData) -> Channel:
        label = cd.name
        keys = sorted(cd.contours)
        index = {k: i for i, k in enumerate(keys)}  # deleted contours: the rest renumbered
        c = len(keys)
        entries = [cd.contours[k] for k in keys]
        pending = [e for e in entries if e[0] is None]
        for e, chain in zip(pending, _canonical_chains([e[7] for e in pending])):
            e[0], e[7] = chain, None
        offsets = np.zeros(c + 1, np.int64)
        if c:
            np.cumsum([e[0].shape[0] for e in entries], out=offsets[1:])
        points = np.concatenate([e[0] for e in entries]) if c else np.zeros((0, 2), np.float64)
        # the transforms, one affine map per distinct matrix (usually one for the layer)
        mats = [e[6] for e in entries]
        owner = np.repeat(np.arange(c), np.diff(offsets))
        if c:
            mm = np.array(mats, np.float64)[owner]  # (P, 6): each point's affine map
            x, y = points[:, 0].copy(), points[:, 1].copy()
            points[:, 0] = mm[:, 0] * x + mm[:, 2] * y + mm[:, 4]
            points[:, 1] = mm[:, 1] * x + mm[:, 3] * y + mm[:, 5]
        if points.size and (not np.all(np.isfinite(points)) or np.abs(points).max() >= MAX_COORD):
            raise LimitError(f"channel {label}: a contour lies beyond the coordinate limit of +-{MAX_COORD:g}")
        so = (offsets - np.arange(c + 1)) // 3
        border = np.zeros(int(so[-1]), bool)
        for i, e in enumerate(entries):
            written, btext = e[4], e[5]
            nseg = int(so[i + 1] - so[i])
            if nseg != written:  # reshaped: the frame decides which segments are border
                border[so[i]:so[i + 1]] = self._frame_segments(points[offsets[i]:offsets[i + 1]])
            elif btext is not None:
                if len(btext) != nseg or btext.strip("01"):
                    raise FormatError(f"channel {label}: border flags of contour {keys[i]} are not {nseg} 0s and 1s")
                border[so[i]:so[i + 1]] = np.frombuffer(btext.encode("ascii"), np.uint8) == ord("1")
        # a contour whose area changed sign (mirrored, reversed) is turned back
        stored = np.array([e[3] for e in entries], np.int64)
        now = np.sign(_signed_areas(points, offsets)).astype(np.int64)
        for i in np.flatnonzero((stored != 0) & (now == -np.sign(stored))).tolist():
            points[offsets[i]:offsets[i + 1]] = points[offsets[i]:offsets[i + 1]][::-1]
            border[so[i]:so[i + 1]] = border[so[i]:so[i + 1]][::-1]
        levels = [e[1] for e in entries]
        parents = [index.get(e[2], -1) if e[2] >= 0 else e[2] for e in entries]
        level = np.array(levels, np.int64)
        parent = np.array(parents, np.int64)

        caps = cd.caps
        cc_old = caps[:, 0].astype(np.int64)
        keep = (cc_old < 0) | np.isin(cc_old, np.array(keys, np.int64))
        cap_contour = np.array([index.get(int(v), -1) if v >= 0 else -1 for v in cc_old.tolist()], np.int64)
        cap_contour[cc_old < -1] = -2  # reported as out of range below
        cap_xy = _apply(cd.group_m, caps[:, 2:4]) if caps.size else np.zeros((0, 2))
        # a contour's caps ride in its path data as markers, through any transform or
        # rewrite; where an editor dropped or added markers, the fallback offsets serve
        rows, src, owner_m, fallback = [], [], [], []
        by_contour = {}
        for i, j in enumerate(cap_contour.tolist()):
            if j >= 0:
                by_contour.setdefault(j, []).append(i)
        for j, members in by_contour.items():
            if len(entries[j][8]) == len(members):
                rows.extend(members)
                src.append(np.asarray(entries[j][8], np.float64).reshape(-1, 2))
                owner_m.extend([j] * len(members))
            else:
                fallback.extend(members)
        if rows:
            mm = np.array(mats, np.float64)[owner_m]
            p = np.concatenate(src)
            cap_xy[rows] = np.stack([mm[:, 0] * p[:, 0] + mm[:, 2] * p[:, 1] + mm[:, 4],
                                     mm[:, 1] * p[:, 0] + mm[:, 3] * p[:, 1] + mm[:, 5]], axis=1)
        if fallback:
            j = cap_contour[fallback]
            mm = np.array(mats, np.float64)[j]
            off = caps[fallback, 2:4]
            cap_xy[fallback] = points[offsets[j]] + np.stack(
                [mm[:, 0] * off[:, 0] + mm[:, 2] * off[:, 1], mm[:, 1] * off[:, 0] + mm[:, 3] * off[:, 1]], axis=1)
        cap_band = caps[:, 1].astype(np.int64)
        cap_value = caps[:, 4].copy()
        cap_contour, cap_band, cap_xy, cap_value = cap_contour[keep], cap_band[keep], cap_xy[keep], cap_value[keep]
        _check_semantics(label, cd.levels.shape[0], level, parent, cap_band, cap_contour)
        if cap_xy.size and (not np.all(np.isfinite(cap_xy)) or np.abs(cap_xy).max() >= MAX_COORD):
            raise LimitError(f"channel {label}: a cap position lies beyond the coordinate limit")
        if cap_value.size and np.abs(cap_value).max() >= MAX_CAP_VALUE:
            raise FormatError(f"channel {label}: a cap value lies beyond the limit of +-{MAX_CAP_VALUE:g}")
        return Channel(
            name=label,
            levels=cd.levels,
            contour_level=level.astype(np.int32),
            offsets=offsets,
            points=np.ascontiguousarray(points, dtype=np.float64),
            border=border,
            parent=parent.astype(np.int32),
            cap_band=cap_band.astype(np.int32),
            cap_contour=cap_contour.astype(np.int32),
            cap_xy=cap_xy.astype(np.float64),
            cap_value=cap_value.astype(np.float64),
            base_band=int(cd.base_band),
            tone=cd.tone,
            cap_ramp=cd.cap_ramp,
        )

    def _frame_segments(self, chain: np.ndarray) -> np.ndarray:
        """Segments whose four control points lie on one edge of the frame."""
        n = (chain.shape[0] - 1) // 3
        idx = 3 * np.arange(n)[:, None] + np.arange(4)[None, :]
        s = chain[idx]  # (n, 4, 2)
        tol = 1e-6 * max(self.width, self.height)
        out = np.zeros(n, bool)
        for axis, v in ((0, 0.0), (0, float(self.width)), (1, 0.0), (1, float(self.height))):
            out |= np.all(np.abs(s[:, :, axis] - v) <= tol, axis=1)
        return out
