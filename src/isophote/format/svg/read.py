"""The isophote SVG reader: ``from_svg``, ``load_svg`` and ``is_svg`` (what it makes of edited
files: format/svg/__init__.py, "Reading edited files")."""

from __future__ import annotations

import gzip
import io
import math
import os
import re
import xml.etree.ElementTree as ET
import zlib

import numpy as np

from ...errors import FormatError, LimitError
from ...model import CAP_RAMP, DOME, Channel, VectorImage
from ..limits import (
    CHANNEL_LAYOUTS, COLOUR_CODES, GZIP_MAGIC, MAX_CAPS, MAX_HEIGHT, MAX_LEVELS, MAX_META_BYTES,
    MAX_SEGMENTS, MAX_SVG_BYTES, MAX_TONE_KNOTS, MAX_WIDTH, SOURCE_DEPTHS, SVG_FORMAT_VERSION,
)
from ..validate import check_cap_ramp, check_levels, check_semantics, parse_meta
from .pathdata import (
    IDENTITY, INT_RE, NUM_RE, apply_affine, canonical_chain_parts, canonical_chains, compose,
    parse_path_markers, parse_transform,
)
from ...geometry import signed_areas
from .profile import MAX_CAP_VALUE, MAX_COORD, NS_ISO, NS_SVG, check_svg_tone

_S = "{%s}" % NS_SVG
_I = "{%s}" % NS_ISO
_FEED_CHUNK = 1 << 20
_CONTOUR_RE = re.compile(r"(-?[0-9]{1,12}) (-?[0-9]{1,12}) (-?[0-9]{1,12}) (-?[0-9]{1,12}) (-?[0-9]{1,12})")


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



def _attr_ints(text: str, what: str) -> list:
    parts = text.split()
    if not all(INT_RE.fullmatch(p) for p in parts):
        raise FormatError(f"{what} must be integers, got {text[:60]!r}")
    return [int(p) for p in parts]


def _attr_floats(text: str, what: str) -> list:
    parts = text.split()
    if not all(NUM_RE.fullmatch(p) for p in parts):
        raise FormatError(f"{what} must be numbers, got {text[:60]!r}")
    vals = [float(p) for p in parts]
    if not all(math.isfinite(v) for v in vals):
        raise FormatError(f"{what}: a number is not finite")
    return vals


def _one_chain(d: str, label: str, k: int):
    """(chain, markers) of a contour's path data, by the general parser."""
    subs, markers = parse_path_markers(d)
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
            self.stack.append((IDENTITY, None))
            return
        m, chan = self.stack[-1]
        t = el.get("transform")
        if t is not None:
            m = compose(m, parse_transform(t))
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
            if not INT_RE.fullmatch(v.strip()):
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
        check_levels(levels, name)
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
            check_svg_tone(tone, name)
        cap_ramp = CAP_RAMP
        if el.get(_I + "cap-ramp") is not None:
            text = el.get(_I + "cap-ramp").strip()
            ramp = [DOME] if text == "dome" else _attr_floats(text, f"channel {name} cap ramp")
            if len(ramp) != 1:
                raise FormatError(f"channel {name}: iso:cap-ramp must be one number or \"dome\"")
            cap_ramp = check_cap_ramp(ramp[0], name)
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
        parts = canonical_chain_parts(d)
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
            meta = parse_meta(b)
        channels = tuple(self._build(ch) for ch in self.channels)
        return VectorImage(width=self.width, height=self.height, colour=self.colour,
                           channels=channels, source_depth=self.depth, meta=meta)

    def _build(self, cd: _ChannelData) -> Channel:
        label = cd.name
        keys = sorted(cd.contours)
        index = {k: i for i, k in enumerate(keys)}  # deleted contours: the rest renumbered
        entries = [cd.contours[k] for k in keys]
        mats = [e[6] for e in entries]
        offsets, points = _placed_chains(label, entries, mats)
        so = (offsets - np.arange(len(keys) + 1)) // 3
        border = self._border(label, keys, entries, offsets, points, so)
        _turn_back(entries, offsets, points, so, border)
        level = np.array([e[1] for e in entries], np.int64)
        parent = np.array([index.get(e[2], -1) if e[2] >= 0 else e[2] for e in entries], np.int64)
        cap_contour, cap_band, cap_xy, cap_value = _placed_caps(cd, keys, index, entries, mats, offsets, points)
        check_semantics(label, cd.levels.shape[0], level, parent, cap_band, cap_contour)
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

    def _border(self, label, keys, entries, offsets, points, so) -> np.ndarray:
        """The border flags: as written, or, where a contour was reshaped, the frame's say."""
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
        return border

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


def _placed_chains(label, entries, mats):
    """(offsets, points) of a channel's contours, built and put through their transforms."""
    c = len(entries)
    pending = [e for e in entries if e[0] is None]
    for e, chain in zip(pending, canonical_chains([e[7] for e in pending])):
        e[0], e[7] = chain, None
    offsets = np.zeros(c + 1, np.int64)
    if c:
        np.cumsum([e[0].shape[0] for e in entries], out=offsets[1:])
    points = np.concatenate([e[0] for e in entries]) if c else np.zeros((0, 2), np.float64)
    # the transforms, one affine map per distinct matrix (usually one for the layer)
    owner = np.repeat(np.arange(c), np.diff(offsets))
    if c:
        mm = np.array(mats, np.float64)[owner]  # (P, 6): each point's affine map
        x, y = points[:, 0].copy(), points[:, 1].copy()
        points[:, 0] = mm[:, 0] * x + mm[:, 2] * y + mm[:, 4]
        points[:, 1] = mm[:, 1] * x + mm[:, 3] * y + mm[:, 5]
    if points.size and (not np.all(np.isfinite(points)) or np.abs(points).max() >= MAX_COORD):
        raise LimitError(f"channel {label}: a contour lies beyond the coordinate limit of +-{MAX_COORD:g}")
    return offsets, points


def _turn_back(entries, offsets, points, so, border) -> None:
    """Reverse, in place, every contour whose area changed sign (mirrored, reversed)."""
    stored = np.array([e[3] for e in entries], np.int64)
    now = np.sign(signed_areas(points, offsets)).astype(np.int64)
    for i in np.flatnonzero((stored != 0) & (now == -np.sign(stored))).tolist():
        points[offsets[i]:offsets[i + 1]] = points[offsets[i]:offsets[i + 1]][::-1]
        border[so[i]:so[i + 1]] = border[so[i]:so[i + 1]][::-1]


def _placed_caps(cd, keys, index, entries, mats, offsets, points):
    """(cap_contour, cap_band, cap_xy, cap_value) of a channel, renumbered with its contours.

    A contour's caps ride in its path data as markers, through any transform or rewrite;
    where an editor dropped or added markers, the fallback offsets serve. Caps of deleted
    contours are dropped."""
    caps = cd.caps
    cc_old = caps[:, 0].astype(np.int64)
    keep = (cc_old < 0) | np.isin(cc_old, np.array(keys, np.int64))
    cap_contour = np.array([index.get(int(v), -1) if v >= 0 else -1 for v in cc_old.tolist()], np.int64)
    cap_contour[cc_old < -1] = -2  # reported as out of range below
    cap_xy = apply_affine(cd.group_m, caps[:, 2:4]) if caps.size else np.zeros((0, 2))
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
    return cap_contour[keep], cap_band[keep], cap_xy[keep], cap_value[keep]
