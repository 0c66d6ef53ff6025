"""SVG path data and transforms, in general: what a drawing program may write (absolute or
relative M, L, H, V, C, S, Q, T, A, Z; matrix, translate, scale, rotate, skewX, skewY), as
cubic chains and affine maps; and a fast path for the chains as the writer lays them out."""

from __future__ import annotations

import math
import re

import numpy as np

from ...errors import FormatError
from ..limits import COORD_LIMIT

CLOSE_SNAP = 1e-7  # relative distance under which a path's end counts as its start

_NUMBER = r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
NUM_RE = re.compile(_NUMBER)
INT_RE = re.compile(r"[-+]?[0-9]+")
_PATH_TOKEN = re.compile(r"([MmZzLlHhVvCcSsQqTtAa])|(" + _NUMBER + ")")
_TRANSFORM = re.compile(r"[\s,]*(matrix|translate|scale|rotate|skewX|skewY)\s*\(([^()]*)\)[\s,]*")
_ARGS = {"M": 2, "L": 2, "H": 1, "V": 1, "C": 6, "S": 4, "Q": 4, "T": 2, "A": 7, "Z": 0}
IDENTITY = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0)


def compose(p, c):
    """Affine p after c; tuples (a, b, c, d, e, f): x' = a x + c y + e, y' = b x + d y + f."""
    a1, b1, c1, d1, e1, f1 = p
    a2, b2, c2, d2, e2, f2 = c
    return (a1 * a2 + c1 * b2, b1 * a2 + d1 * b2, a1 * c2 + c1 * d2, b1 * c2 + d1 * d2,
            a1 * e2 + c1 * f2 + e1, b1 * e2 + d1 * f2 + f1)


def apply_affine(m, pts: np.ndarray) -> np.ndarray:
    if m == IDENTITY:
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
    """An SVG transform list as an affine tuple (see compose). FormatError when malformed."""
    m = IDENTITY
    pos = 0
    text = text.strip()
    while pos < len(text):
        t = _TRANSFORM.match(text, pos)
        if t is None or t.end() == pos:
            raise FormatError(f"malformed transform {text[:60]!r}")
        pos = t.end()
        name, body = t.group(1), t.group(2)
        if NUM_RE.sub("", body).strip(" \t\r\n,"):
            raise FormatError(f"malformed transform arguments {body[:60]!r}")
        args = [float(v) for v in NUM_RE.findall(body)]
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
                step = compose(compose((1.0, 0.0, 0.0, 1.0, cx, cy), step), (1.0, 0.0, 0.0, 1.0, -cx, -cy))
        elif name == "skewX" and n == 1:
            step = (1.0, 0.0, math.tan(math.radians(args[0])), 1.0, 0.0, 0.0)
        elif name == "skewY" and n == 1:
            step = (1.0, math.tan(math.radians(args[0])), 0.0, 1.0, 0.0, 0.0)
        else:
            raise FormatError(f"transform {name} takes other arguments than {n}")
        m = compose(m, step)
    if not all(math.isfinite(v) for v in m):
        raise FormatError("a transform is not finite")
    return m


def parse_path(d: str) -> list:
    """SVG path data as a list of subpaths, each a (1 + 3n, 2) float64 chain of cubics
    (absolute coordinates; lines, quadratics and arcs converted; every subpath closed by a
    line to its start where it does not end there). Subpaths that draw nothing are left
    out. FormatError when malformed."""
    return parse_path_markers(d)[0]


def parse_path_markers(d: str):
    """(subpaths as parse_path gives them, (m, 2) points of the subpaths that draw nothing:
    the markers that carry a contour's caps)."""
    tokens = _PATH_TOKEN.findall(d)
    if _PATH_TOKEN.sub("", d).strip(" \t\r\n\f,"):
        raise FormatError(f"malformed path data near {d[:40]!r}")
    pen = _Pen()
    pos = 0
    n_tok = len(tokens)
    while pos < n_tok:
        cmd = tokens[pos][0]
        if not cmd:
            raise FormatError("path data must start with a command")
        pos += 1
        nums = []
        while pos < n_tok and not tokens[pos][0]:
            nums.append(tokens[pos][1])
            pos += 1
        pen.command(cmd, nums)
    pen.finish()
    return pen.subpaths, np.array(pen.markers, np.float64).reshape(-1, 2)


class _Pen:
    """Draws path commands as cubics, one subpath after another."""

    def __init__(self):
        self.subpaths = []
        self.markers = []
        self.cur = np.zeros(2)
        self.start = np.zeros(2)
        self.segs = []  # arrays (n, 3, 2) of the current subpath
        self.last_c = None  # previous cubic's second control point (for S)
        self.last_q = None  # previous quadratic's control point (for T)
        self.started = False  # a moveto began a subpath that finish() has not ended yet

    def finish(self) -> None:
        """End the current subpath: closed by a line where it does not end on its start, or
        a marker when it draws nothing."""
        start = self.start
        body = np.concatenate(self.segs).reshape(-1, 2) if self.segs else np.zeros((0, 2))
        if body.shape[0]:
            end = body[-1]
            scale = max(1.0, float(np.abs(body).max()), float(np.abs(start).max()))
            if not np.array_equal(end, start):
                if np.abs(end - start).max() <= CLOSE_SNAP * scale:
                    body[-1] = start
                else:
                    body = np.vstack([body, _line(end, start).reshape(-1, 2)])
            self.subpaths.append(np.vstack([start[None, :], body]))
        elif self.started:
            self.markers.append(start.copy())
        self.segs = []
        self.started = False

    def command(self, cmd: str, nums: list) -> None:
        up = cmd.upper()
        rel = cmd != up
        na = _ARGS[up]
        if up == "Z":
            if nums:
                raise FormatError("numbers after a closepath")
            self.finish()
            self.cur = self.start.copy()
            self.last_c = self.last_q = None
            return
        if up == "A":
            nums = _split_arc_flags(nums)
        if not nums or len(nums) % na:
            raise FormatError(f"path command {cmd} needs a multiple of {na} numbers, got {len(nums)}")
        v = np.array([float(x) for x in nums], dtype=np.float64)
        if not np.all(np.isfinite(v)):
            raise FormatError("a path coordinate is not finite")
        v = v.reshape(-1, na)
        if up == "M":
            self._moveto(v, rel)
        elif up == "C":
            self._cubics(v, rel)
        elif up in ("L", "H", "V"):
            self._lines(v, up, rel)
        else:
            for row in v:  # S, Q, T, A: one at a time
                self._one(up, row, rel)

    def _moveto(self, v, rel) -> None:
        self.finish()
        self.started = True
        p = v[0] + (self.cur if rel else 0.0)
        self.cur = p.copy()
        self.start = p.copy()
        self.last_c = self.last_q = None
        if len(v) > 1:  # further pairs are implicit lines
            self.cur = _lines(self.segs, self.cur, v[1:], rel)

    def _cubics(self, v, rel) -> None:
        r = v.reshape(-1, 3, 2)
        if rel:
            ends = self.cur + np.cumsum(r[:, 2], axis=0)
            starts = np.vstack([self.cur[None, :], ends[:-1]])
            r = starts[:, None, :] + r
        self.segs.append(r)
        self.cur = r[-1, 2].copy()
        self.last_c, self.last_q = r[-1, 1].copy(), None

    def _lines(self, v, up, rel) -> None:
        if up == "H":
            v = np.stack([v[:, 0], np.zeros(len(v)) if rel else np.full(len(v), np.nan)], 1)
        elif up == "V":
            v = np.stack([np.zeros(len(v)) if rel else np.full(len(v), np.nan), v[:, 0]], 1)
        self.cur = _lines(self.segs, self.cur, v, rel)
        self.last_c = self.last_q = None

    def _one(self, up, row, rel) -> None:
        """One S, Q, T or A command's piece."""
        cur = self.cur
        if up == "S":
            c1 = 2 * cur - self.last_c if self.last_c is not None else cur.copy()
            c2 = row[0:2] + (cur if rel else 0.0)
            p = row[2:4] + (cur if rel else 0.0)
            self.segs.append(np.stack([c1, c2, p])[None])
            self.last_c, self.last_q = c2, None
        elif up in ("Q", "T"):
            if up == "Q":
                qc = row[0:2] + (cur if rel else 0.0)
                p = row[2:4] + (cur if rel else 0.0)
            else:
                qc = 2 * cur - self.last_q if self.last_q is not None else cur.copy()
                p = row[0:2] + (cur if rel else 0.0)
            self.segs.append(np.stack([cur + 2.0 / 3.0 * (qc - cur), p + 2.0 / 3.0 * (qc - p), p])[None])
            self.last_c, self.last_q = None, qc
        else:
            p = row[5:7] + (cur if rel else 0.0)
            self.segs.append(_arc(cur, row[0], row[1], row[2], row[3] != 0, row[4] != 0, p))
            self.last_c = self.last_q = None
        self.cur = p.copy()


_CANON_RE = re.compile(r"M(-?[0-9]{1,12}) (-?[0-9]{1,12})c([-0-9 ]+)z((?:m-?[0-9]{1,12}(?: |(?=-))-?[0-9]{1,12})*)")
_CANON_MARK = re.compile(r"m(-?[0-9]+) ?(-?[0-9]+)")


def canonical_chain_parts(d: str):
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


def canonical_chains(items: list) -> list:
    """The chains of many canonical_chain_parts results, at once."""
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

