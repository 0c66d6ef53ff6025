"""The plain-Python twin of ``entropy.py``: the same channel layout (on rangecoder_ref.py), written
as directly from the specification (format/isoph.py, "Range-coded channels") as possible,
with Python integers and objects instead of flat arrays. Slow; the tests run both on random
inputs and require the same bytes and the same decoded arrays.
"""

from __future__ import annotations

import math

from ...shared.grid_ref import chord_frame, from_frame, rnd, rnd3, to_frame  # noqa: F401
from .rangecoder_ref import KMAX, PROB_ONE, Bit, Decoder, Encoder, IntModel  # noqa: F401

# The constants are the specification's; they are repeated here, not imported, so that a
# change to one implementation cannot silently change the other.
NB = 12
PATH_MAX = 32
LIMIT = 1 << 30
MAX_HANDLE_SHIFT = 5
PART_SEGMENTS = 1 << 18  # version 5: the points in parts of at least this many segments


def part_starts(nseg, part_segments):
    """Version 5: the first contour of each part of the points, then C. A part ends after the
    contour that brings it to part_segments segments or more."""
    starts, acc = [0], 0
    for k, n in enumerate(nseg):
        acc += n
        if acc >= part_segments and k + 1 < len(nseg):
            starts.append(k + 1)
            acc = 0
    return starts + [len(nseg)]


def u32(v: int) -> bytes:
    return v.to_bytes(4, "little")


class Models:
    """Every model and flag probability of one channel, made on first use."""

    def __init__(self):
        self.ints = {}
        self.bits = {}

    def int(self, *key) -> IntModel:
        if key not in self.ints:
            self.ints[key] = IntModel()
        return self.ints[key]

    def bit(self, *key) -> Bit:
        if key not in self.bits:
            self.bits[key] = Bit()
        return self.bits[key]


def bucket(v: int) -> int:
    return min(abs(v).bit_length(), NB - 1)


def g_contexts(version, h1, h2):
    """Buckets selecting the models of the second handle's two terms (non-border segments):
    version 2 both by bucket(max(|h1|, |h2|)), version 3 by bucket(h1) and bucket(h2)."""
    hb = bucket(max(abs(h1), abs(h2)))
    return (bucket(h1), bucket(h2)) if version >= 3 else (hb, hb)


def shift_model(mo, prev_h, db):
    """Version 4's model of a segment's handle shift: by the previous shift and the chord."""
    return mo.int("handle shift", prev_h, 0 if db <= 7 else (1 if db <= 9 else 2))


def put_handles(enc, mo, version, b, db, d, h, r, prev_h=0):
    """The residuals h = Ca - A - rnd3(d) and r = Cb - N + rnd3(d) of one segment: as they
    are (version 2), or in the chord's frame with r.a after -h.a / 2 (version 3); version 4
    first codes the shift sh of a non-border segment, the largest <= MAX_HANDLE_SHIFT that
    divides all four frame terms, then the terms divided by 2**sh. Returns sh."""
    (h1, h2), (g1, g2) = h, r
    sh = 0
    if version >= 3:
        frame = chord_frame(*d)
        h1, h2 = to_frame(frame, *h)
        g1, g2 = to_frame(frame, *r)
        if version >= 4 and not b:
            low = h1 | h2 | g1 | g2
            while sh < MAX_HANDLE_SHIFT and not (low >> sh) & 1:
                sh += 1
            shift_model(mo, prev_h, db).put_uint(enc, sh)
            h1, h2, g1, g2 = h1 >> sh, h2 >> sh, g1 >> sh, g2 >> sh
        g1 += (h1 + 1) >> 1
    mo.int("hx", b, db).put(enc, h1)
    if b:
        for name, v in (("hy", h2), ("gx", g1), ("gy", g2)):
            mo.int(name, "border").put(enc, v)
    else:
        mo.int("hy", bucket(h1), db).put(enc, h2)
        c1, c2 = g_contexts(version, h1, h2)
        mo.int("gx", c1, db).put(enc, g1)
        mo.int("gy", c2, db).put(enc, g2)
    return sh


def get_handles(dec, mo, version, b, db, d, prev_h=0):
    """The inverse of put_handles: (h, r, sh); sh is None for a shift beyond the largest."""
    sh = 0
    if version >= 4 and not b:
        sh = shift_model(mo, prev_h, db).get_uint(dec)
        if sh > MAX_HANDLE_SHIFT:
            return None, None, None
    h1 = mo.int("hx", b, db).get(dec)
    if b:
        h2, g1, g2 = (mo.int(name, "border").get(dec) for name in ("hy", "gx", "gy"))
    else:
        h2 = mo.int("hy", bucket(h1), db).get(dec)
        c1, c2 = g_contexts(version, h1, h2)
        g1 = mo.int("gx", c1, db).get(dec)
        g2 = mo.int("gy", c2, db).get(dec)
    if version >= 3:
        g1 -= (h1 + 1) >> 1
        h1, h2, g1, g2 = h1 << sh, h2 << sh, g1 << sh, g2 << sh
        frame = chord_frame(*d)
        return from_frame(frame, h1, h2), from_frame(frame, g1, g2), sh
    return (h1, h2), (g1, g2), sh


def level_pred(levels, lev: int, shift: int) -> int:
    x = min(max(float(levels[lev]) * 64.0, -LIMIT), LIMIT)
    return math.floor(x + 0.5) >> shift


def candidates(parent, k):
    """The parent candidates of contour k: k - 1 and its ancestors, as far as known."""
    out, x = [], k - 1
    while len(out) < PATH_MAX:
        out.append(x)
        if x < 0 or x >= k:
            break
        x = parent[x]
    return out


def on_grid(v: int, g: int) -> bool:
    return v % (1 << g) == 0


def anchor_flag(x: int, y: int, g: int) -> int:
    return (1 if on_grid(x, g) else 0) | (2 if on_grid(y, g) else 0) if g else 0


def put_flag4(enc, models, ctx, f):
    enc.bit(models.bit("anchor", ctx, 0), f & 1)
    enc.bit(models.bit("anchor", ctx, 1 + (f & 1)), f >> 1)


def get_flag4(dec, models, ctx):
    b1 = dec.bit(models.bit("anchor", ctx, 0))
    return b1 | (dec.bit(models.bit("anchor", ctx, 1 + b1)) << 1)


def put_coord(enc, model_fine, model_coarse, on, new, old, g):
    """A coordinate after ``old``: coarse (on the anchor grid) when ``on``, else fine."""
    if on:
        model_coarse.put(enc, (new >> g) - ((old + ((1 << g) >> 1)) >> g))
    else:
        model_fine.put(enc, new - old)


def get_coord(dec, model_fine, model_coarse, on, old, g):
    if on:
        return (((old + ((1 << g) >> 1)) >> g) + model_coarse.get(dec)) << g
    return old + model_fine.get(dec)


def encode_channel(ch: dict) -> bytes:
    """ch: level, nseg, parent, chains (per contour, its 3 n stored points on the point grid),
    border (per segment), g, cap_contour, cap_band, cap_xy (cap grid), cap_value (value grid),
    s_p, s_c, s_v, levels, base_band; and ``version`` (2 to 5, default 4): whose layout
    (``part_segments``: version 5's parts, PART_SEGMENTS by default).

    It codes whatever it is given, lies included (segment counts that do not fit the chains,
    levels or cap contours out of range: (0, 0) and 0 stand in for what does not exist), so
    that tests can craft invalid files with valid coding.
    """
    enc, mo = Encoder(), Models()
    level, parent, g = ch["level"], ch["parent"], ch["g"]
    version = ch.get("version", 4)
    c = len(level)
    prev_rank = 0
    for k in range(c):
        cand = candidates(parent, k)
        rank = cand.index(parent[k]) + 1 if parent[k] in cand else 0
        mo.int("rank", min(prev_rank, 3)).put_uint(enc, rank)
        if rank == 0:
            mo.int("far").put(enc, k - parent[k])
        prev_rank = rank
        p = parent[k]
        if 0 <= p < k:
            mo.int("level rel").put(enc, level[k] - level[p])
        else:
            mo.int("level abs").put(enc, level[k] - (level[k - 1] if k else 0))
        mo.int("nseg").put_uint(enc, ch["nseg"][k] - 1)

    # version 5: a part after the first starts a stream of its own, fresh models, P0 after (0, 0)
    main, mo_main, parts = enc, mo, []
    starts = part_starts(ch["nseg"], ch.get("part_segments", PART_SEGMENTS)) if version >= 5 else [0, c]
    prev0 = (0, 0)
    prev_h = 0
    s0 = 0
    for k in range(c):
        if k in starts[1:-1]:
            if enc is not main:
                parts.append(enc.finish())
            enc, mo, prev0, prev_h = Encoder(), Models(), (0, 0), 0
        chain, n = ch["chains"][k], ch["nseg"][k]

        def pts(i, chain=chain):
            return chain[i] if i < len(chain) else (0, 0)

        x0, y0 = pts(0)
        f = anchor_flag(x0, y0, g)
        if g:
            put_flag4(enc, mo, 4, f)
        put_coord(enc, mo.int("p0", 0), mo.int("p0 coarse", 0), f & 1, x0, prev0[0], g)
        put_coord(enc, mo.int("p0", 1), mo.int("p0 coarse", 1), f & 2, y0, prev0[1], g)
        prev0 = (x0, y0)
        prev_b, prev_f, dbk, pd = 2, f, 0, (0, 0)
        for i in range(n):
            ax, ay = pts(3 * i)
            nx, ny = pts(3 * i + 3) if i < n - 1 else (x0, y0)
            b = int(ch["border"][s0 + i]) if s0 + i < len(ch["border"]) else 0
            enc.bit(mo.bit("border", prev_b), b)
            prev_b = b
            if i < n - 1:
                f = anchor_flag(nx, ny, g)
                if g:
                    put_flag4(enc, mo, prev_f, f)
                prev_f = f
                bx, by = (ax + (pd[0] >> 1), ay + (pd[1] >> 1)) if version >= 3 else (ax, ay)
                put_coord(enc, mo.int("dx", b, dbk), mo.int("dx coarse", b, dbk), f & 1, nx, bx, g)
                ybk = bucket(nx - ax)
                put_coord(enc, mo.int("dy", b, ybk), mo.int("dy coarse", b, ybk), f & 2, ny, by, g)
            dx, dy = nx - ax, ny - ay
            pd = (dx, dy)
            db = dbk = bucket(max(abs(dx), abs(dy)))
            h = (pts(3 * i + 1)[0] - ax - rnd3(dx), pts(3 * i + 1)[1] - ay - rnd3(dy))
            r = (pts(3 * i + 2)[0] - nx + rnd3(dx), pts(3 * i + 2)[1] - ny + rnd3(dy))
            sh = put_handles(enc, mo, version, b, db, (dx, dy), h, r, prev_h)
            if not b:
                prev_h = sh
        s0 += n

    if enc is not main:
        parts.append(enc.finish())
        enc, mo = main, mo_main
    s_p, s_c, s_v = ch["s_p"], ch["s_c"], ch["s_v"]
    prev_cc = -1
    for i, cc in enumerate(ch["cap_contour"]):
        mo.int("cap contour").put(enc, cc - prev_cc)
        prev_cc = cc
        ox = oy = vpred = 0
        if cc >= 0:
            lev = level[cc] if cc < c else 0
            rel = ch["cap_band"][i] - lev
            mo.int("band rel").put(enc, rel)
            ctx = rel if 0 <= rel <= 1 else 2
            ox, oy = (v << s_p for v in (ch["chains"][cc][0] if cc < c else (0, 0)))
            vpred = level_pred(ch["levels"], lev, s_v) if 0 <= lev < len(ch["levels"]) else 0
        else:
            mo.int("band root").put(enc, ch["cap_band"][i] - ch["base_band"])
            ctx = 2
        half = (1 << s_c) >> 1
        mo.int("cap xy", 0).put(enc, ch["cap_xy"][i][0] - ((ox + half) >> s_c))
        mo.int("cap xy", 1).put(enc, ch["cap_xy"][i][1] - ((oy + half) >> s_c))
        mo.int("cap value", ctx).put(enc, ch["cap_value"][i] - vpred)
    if version < 5:
        return enc.finish()
    return enc.finish() + b"".join(parts) + b"".join(u32(len(b)) for b in parts) + u32(len(parts))


class Invalid(Exception):
    """A decoded value breaks a rule; args: (what, entry)."""


def decode_channel(data: bytes, c, s, k, g, s_p, s_c, s_v, levels, base_band, version=4,
                   part_segments=PART_SEGMENTS) -> dict:
    """The inverse of encode_channel: a dict of lists, points in 1/64 px as (x, y) tuples per
    contour with the closing point, caps in 1/64 units. Raises Invalid for a broken rule."""
    parts = []
    if version >= 5:  # the stream, its parts of points, their sizes, their count
        n = len(data)
        count = int.from_bytes(data[n - 4:], "little") if n >= 4 else -1
        end = n - 4 - 4 * count
        if count < 0 or count > max(c - 1, 0) or end < 0:
            raise Invalid("parts", 0)
        sizes = [int.from_bytes(data[end + 4 * i:end + 4 * i + 4], "little") for i in range(count)]
        if sum(sizes) > end:
            raise Invalid("parts", 0)
        for size in reversed(sizes):
            parts.insert(0, data[end - size:end])
            end -= size
        data = data[:end]
    dec, mo = Decoder(data), Models()
    level, nseg, parent = [], [], []
    prev_rank = total = 0
    for j in range(c):
        rank = mo.int("rank", min(prev_rank, 3)).get_uint(dec)
        if rank == 0:
            p = j - mo.int("far").get(dec)
            if not -1 <= p < c:
                raise Invalid("parent", j)
        else:
            cand = candidates(parent, j)
            if rank > len(cand):
                raise Invalid("rank", j)
            p = cand[rank - 1]
        parent.append(p)
        prev_rank = rank
        if 0 <= p < j:
            lv = level[p] + mo.int("level rel").get(dec)
        else:
            lv = (level[j - 1] if j else 0) + mo.int("level abs").get(dec)
        if not 0 <= lv < len(levels):
            raise Invalid("level", j)
        level.append(lv)
        n = mo.int("nseg").get_uint(dec) + 1
        total += n
        if total > s:
            raise Invalid("nseg", j)
        nseg.append(n)
    if total != s:
        raise Invalid("nseg short", c)

    lim = LIMIT >> s_p
    chains, border = [], []
    main, mo_main = dec, mo
    starts = part_starts(nseg, part_segments) if version >= 5 else [0, c]
    if len(starts) - 2 != len(parts):
        raise Invalid("parts", len(parts))
    prev0 = (0, 0)
    prev_h = 0
    for j in range(c):
        if j in starts[1:-1]:
            if dec is not main and dec.status() != "ok":
                raise Invalid(dec.status(), j)
            dec, mo = Decoder(parts[starts.index(j) - 1]), Models()
            prev0, prev_h = (0, 0), 0
        n = nseg[j]
        f = get_flag4(dec, mo, 4) if g else 0
        x0 = get_coord(dec, mo.int("p0", 0), mo.int("p0 coarse", 0), f & 1, prev0[0], g)
        y0 = get_coord(dec, mo.int("p0", 1), mo.int("p0 coarse", 1), f & 2, prev0[1], g)
        if abs(x0) >= lim or abs(y0) >= lim:
            raise Invalid("point", j)
        prev0 = (x0, y0)
        pts = [(x0, y0)]
        prev_b, prev_f, dbk, pd = 2, f, 0, (0, 0)
        ax, ay = x0, y0
        for i in range(n):
            b = dec.bit(mo.bit("border", prev_b))
            border.append(b)
            prev_b = b
            if i < n - 1:
                f = get_flag4(dec, mo, prev_f) if g else 0
                prev_f = f
                bx, by = (ax + (pd[0] >> 1), ay + (pd[1] >> 1)) if version >= 3 else (ax, ay)
                nx = get_coord(dec, mo.int("dx", b, dbk), mo.int("dx coarse", b, dbk), f & 1, bx, g)
                ybk = bucket(nx - ax)
                ny = get_coord(dec, mo.int("dy", b, ybk), mo.int("dy coarse", b, ybk), f & 2, by, g)
                if abs(nx) >= lim or abs(ny) >= lim:
                    raise Invalid("point", j)
            else:
                nx, ny = x0, y0
            dx, dy = nx - ax, ny - ay
            pd = (dx, dy)
            db = dbk = bucket(max(abs(dx), abs(dy)))
            h, r, sh = get_handles(dec, mo, version, b, db, (dx, dy), prev_h)
            if sh is None:
                raise Invalid("handle shift", j)
            if not b:
                prev_h = sh
            (hx, hy), (gx, gy) = h, r
            ca = (ax + rnd3(dx) + hx, ay + rnd3(dy) + hy)
            cb = (nx - rnd3(dx) + gx, ny - rnd3(dy) + gy)
            if max(abs(ca[0]), abs(ca[1]), abs(cb[0]), abs(cb[1])) >= lim:
                raise Invalid("point", j)
            pts += [ca, cb, (nx, ny)]
            ax, ay = nx, ny
        chains.append([(x << s_p, y << s_p) for x, y in pts])

    if dec is not main:
        if dec.status() != "ok":
            raise Invalid(dec.status(), c)
        dec, mo = main, mo_main
    cap_contour, cap_band, cap_xy, cap_value = [], [], [], []
    prev_cc = -1
    half = (1 << s_c) >> 1
    for i in range(k):
        cc = prev_cc + mo.int("cap contour").get(dec)
        if not -1 <= cc < c:
            raise Invalid("cap contour", i)
        prev_cc = cc
        ox = oy = vpred = 0
        if cc >= 0:
            rel = mo.int("band rel").get(dec)
            band = level[cc] + rel
            ctx = rel if 0 <= rel <= 1 else 2
            ox, oy = chains[cc][0]
            vpred = level_pred(levels, level[cc], s_v)
        else:
            band = base_band + mo.int("band root").get(dec)
            ctx = 2
        x = ((ox + half) >> s_c) + mo.int("cap xy", 0).get(dec)
        y = ((oy + half) >> s_c) + mo.int("cap xy", 1).get(dec)
        if abs(x << s_c) >= LIMIT or abs(y << s_c) >= LIMIT:
            raise Invalid("cap xy", i)
        v = vpred + mo.int("cap value", ctx).get(dec)
        if abs(v << s_v) >= LIMIT:
            raise Invalid("cap value", i)
        cap_contour.append(cc)
        cap_band.append(band)
        cap_xy.append((x << s_c, y << s_c))
        cap_value.append(v << s_v)
    status = dec.status()
    if status != "ok":
        raise Invalid(status, 0)
    return dict(level=level, nseg=nseg, parent=parent, chains=chains, border=border,
                cap_contour=cap_contour, cap_band=cap_band, cap_xy=cap_xy, cap_value=cap_value)
