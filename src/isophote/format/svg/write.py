"""The isophote SVG writer: ``to_svg`` and ``save_svg`` (the profile: format/svg/__init__.py)."""

from __future__ import annotations

import gzip
import json
import math
import os

import numpy as np

from ...errors import FormatError, LimitError
from ...imageio import atomic_write_bytes
from ...model import CAP_RAMP, Channel, VectorImage
from ..limits import MAX_LEVELS, SVG_FORMAT_VERSION
from ..validate import check_cap_ramp, check_image_kind, check_levels, check_semantics, meta_bytes
from ...geometry import signed_areas
from . import polyline
from .preview import FILTER_ID, PREVIEW_ID, filter_def, icc_affine, layer_offset, paints
from .profile import LOCAL_SCALE, MAX_CAP_VALUE, MAX_COORD, NS_INKSCAPE, NS_ISO, NS_SVG, UV_STROKES, check_svg_tone


def to_svg(vi: VectorImage, crisp: bool = True, lines: bool = True) -> str:
    """The isophote SVG document of ``vi`` (see the module docstring).

    Parameters
    ----------
    vi : VectorImage
    crisp : bool
        Ask viewers not to anti-alias the preview's region edges
        (``shape-rendering="crispEdges"``, the default): each pixel shows the region at its
        centre, as isophote's flat-fill render at 1x does. False: anti-aliased edges, softer
        to look at but further from the photograph where many contours share an edge (each
        nested contour's partial coverage paints over the last, so a sharp edge creeps
        outwards: see benchmarks/results/svg_preview.md).
    lines : bool
        Paint the preview as polylines (polyline.py; the default): viewers flatten cubics too
        coarsely to show dense contours as the flat render does. The contours' cubic paths
        (the data) then sit in hidden layers. False: the data paths themselves are painted
        (a smaller file, the layers an editor shows, about 1-1.7 dB further from the flat
        render on dense photographs in resvg and Chromium).

    Returns
    -------
    str
        Deterministic for a given image.

    Raises
    ------
    ValueError
        ``vi`` breaks the data model.
    """
    try:
        _check_image(vi)
        # canonical JSON (sorted keys), then ASCII only: every character is legal in XML
        meta = json.dumps(json.loads(meta_bytes(vi.meta)), sort_keys=True, separators=(",", ":")) if vi.meta else ""
    except (FormatError, LimitError) as e:
        raise ValueError(f"cannot write SVG: {e}") from None
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
    yuv = vi.colour == "yuv"
    shown = [ch for ch in vi.channels if ch.name in ("Y", "U", "V")]
    offsets = {ch.name: layer_offset(ch, w, h) if yuv else 0.0 for ch in shown}
    if yuv:
        out.append("<defs>\n" + filter_def(w, h, icc_affine(vi), [offsets.get(c, 0.0) for c in "YUV"])
                   + "</defs>\n")
    edges = ' shape-rendering="crispEdges"' if crisp else ""
    group = f'<g filter="url(#{FILTER_ID})"{edges}>\n' if yuv else f"<g{edges}>\n"
    if lines:
        out.append(group.replace("<g", f'<g id="{PREVIEW_ID}"', 1))
        for ch in shown:
            out.extend(_preview_layer(ch, paints(ch, vi.colour, offsets[ch.name]), w, h))
        out.append("</g>\n")
        for ch in vi.channels:
            out.extend(_channel_layer(ch, None, w, h))
    else:
        out.append(group)
        for ch in vi.channels:
            if ch.name == "A":
                out.append("</g>\n")
            shown_here = ch.name in offsets
            out.extend(_channel_layer(ch, paints(ch, vi.colour, offsets[ch.name]) if shown_here else None, w, h))
        if not vi.has_alpha:
            out.append("</g>\n")
    out.append("</svg>\n")
    return "".join(out)


def save_svg(vi: VectorImage, path, compress=None, crisp: bool = True, lines: bool = True) -> None:
    """Write ``vi`` as SVG to ``path`` atomically (``crisp``, ``lines``: see to_svg).

    ``compress`` None: gzip (SVGZ) when the name ends in ``.svgz``. The gzip stream is
    deterministic (mtime 0, no file name).
    """
    data = to_svg(vi, crisp=crisp, lines=lines).encode("utf-8")
    if compress is None:
        compress = os.fspath(path).lower().endswith(".svgz")
    if compress:
        data = gzip.compress(data, compresslevel=9, mtime=0)
    atomic_write_bytes(path, data)



def _check_image(vi) -> None:
    check_image_kind(vi, too_big=FormatError)
    for ch in vi.channels:
        label = ch.name
        levels = np.asarray(ch.levels)
        if levels.ndim != 1 or levels.shape[0] > MAX_LEVELS:
            raise FormatError(f"channel {label}: levels must be 1-D, at most {MAX_LEVELS}")
        check_levels(levels, label)
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
        check_semantics(label, levels.shape[0], ch.contour_level.astype(np.int64),
                         ch.parent.astype(np.int64), ch.cap_band.astype(np.int64),
                         ch.cap_contour.astype(np.int64))
        if not 0 <= int(ch.base_band) <= levels.shape[0]:
            raise FormatError(f"channel {label}: base band {ch.base_band} is outside [0, {levels.shape[0]}]")
        if ch.tone is not None:
            check_svg_tone(np.asarray(ch.tone), label)
        check_cap_ramp(ch.cap_ramp, label)



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


def _channel_layer(ch: Channel, paint, w: int, h: int) -> list:
    """The <g> layer of one channel, as a list of strings. ``paint``: (root fill, contour
    fills) of a shown layer (preview.paints), None for a hidden one (alpha)."""
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
    if paint is None:
        attrs.append(f'style="display:none" fill="none" stroke="{UV_STROKES.get(label, "#000")}" '
                     f'stroke-width="{LOCAL_SCALE // 4}"')
    else:
        attrs.append('stroke="none"' + (' style="mix-blend-mode:lighten"' if label in ("U", "V") else ""))
    out = [f"<g {' '.join(attrs)}>\n"]
    fills = None
    if paint is not None:
        root, fills = paint
        out.append(f'<rect width="{w * LOCAL_SCALE}" height="{h * LOCAL_SCALE}" fill="{root}"/>\n')
    if c == 0:
        out.append("</g>\n")
        return out
    d = _path_data(q, ch.offsets, ch.cap_xy * LOCAL_SCALE, ch.cap_contour)
    so = ch.segment_offsets()
    area = np.sign(signed_areas(ch.points, ch.offsets)).astype(np.int64)
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


def _preview_layer(ch: Channel, paint, w: int, h: int) -> list:
    """The preview's layer of one channel: its root rectangle, then its contours as
    polylines (polyline.py), one path per depth and fill (every depth after the one above
    it: the painter's order of _painter_order; contours of one depth never nest, so one
    nonzero fill of them, all run one way, paints each one's footprint)."""
    root, fills = paint
    blend = ' style="mix-blend-mode:lighten"' if ch.name in ("U", "V") else ""
    out = [f'<g transform="scale({1 / LOCAL_SCALE!r})"{blend}>\n',
           f'<rect width="{w * LOCAL_SCALE}" height="{h * LOCAL_SCALE}" fill="{root}"/>\n']
    if ch.n_contours:
        vert, vo = polyline.vertices(ch.points, ch.offsets, ch.border)
        d = polyline.path_data(vert, vo, LOCAL_SCALE, signed_areas(ch.points, ch.offsets) < 0)
        depth = _depths(ch.parent)
        names = sorted(set(fills))
        fill_ix = np.searchsorted(names, fills)
        order = np.lexsort((np.arange(depth.shape[0]), fill_ix, depth)).tolist()
        key = (depth * len(names) + fill_ix).tolist()
        i = 0
        while i < len(order):
            j = i
            while j < len(order) and key[order[j]] == key[order[i]]:
                j += 1
            out.append(f'<path fill="{fills[order[i]]}" d="{"".join(d[k] for k in order[i:j])}"/>\n')
            i = j
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


def _depths(parent: np.ndarray) -> np.ndarray:
    """(C,) every contour's depth below the frame (0: a child of the frame)."""
    c = parent.shape[0]
    par = parent.tolist()
    dl = [-1] * c
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
    return np.asarray(dl, np.int64)


def _painter_order(parent: np.ndarray) -> np.ndarray:
    """Contour indices with every parent before its children: stable by depth."""
    return np.argsort(_depths(parent), kind="stable")
