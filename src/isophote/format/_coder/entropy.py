"""The .isoph channel layout of compression code 3 ("range"): the contour table, the points
and the caps of one channel as context-modelled integers on the range coder of rangecoder.py
(kernels).

The specification is in format/isoph.py ("Range-coded channels") and docs/format.md; the
plain-Python twin ``entropy_ref.py`` implements the same from that text (with
rangecoder_ref.py), and the tests check that both give the same bytes and the same arrays on
random inputs. Everything here is integer arithmetic (and one float multiply-and-floor on
the writer's and reader's sides alike), so the bytes are the same on every machine.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...shared.grid import chord_frame as _frame, from_frame as _from_frame, rnd3 as _rnd3, to_frame as _to_frame
from .rangecoder import (  # noqa: F401 (KMAX .. decode_ints: the stream's, for this module's callers)
    E_LONG, E_SHORT, KMAX, MAX_UINT, MODEL_SLOTS, OK, PROB_INIT, _dec_bit, _dec_init, _dec_int,
    _dec_status, _dec_uint, _enc_bit, _enc_int, _enc_uint, _finish, _grow, decode_ints, encode_ints,
)

# ---- the channel layout's contexts ---------------------------------------------------------

NB = 12  # magnitude buckets: bit length of |v|, capped at NB - 1
PATH_MAX = 32  # parent candidates: the last contour and its ancestors, at most this many

# integer models, by name -> (first model, count)
_MODELS = [
    ("RANK", 4), ("FAR", 1), ("LEVEL_REL", 1), ("LEVEL_ABS", 1), ("NSEG", 1),
    ("P0F", 2), ("P0C", 2),
    ("DFX", 2 * NB), ("DFY", 2 * NB), ("DCX", 2 * NB), ("DCY", 2 * NB),
    ("HX", 2 * NB), ("HY", NB * NB + 1), ("GX", NB * NB + 1), ("GY", NB * NB + 1),
    ("CC", 1), ("BAND_REL", 1), ("BAND_ROOT", 1), ("CXY", 2), ("CVAL", 3),
    ("HS", 18),
]
M = {}
_n = 0
for _name, _count in _MODELS:
    M[_name] = _n
    _n += _count
N_MODELS = _n
# flag probabilities, after the models' slots
F_BORDER = N_MODELS * MODEL_SLOTS  # 3: previous flag 0, 1, or first segment
F_ANCHOR = F_BORDER + 3  # 5 contexts x 3 tree nodes: previous anchor's flag 0..3, or P0
N_SLOTS = F_ANCHOR + 15

M_RANK, M_FAR, M_LEVEL_REL, M_LEVEL_ABS, M_NSEG = M["RANK"], M["FAR"], M["LEVEL_REL"], M["LEVEL_ABS"], M["NSEG"]
M_P0F, M_P0C, M_DFX, M_DFY, M_DCX, M_DCY = M["P0F"], M["P0C"], M["DFX"], M["DFY"], M["DCX"], M["DCY"]
M_HX, M_HY, M_GX, M_GY = M["HX"], M["HY"], M["GX"], M["GY"]
M_CC, M_BAND_REL, M_BAND_ROOT, M_CXY, M_CVAL = M["CC"], M["BAND_REL"], M["BAND_ROOT"], M["CXY"], M["CVAL"]
M_HS = M["HS"]
MAX_HANDLE_SHIFT = 5  # layout 4: a segment's handles on the 2**h grid, h = 0 .. this
# layout 5: the points in parts of at least this many segments (whole contours), each part but
# the first its own stream with fresh probabilities, so that a reader decodes them side by side
PART_SEGMENTS = 1 << 18
BORDER_CTX = NB * NB  # the HY/GX/GY model of border segments

LIMIT = 1 << 30  # |coordinate| and |cap value| in 1/64 units (isoph.COORD_LIMIT)

# decoder status codes (format/isoph.py turns them into messages; OK, E_SHORT and E_LONG are
# the stream's, rangecoder.py)
E_RANK = 1
E_PARENT = 2
E_LEVEL = 3
E_NSEG = 4
E_NSEG_SHORT = 5
E_POINT = 6
E_CAP_CONTOUR = 7
E_CAP_XY = 8
E_CAP_VALUE = 9
E_SHIFT = 12
E_PARTS = 13  # layout 5: the parts' table does not fit the data, or not the contours


# =============================================================================================
# The channel layout (compression code 3)
# =============================================================================================


@njit(cache=True, nogil=True)
def _bucket(v):
    if v < 0:
        v = -v
    k = 0
    while v != 0 and k < NB - 1:
        v >>= 1
        k += 1
    return k


@njit(cache=True, nogil=True)
def _level_pred(levels, lev, shift):
    """A cap value's prediction: its contour's level in 1/64 grey level, on the value grid."""
    x = levels[lev] * 64.0
    if x > LIMIT:
        x = LIMIT
    if x < -LIMIT:
        x = -LIMIT
    return np.int64(np.floor(x + 0.5)) >> shift


@njit(cache=True, nogil=True)
def _rank_of(parent, k, p):
    """1 + the position of p among the parent candidates of contour k, or 0."""
    x = k - 1
    for j in range(PATH_MAX):
        if x == p:
            return j + 1
        if x < 0 or x >= k:
            return 0
        x = parent[x]
    return 0


@njit(cache=True, nogil=True)
def _candidate(parent, k, rank):
    """The parent candidate of contour k at 1-based ``rank``, or -2 when there is none."""
    x = k - 1
    for _ in range(rank - 1):
        if x < 0 or x >= k:
            return -2
        x = parent[x]
    return x


@njit(cache=True, nogil=True)
def _g_contexts(layout, h1, h2):
    """Buckets selecting the models of the second handle's two terms (non-border segments):
    layout 2 both by bucket(max(|h1|, |h2|)), layout 3 by bucket(h1) and bucket(h2)."""
    if layout >= 3:
        return _bucket(h1), _bucket(h2)
    hb = _bucket(max(abs(h1), abs(h2)))
    return hb, hb


@njit(cache=True, nogil=True)
def _enc_handle_terms(st, out, probs, layout, b, db, h1, h2, g1, g2):
    """The four handle terms of one segment: h1 by border flag and bucket(max|d|); then h2
    (by bucket(h1)), g1 and g2 (_g_contexts), or all three on the border models."""
    _enc_int(st, out, probs, M_HX + b * NB + db, h1)
    if b:
        _enc_int(st, out, probs, M_HY + BORDER_CTX, h2)
        _enc_int(st, out, probs, M_GX + BORDER_CTX, g1)
        _enc_int(st, out, probs, M_GY + BORDER_CTX, g2)
    else:
        _enc_int(st, out, probs, M_HY + _bucket(h1) * NB + db, h2)
        c1, c2 = _g_contexts(layout, h1, h2)
        _enc_int(st, out, probs, M_GX + c1 * NB + db, g1)
        _enc_int(st, out, probs, M_GY + c2 * NB + db, g2)


@njit(cache=True, nogil=True)
def _dec_handle_terms(ds, inp, probs, layout, b, db):
    """The inverse of _enc_handle_terms: (h1, h2, g1, g2)."""
    h1 = _dec_int(ds, inp, probs, M_HX + b * NB + db)
    if b:
        h2 = _dec_int(ds, inp, probs, M_HY + BORDER_CTX)
        g1 = _dec_int(ds, inp, probs, M_GX + BORDER_CTX)
        g2 = _dec_int(ds, inp, probs, M_GY + BORDER_CTX)
    else:
        h2 = _dec_int(ds, inp, probs, M_HY + _bucket(h1) * NB + db)
        c1, c2 = _g_contexts(layout, h1, h2)
        g1 = _dec_int(ds, inp, probs, M_GX + c1 * NB + db)
        g2 = _dec_int(ds, inp, probs, M_GY + c2 * NB + db)
    return h1, h2, g1, g2


@njit(cache=True, nogil=True)
def _shift_ctx(prev_h, db):
    """The model of a segment's handle shift: the previous shift and the chord's length."""
    return M_HS + 3 * prev_h + (0 if db <= 7 else (1 if db <= 9 else 2))


@njit(cache=True, nogil=True)
def _enc_handles(st, out, probs, layout, b, db, dx, dy, hx, hy, gx, gy, prev_h):
    """One segment's handle residuals h = (hx, hy), r = (gx, gy). Layout 2 codes them as
    they are; layout 3 in the chord's frame, (h.a, h.c) and (r.a, r.c), with r.a after
    -h.a / 2 (the two handles tend to grow and shrink together); layout 4 as 3, after the
    segment's handle shift (non-border segments): the largest sh <= MAX_HANDLE_SHIFT that
    divides all four frame terms, which are then coded divided by 2**sh. Returns sh."""
    sh = 0
    if layout >= 3:
        sg, p, q = _frame(dx, dy)
        hx, hy = _to_frame(sg, p, q, hx, hy)
        gx, gy = _to_frame(sg, p, q, gx, gy)
        if layout >= 4 and b == 0:
            low = hx | hy | gx | gy
            while sh < MAX_HANDLE_SHIFT and (low >> sh) & 1 == 0:
                sh += 1
            _enc_uint(st, out, probs, _shift_ctx(prev_h, db), sh)
            hx >>= sh
            hy >>= sh
            gx >>= sh
            gy >>= sh
        gx += (hx + 1) >> 1
    _enc_handle_terms(st, out, probs, layout, b, db, hx, hy, gx, gy)
    return sh


@njit(cache=True, nogil=True)
def _dec_handles(ds, inp, probs, layout, b, db, dx, dy, prev_h):
    """The inverse of _enc_handles: (hx, hy, gx, gy, sh); sh = -1 for a shift beyond
    MAX_HANDLE_SHIFT (a corrupt file)."""
    sh = 0
    if layout >= 4 and b == 0:
        sh = _dec_uint(ds, inp, probs, _shift_ctx(prev_h, db))
        if sh > MAX_HANDLE_SHIFT:
            return 0, 0, 0, 0, -1
    hx, hy, gx, gy = _dec_handle_terms(ds, inp, probs, layout, b, db)
    if layout >= 3:
        gx -= (hx + 1) >> 1
        hx <<= sh
        hy <<= sh
        gx <<= sh
        gy <<= sh
        sg, p, q = _frame(dx, dy)
        hx, hy = _from_frame(sg, p, q, hx, hy)
        gx, gy = _from_frame(sg, p, q, gx, gy)
    return hx, hy, gx, gy, sh


@njit(cache=True, nogil=True)
def _enc_flag4(st, out, probs, ctx, f):
    base = F_ANCHOR + 3 * ctx
    b1 = f & 1
    _enc_bit(st, out, probs, base, b1)
    _enc_bit(st, out, probs, base + 1 + b1, (f >> 1) & 1)


@njit(cache=True, nogil=True)
def _dec_flag4(ds, inp, probs, ctx):
    base = F_ANCHOR + 3 * ctx
    b1 = _dec_bit(ds, inp, probs, base)
    b2 = _dec_bit(ds, inp, probs, base + 1 + b1)
    return b1 | (b2 << 1)


@njit(cache=True, nogil=True)
def _anchor_flags(x, y, g):
    """Bit 1 where x, bit 2 where y lies on the anchor grid (multiples of 2**g, g > 0)."""
    mask = (1 << g) - 1
    return (1 if (x & mask) == 0 else 0) | (2 if (y & mask) == 0 else 0)


@njit(cache=True, nogil=True)
def _enc_coord(st, out, probs, coarse, m_coarse, m_fine, v, pred, g, half_g):
    """One point coordinate v against its prediction: on the anchor grid (``coarse``) as the
    difference of both on that grid, else as it is."""
    if coarse:
        _enc_int(st, out, probs, m_coarse, (v >> g) - ((pred + half_g) >> g))
    else:
        _enc_int(st, out, probs, m_fine, v - pred)


@njit(cache=True, nogil=True)
def _dec_coord(ds, inp, probs, coarse, m_coarse, m_fine, pred, g, half_g):
    """The inverse of _enc_coord: the coordinate."""
    if coarse:
        return (((pred + half_g) >> g) + _dec_int(ds, inp, probs, m_coarse)) << g
    return pred + _dec_int(ds, inp, probs, m_fine)


@njit(cache=True, nogil=True)
def _enc_contours(st, out, probs, level, nseg, parent):
    """The contour table: per contour its parent (rank among the candidates, or the distance
    back), its level (against the parent's, or the previous contour's) and segment count."""
    prev_rank = 0
    for k in range(level.shape[0]):
        out = _grow(out, st[4] + st[3] + 1024)
        r = _rank_of(parent, k, parent[k])
        _enc_uint(st, out, probs, M_RANK + min(prev_rank, 3), r)
        if r == 0:
            _enc_int(st, out, probs, M_FAR, k - parent[k])
        prev_rank = r
        p = parent[k]
        if 0 <= p < k:
            _enc_int(st, out, probs, M_LEVEL_REL, level[k] - level[p])
        else:
            _enc_int(st, out, probs, M_LEVEL_ABS, level[k] - (level[k - 1] if k > 0 else 0))
        _enc_uint(st, out, probs, M_NSEG, nseg[k] - 1)
    return out


@njit(cache=True, nogil=True)
def _predict_next(ax, ay, pdx, pdy, layout):
    """The prediction of a segment's next anchor N: A (layout 2), A + half the previous
    chord (pdx, pdy) from layout 3."""
    if layout >= 3:
        return ax + (pdx >> 1), ay + (pdy >> 1)
    return ax, ay


@njit(cache=True, nogil=True)
def _chord(ax, ay, nx, ny):
    """A segment's chord A -> N and the bucket of its longer component."""
    dx = nx - ax
    dy = ny - ay
    return dx, dy, _bucket(max(abs(dx), abs(dy)))


@njit(cache=True, nogil=True)
def _enc_chain(st, out, probs, pts, border, t, s0, n, g, layout, px0, py0, prev_h):
    """One contour's points (its n segments from pts[t], flags from border[s0]): P0 against
    the previous contour's, then per segment its border flag, the next anchor N against A
    (plus half the previous chord from layout 3) and the handles. Returns (out, prev_h)."""
    half_g = (1 << g) >> 1
    x0 = pts[t, 0]
    y0 = pts[t, 1]
    out = _grow(out, st[4] + st[3] + 1024)
    f = 0
    if g > 0:
        f = _anchor_flags(x0, y0, g)
        _enc_flag4(st, out, probs, 4, f)
    _enc_coord(st, out, probs, f & 1, M_P0C, M_P0F, x0, px0, g, half_g)
    _enc_coord(st, out, probs, f & 2, M_P0C + 1, M_P0F + 1, y0, py0, g, half_g)
    prev_b = 2
    prev_f = f
    dbk = 0
    pdx = np.int64(0)
    pdy = np.int64(0)
    for i in range(n):
        out = _grow(out, st[4] + st[3] + 2048)
        ax = pts[t + 3 * i, 0]
        ay = pts[t + 3 * i, 1]
        if i < n - 1:
            nx = pts[t + 3 * i + 3, 0]
            ny = pts[t + 3 * i + 3, 1]
        else:
            nx = x0
            ny = y0
        b = np.int64(border[s0 + i])
        _enc_bit(st, out, probs, F_BORDER + prev_b, b)
        prev_b = b
        if i < n - 1:
            f = 0
            if g > 0:
                f = _anchor_flags(nx, ny, g)
                _enc_flag4(st, out, probs, prev_f, f)
            prev_f = f
            bx, by = _predict_next(ax, ay, pdx, pdy, layout)
            _enc_coord(st, out, probs, f & 1, M_DCX + b * NB + dbk, M_DFX + b * NB + dbk, nx, bx, g, half_g)
            ybk = _bucket(nx - ax)
            _enc_coord(st, out, probs, f & 2, M_DCY + b * NB + ybk, M_DFY + b * NB + ybk, ny, by, g, half_g)
        dx, dy, db = _chord(ax, ay, nx, ny)
        pdx, pdy, dbk = dx, dy, db
        hx = pts[t + 3 * i + 1, 0] - ax - _rnd3(dx)
        hy = pts[t + 3 * i + 1, 1] - ay - _rnd3(dy)
        gx = pts[t + 3 * i + 2, 0] - nx + _rnd3(dx)
        gy = pts[t + 3 * i + 2, 1] - ny + _rnd3(dy)
        sh = _enc_handles(st, out, probs, layout, b, db, dx, dy, hx, hy, gx, gy, prev_h)
        if b == 0:
            prev_h = sh
    return out, prev_h


@njit(cache=True, nogil=True)
def _enc_caps(st, out, probs, level, nseg, pts, cap_contour, cap_band, cap_xy, cap_value,
              s_p, s_c, s_v, levels, base_band):
    """The caps: contour (against the previous cap's), band (against its contour's level),
    position (against its contour's P0) and value (against the level's)."""
    c = level.shape[0]
    half_c = (1 << s_c) >> 1
    prev_cc = -1
    first = np.zeros(c, np.int64)
    t = 0
    for k in range(c):
        first[k] = t
        t += 3 * nseg[k]
    for i in range(cap_contour.shape[0]):
        out = _grow(out, st[4] + st[3] + 1024)
        cc = cap_contour[i]
        _enc_int(st, out, probs, M_CC, cc - prev_cc)
        prev_cc = cc
        ox = np.int64(0)
        oy = np.int64(0)
        vpred = np.int64(0)
        if cc >= 0:
            rel = cap_band[i] - level[cc]
            _enc_int(st, out, probs, M_BAND_REL, rel)
            ctx = rel if 0 <= rel <= 1 else 2
            ox = pts[first[cc], 0] << s_p
            oy = pts[first[cc], 1] << s_p
            vpred = _level_pred(levels, level[cc], s_v)
        else:
            _enc_int(st, out, probs, M_BAND_ROOT, cap_band[i] - base_band)
            ctx = 2
        _enc_int(st, out, probs, M_CXY, cap_xy[i, 0] - ((ox + half_c) >> s_c))
        _enc_int(st, out, probs, M_CXY + 1, cap_xy[i, 1] - ((oy + half_c) >> s_c))
        _enc_int(st, out, probs, M_CVAL + ctx, cap_value[i] - vpred)
    return out


@njit(cache=True, nogil=True)
def new_state(account):
    """A coder's state: low, range, cache, cache_size, pos, then, when accounting, the first
    flag slot and the bits spent per model and flag slot (millionths)."""
    st = np.zeros(5 + (1 + N_MODELS + 18 if account else 0), np.int64)
    st[1] = 0xFFFFFFFF
    st[3] = 1
    if account:
        st[5] = F_BORDER
    return st


@njit(cache=True, nogil=True)
def encode_channel(level, nseg, parent, pts, border, g, cap_contour, cap_band, cap_xy, cap_value,
                   s_p, s_c, s_v, levels, base_band, layout, account, part_segments=PART_SEGMENTS):
    """One channel's own stream (uint8 array), and the bits spent in it per model and flag
    slot (float64, N_MODELS + 18 entries; all 0 unless ``account``: it slows coding down).
    Before layout 5 the stream is the channel's coded bytes; from layout 5 it holds the
    contours, the first part of the points and the caps, and rangecoded.code_channel adds
    the later parts (encode_part) and their table.

    level, nseg, parent : (C,) int64.
    pts : (3 S, 2) int64: the stored points (no closing points) on the point grid.
    border : (S,) uint8.
    g : anchor grid shift (0: no anchor flags).
    cap_contour, cap_band : (K,) int64; cap_xy : (K, 2) int64 on the cap grid;
    cap_value : (K,) int64 on the value grid.
    s_p, s_c, s_v : the grids' shifts from 1/64; levels : (L,) float64; base_band : int.
    layout : 2 to 5, the format version whose predictions to use (3: chords after half the
        previous chord, handles in the chord's frame; 4: 3 and the handle shifts; 5: 4 with the
        points in parts of part_segments, part_starts).
    """
    probs = new_probs_kernel()
    st = new_state(account)
    c = level.shape[0]
    out = np.empty(64 + 4 * c + 8 * pts.shape[0] + 8 * cap_contour.shape[0], np.uint8)
    out = _enc_contours(st, out, probs, level, nseg, parent)
    starts = part_starts(nseg, part_segments if layout >= 5 else 0)
    out = _enc_points(st, out, probs, pts, border, nseg, 0, starts[1], first_points(nseg), g, layout)
    out = _enc_caps(st, out, probs, level, nseg, pts, cap_contour, cap_band, cap_xy, cap_value,
                    s_p, s_c, s_v, levels, base_band)
    out = _grow(out, st[4] + st[3] + 16)
    bits = np.zeros(N_MODELS + 18)
    if account:
        bits[:] = st[6:] / 1e6
    return _finish(st, out), bits


@njit(cache=True, nogil=True)
def first_points(nseg):
    """(C + 1,) each contour's first stored point (3 a segment before it), then the total."""
    t0 = np.zeros(nseg.shape[0] + 1, np.int64)
    for k in range(nseg.shape[0]):
        t0[k + 1] = t0[k] + 3 * nseg[k]
    return t0


@njit(cache=True, nogil=True)
def encode_part(pst, pts, border, nseg, k0, k1, t0, g, layout):
    """Contours k0 .. k1 - 1's points as a part of their own (layout 5): a fresh stream and
    probabilities; pst (new_state) is left with the stream's state, its accounting included.
    t0: first_points."""
    pout = np.empty(64 + 8 * (t0[k1] - t0[k0]), np.uint8)
    pout = _enc_points(pst, pout, new_probs_kernel(), pts, border, nseg, k0, k1, t0, g, layout)
    pout = _grow(pout, pst[4] + pst[3] + 16)
    return _finish(pst, pout)


@njit(cache=True, nogil=True)
def part_starts(nseg, part_segments):
    """The first contour of each part of the points, and C: [0, ..., C] (layout 5). A part
    ends after the contour that brings it to part_segments segments or more (0: one part)."""
    c = nseg.shape[0]
    out = np.empty(c + 2, np.int64)
    out[0] = 0
    n = 1
    acc = 0
    for k in range(c):
        acc += nseg[k]
        if part_segments > 0 and acc >= part_segments and k + 1 < c:
            out[n] = k + 1
            n += 1
            acc = 0
    out[n] = c
    return out[: n + 1].copy()


@njit(cache=True, nogil=True)
def _enc_points(st, out, probs, pts, border, nseg, k0, k1, t0, g, layout):
    """Contours k0 .. k1 - 1's points, P0 of k0 against (0, 0) and the handle-shift context
    from 0: a part of the points (the whole of them before layout 5)."""
    prev_h = 0
    px0 = np.int64(0)  # the previous contour's P0
    py0 = np.int64(0)
    for k in range(k0, k1):
        t = t0[k]
        out, prev_h = _enc_chain(st, out, probs, pts, border, t, t // 3, nseg[k], g, layout, px0, py0, prev_h)
        px0 = pts[t, 0]
        py0 = pts[t, 1]
    return out


@njit(cache=True, nogil=True)
def new_probs_kernel():
    """All the probabilities of one channel, at 1/2: (2 * N_SLOTS,) int32 (fast, slow)."""
    return np.full(2 * N_SLOTS, PROB_INIT, np.int32)


@njit(cache=True, nogil=True)
def _dec_contours(ds, inp, probs, s, n_levels, level, nseg, parent):
    """The inverse of _enc_contours, checking as it goes: (status, where, what)."""
    c = level.shape[0]
    prev_rank = 0
    total = 0
    for j in range(c):
        r = _dec_uint(ds, inp, probs, M_RANK + min(prev_rank, 3))
        if r == 0:
            p = j - _dec_int(ds, inp, probs, M_FAR)
            if p < -1 or p >= c:
                return E_PARENT, j, p
        else:
            if r > PATH_MAX:
                return E_RANK, j, r
            p = _candidate(parent, j, r)
            if p == -2:
                return E_RANK, j, r
        parent[j] = p
        prev_rank = r
        if 0 <= p < j:
            lv = level[p] + _dec_int(ds, inp, probs, M_LEVEL_REL)
        else:
            lv = (level[j - 1] if j > 0 else 0) + _dec_int(ds, inp, probs, M_LEVEL_ABS)
        if lv < 0 or lv >= n_levels:
            return E_LEVEL, j, lv
        level[j] = lv
        n = _dec_uint(ds, inp, probs, M_NSEG) + 1
        total += n
        if total > s:
            return E_NSEG, j, total
        nseg[j] = n
    if total != s:
        return E_NSEG_SHORT, c, total
    return OK, 0, 0


@njit(cache=True, nogil=True)
def _dec_chain(ds, inp, probs, q, border, t, s0, n, g, layout, lim, px0, py0, prev_h):
    """The inverse of _enc_chain into q[t:] (on the point grid, closed) and border[s0:],
    checking every point against lim: (status, x0, y0, prev_h), status OK, E_POINT or
    E_SHIFT."""
    half_g = (1 << g) >> 1
    f = 0
    if g > 0:
        f = _dec_flag4(ds, inp, probs, 4)
    x0 = _dec_coord(ds, inp, probs, f & 1, M_P0C, M_P0F, px0, g, half_g)
    y0 = _dec_coord(ds, inp, probs, f & 2, M_P0C + 1, M_P0F + 1, py0, g, half_g)
    if abs(x0) >= lim or abs(y0) >= lim:
        return E_POINT, x0, y0, prev_h
    q[t, 0] = x0
    q[t, 1] = y0
    prev_b = 2
    prev_f = f
    dbk = 0
    pdx = np.int64(0)
    pdy = np.int64(0)
    ax = x0
    ay = y0
    for i in range(n):
        b = np.int64(_dec_bit(ds, inp, probs, F_BORDER + prev_b))
        border[s0 + i] = b
        prev_b = b
        if i < n - 1:
            f = 0
            if g > 0:
                f = _dec_flag4(ds, inp, probs, prev_f)
            prev_f = f
            bx, by = _predict_next(ax, ay, pdx, pdy, layout)
            nx = _dec_coord(ds, inp, probs, f & 1, M_DCX + b * NB + dbk, M_DFX + b * NB + dbk, bx, g, half_g)
            ybk = _bucket(nx - ax)
            ny = _dec_coord(ds, inp, probs, f & 2, M_DCY + b * NB + ybk, M_DFY + b * NB + ybk, by, g, half_g)
            if abs(nx) >= lim or abs(ny) >= lim:
                return E_POINT, x0, y0, prev_h
        else:
            nx = x0
            ny = y0
        dx, dy, db = _chord(ax, ay, nx, ny)
        pdx, pdy, dbk = dx, dy, db
        hx, hy, gx, gy, sh = _dec_handles(ds, inp, probs, layout, b, db, dx, dy, prev_h)
        if sh < 0:
            return E_SHIFT, x0, y0, prev_h
        if b == 0:
            prev_h = sh
        cax = ax + _rnd3(dx) + hx
        cay = ay + _rnd3(dy) + hy
        cbx = nx - _rnd3(dx) + gx
        cby = ny - _rnd3(dy) + gy
        if abs(cax) >= lim or abs(cay) >= lim or abs(cbx) >= lim or abs(cby) >= lim:
            return E_POINT, x0, y0, prev_h
        q[t + 3 * i + 1, 0] = cax
        q[t + 3 * i + 1, 1] = cay
        q[t + 3 * i + 2, 0] = cbx
        q[t + 3 * i + 2, 1] = cby
        q[t + 3 * i + 3, 0] = nx
        q[t + 3 * i + 3, 1] = ny
        ax = nx
        ay = ny
    return OK, x0, y0, prev_h


@njit(cache=True, nogil=True)
def _dec_points(ds, inp, probs, nseg, q, border, first, g, s_p, layout):
    """Every contour's points (_dec_chain), then q from the point grid to 1/64 px:
    (status, where, what)."""
    status, where, what = decode_part(ds, inp, probs, nseg, q, border, first, 0, nseg.shape[0], g, s_p, layout)
    if status == OK:
        shift_points(q, s_p)
    return status, where, what


@njit(cache=True, nogil=True)
def decode_part(ds, inp, probs, nseg, q, border, first, k0, k1, g, s_p, layout):
    """Contours k0 .. k1 - 1's points into q (on the point grid) and border, and their first
    points' rows into first (also those of the contours before k0, which the points of these
    do not depend on): the inverse of _enc_points, (status, where, what). Parts write disjoint
    rows of q, border and first, so that threads may decode them side by side."""
    lim = LIMIT >> s_p  # |u << s_p| < LIMIT  <=>  |u| < lim (s_p <= 6)
    t = 0
    s0 = 0
    for j in range(k0):
        t += 3 * nseg[j] + 1
        s0 += nseg[j]
    prev_h = 0
    px0 = np.int64(0)
    py0 = np.int64(0)
    for j in range(k0, k1):
        n = nseg[j]
        first[j] = t
        status, px0, py0, prev_h = _dec_chain(ds, inp, probs, q, border, t, s0, n, g, layout, lim, px0, py0, prev_h)
        if status != OK:
            return status, j, 0
        t += 3 * n + 1
        s0 += n
    return OK, 0, 0


@njit(cache=True, nogil=True)
def shift_points(q, s_p):
    """q from the point grid to 1/64 px."""
    if s_p > 0:
        for i in range(q.shape[0]):
            q[i, 0] <<= s_p
            q[i, 1] <<= s_p


@njit(cache=True, nogil=True)
def _dec_caps(ds, inp, probs, level, q, first, s_c, s_v, levels, base_band, cap_contour, cap_band, cap_xy,
              cap_value):
    """The inverse of _enc_caps (q in 1/64 px), checking as it goes: (status, where, what)."""
    c = level.shape[0]
    half_c = (1 << s_c) >> 1
    prev_cc = -1
    for i in range(cap_contour.shape[0]):
        cc = prev_cc + _dec_int(ds, inp, probs, M_CC)
        if cc < -1 or cc >= c:
            return E_CAP_CONTOUR, i, cc
        cap_contour[i] = cc
        prev_cc = cc
        ox = np.int64(0)
        oy = np.int64(0)
        vpred = np.int64(0)
        if cc >= 0:
            rel = _dec_int(ds, inp, probs, M_BAND_REL)
            cap_band[i] = level[cc] + rel
            ctx = rel if 0 <= rel <= 1 else 2
            ox = q[first[cc], 0]
            oy = q[first[cc], 1]
            vpred = _level_pred(levels, level[cc], s_v)
        else:
            cap_band[i] = base_band + _dec_int(ds, inp, probs, M_BAND_ROOT)
            ctx = 2
        x = ((ox + half_c) >> s_c) + _dec_int(ds, inp, probs, M_CXY)
        y = ((oy + half_c) >> s_c) + _dec_int(ds, inp, probs, M_CXY + 1)
        if abs(x << s_c) >= LIMIT or abs(y << s_c) >= LIMIT:
            return E_CAP_XY, i, 0
        cap_xy[i, 0] = x << s_c
        cap_xy[i, 1] = y << s_c
        v = vpred + _dec_int(ds, inp, probs, M_CVAL + ctx)
        if abs(v << s_v) >= LIMIT:
            return E_CAP_VALUE, i, 0
        cap_value[i] = v << s_v
    return OK, 0, 0


@njit(cache=True, nogil=True)
def decode_channel(inp, c, s, k, g, s_p, s_c, s_v, levels, base_band, layout):
    """The inverse of encode_channel for layouts 2, 3 and 4, checking as it goes (layout 5:
    decode_contours, decode_part and decode_caps, which its parts need apart).

    Returns (status, where, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy,
    cap_value): q is (3 S + C, 2) int64 in 1/64 px with every chain closed; cap_xy and
    cap_value in 1/64 units. ``status`` is OK or an E_* code, ``where`` the entry it concerns.
    """
    status, where, what, level, nseg, parent, ds, probs = decode_contours(inp, c, s, levels.shape[0])
    q = np.zeros((3 * s + c, 2), np.int64)
    border = np.zeros(s, np.uint8)
    first = np.zeros(c, np.int64)  # each contour's P0 in q
    if status == OK:
        status, where, what = _dec_points(ds, inp, probs, nseg, q, border, first, g, s_p, layout)
    cap_contour, cap_band, cap_xy, cap_value = new_caps(k)
    if status == OK:
        status, where, what = decode_caps(ds, inp, probs, level, q, first, s_c, s_v, levels, base_band,
                                          cap_contour, cap_band, cap_xy, cap_value)
    return (status, where, what, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)


@njit(cache=True, nogil=True)
def decode_contours(inp, c, s, n_levels):
    """A channel's contour table from the start of its stream: (status, where, what, level,
    nseg, parent, ds, probs), ds and probs the stream's state after it."""
    probs = new_probs_kernel()
    ds = _dec_init(inp)
    level = np.zeros(c, np.int64)
    nseg = np.zeros(c, np.int64)
    parent = np.zeros(c, np.int64)
    status, where, what = _dec_contours(ds, inp, probs, s, n_levels, level, nseg, parent)
    return status, where, what, level, nseg, parent, ds, probs


@njit(cache=True, nogil=True)
def new_caps(k):
    return np.zeros(k, np.int64), np.zeros(k, np.int64), np.zeros((k, 2), np.int64), np.zeros(k, np.int64)


@njit(cache=True, nogil=True)
def decode_caps(ds, inp, probs, level, q, first, s_c, s_v, levels, base_band, cap_contour, cap_band, cap_xy,
                cap_value):
    """The caps after the points (q in 1/64 px), then the stream's end: (status, where, what)."""
    status, where, what = _dec_caps(ds, inp, probs, level, q, first, s_c, s_v, levels, base_band,
                                    cap_contour, cap_band, cap_xy, cap_value)
    if status == OK:
        status = _dec_status(ds, inp)
    return status, where, what


@njit(cache=True, nogil=True)
def start_part(inp):
    """A part's own stream (layout 5): its decoder state and fresh probabilities."""
    return _dec_init(inp), new_probs_kernel()


@njit(cache=True, nogil=True)
def end_part(ds, inp):
    """OK where a part's stream ended exactly, else E_SHORT or E_LONG."""
    return _dec_status(ds, inp)
