"""The .isoph range coder: an adaptive binary range coder with context-modelled integers,
and the channel layout of compression code 3 ("range") on top of it (kernels).

The specification is in format/isoph.py ("Range-coded channels") and docs/format.md; the
plain-Python twin ``entropy_ref.py`` implements the same from that text, and the tests check
that both give the same bytes and the same arrays on random inputs. Everything here is
integer arithmetic (and one float multiply-and-floor on the writer's and reader's sides
alike), so the bytes are the same on every machine.

Coder
    LZMA's carry-less range coder (``low`` of 33 bits, 32-bit ``range``, renormalised a byte
    at a time below 2**24), without LZMA's always-zero first byte. A bit is coded with the
    probability of a 0, ``p / 2**15``, the mean of two adaptive estimates that move 1/16 and
    1/128 of the way towards each coded bit (a fast and a slow one). Each estimate starts at
    1/2.

Integers
    An unsigned v is coded as m = v + 1 = 2**k + rest: k in unary (a 1 per step, a 0 to stop,
    no stop bit at k = KMAX - 1), one adaptive bit per step; then the k bits of ``rest`` from
    the top: the first two through a bit tree (their probabilities depend on the bits before
    them; a tree per k), the others one probability per position from the top (shared by
    every k). These probabilities make the integer's *model* (MODEL_SLOTS of them), which
    learns the distribution of magnitudes and of their leading bits. A signed v is |v| then,
    when v is not 0, a sign bit (1 = negative) with its own probability.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...shared.grid import chord_frame as _frame, from_frame as _from_frame, rnd3 as _rnd3, to_frame as _to_frame

# ---- coder constants -----------------------------------------------------------------------

PROB_BITS = 15
PROB_ONE = 1 << PROB_BITS
PROB_INIT = PROB_ONE >> 1
RATE_FAST = 4
RATE_SLOW = 7
TOP = 1 << 24
KMAX = 40  # unsigned values up to 2**40 - 2
UNARY_SLOTS = KMAX - 1
TREE_SLOTS = UNARY_SLOTS  # 3 per bit length k: the bit tree of the top two mantissa bits
LOW_SLOTS = TREE_SLOTS + 3 * KMAX  # one per position (from the top) of the lower mantissa bits
SIGN_SLOT = LOW_SLOTS + KMAX
MODEL_SLOTS = SIGN_SLOT + 1
MAX_UINT = (1 << KMAX) - 2

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
BORDER_CTX = NB * NB  # the HY/GX/GY model of border segments

LIMIT = 1 << 30  # |coordinate| and |cap value| in 1/64 units (isoph.COORD_LIMIT)

# decoder status codes (format/isoph.py turns them into messages)
OK = 0
E_RANK = 1
E_PARENT = 2
E_LEVEL = 3
E_NSEG = 4
E_NSEG_SHORT = 5
E_POINT = 6
E_CAP_CONTOUR = 7
E_CAP_XY = 8
E_CAP_VALUE = 9
E_SHORT = 10
E_LONG = 11
E_SHIFT = 12


# =============================================================================================
# The coder
# =============================================================================================


@njit(cache=True, nogil=True)
def _shift_low(st, out):
    # st: low, range, cache, cache_size, pos
    low = st[0]
    if low < 0xFF000000 or low >= (1 << 32):
        carry = low >> 32
        temp = st[2]
        while True:
            out[st[4]] = (temp + carry) & 0xFF
            st[4] += 1
            temp = 0xFF
            st[3] -= 1
            if st[3] == 0:
                break
        st[2] = (low >> 24) & 0xFF
    st[3] += 1
    st[0] = (low & 0x00FFFFFF) << 8


@njit(cache=True, nogil=True)
def _enc_bit(st, out, probs, slot, bit):
    a = probs[2 * slot]
    b = probs[2 * slot + 1]
    p = (a + b) >> 1
    rng = st[1]
    bound = (rng >> PROB_BITS) * p
    if st.shape[0] > 5:  # accounting (benchmarks): bits spent per model, then per flag slot
        p0 = p / PROB_ONE
        i = slot // MODEL_SLOTS if slot < F_BORDER else N_MODELS + slot - F_BORDER
        st[5 + i] += np.int64(-1e6 * np.log2(p0 if bit == 0 else 1.0 - p0))
    if bit == 0:
        rng = bound
        probs[2 * slot] = a + ((PROB_ONE - a) >> RATE_FAST)
        probs[2 * slot + 1] = b + ((PROB_ONE - b) >> RATE_SLOW)
    else:
        st[0] += bound
        rng -= bound
        probs[2 * slot] = a - (a >> RATE_FAST)
        probs[2 * slot + 1] = b - (b >> RATE_SLOW)
    while rng < TOP:
        rng <<= 8
        _shift_low(st, out)
    st[1] = rng


@njit(cache=True, nogil=True)
def _dec_bit(ds, inp, probs, slot):
    # ds: code, range, pos, overrun
    a = probs[2 * slot]
    b = probs[2 * slot + 1]
    code = ds[0]
    rng = ds[1]
    bound = (rng >> PROB_BITS) * ((a + b) >> 1)
    if code < bound:
        rng = bound
        probs[2 * slot] = a + ((PROB_ONE - a) >> RATE_FAST)
        probs[2 * slot + 1] = b + ((PROB_ONE - b) >> RATE_SLOW)
        bit = 0
    else:
        code -= bound
        rng -= bound
        probs[2 * slot] = a - (a >> RATE_FAST)
        probs[2 * slot + 1] = b - (b >> RATE_SLOW)
        bit = 1
    while rng < TOP:
        rng <<= 8
        byte = 0
        pos = ds[2]
        if pos < inp.shape[0]:
            byte = inp[pos]
        else:
            ds[3] = 1
        ds[2] = pos + 1
        code = ((code << 8) | byte) & 0xFFFFFFFF
    ds[0] = code
    ds[1] = rng
    return bit


@njit(cache=True, nogil=True)
def _enc_uint(st, out, probs, model, v):
    base = model * MODEL_SLOTS
    m = v + 1
    k = 0
    while (m >> (k + 1)) != 0:
        k += 1
    for j in range(UNARY_SLOTS):
        if j == k:
            _enc_bit(st, out, probs, base + j, 0)
            break
        _enc_bit(st, out, probs, base + j, 1)
    tree = base + TREE_SLOTS + 3 * k - 1
    node = 1
    for pos in range(k):
        bit = (m >> (k - 1 - pos)) & 1
        if pos < 2:
            _enc_bit(st, out, probs, tree + node, bit)
            node = 2 * node + bit
        else:
            _enc_bit(st, out, probs, base + LOW_SLOTS + pos, bit)


@njit(cache=True, nogil=True)
def _enc_int(st, out, probs, model, v):
    a = v if v >= 0 else -v
    _enc_uint(st, out, probs, model, a)
    if a != 0:
        _enc_bit(st, out, probs, model * MODEL_SLOTS + SIGN_SLOT, 1 if v < 0 else 0)


@njit(cache=True, nogil=True)
def _dec_uint(ds, inp, probs, model):
    base = model * MODEL_SLOTS
    k = 0
    while k < UNARY_SLOTS:
        if _dec_bit(ds, inp, probs, base + k) == 0:
            break
        k += 1
    tree = base + TREE_SLOTS + 3 * k - 1
    m = 1
    node = 1
    for pos in range(k):
        if pos < 2:
            bit = _dec_bit(ds, inp, probs, tree + node)
            node = 2 * node + bit
        else:
            bit = _dec_bit(ds, inp, probs, base + LOW_SLOTS + pos)
        m = 2 * m + bit
    return m - 1


@njit(cache=True, nogil=True)
def _dec_int(ds, inp, probs, model):
    a = _dec_uint(ds, inp, probs, model)
    if a != 0 and _dec_bit(ds, inp, probs, model * MODEL_SLOTS + SIGN_SLOT) == 1:
        return -a
    return a


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
def _grow(out, need):
    if need <= out.shape[0]:
        return out
    bigger = np.empty(max(need, 2 * out.shape[0]), np.uint8)
    bigger[: out.shape[0]] = out
    return bigger


@njit(cache=True, nogil=True)
def _finish(st, out):
    for _ in range(5):
        _shift_low(st, out)
    return out[1 : st[4]].copy()  # the first byte is always 0: not stored


# ---- a plain stream of integers (tests and benchmarks) ----------------------------------------


@njit(cache=True, nogil=True)
def _int_probs(models):
    """Fresh probabilities for integer models 0 .. max(models)."""
    nm = 0
    for i in range(models.shape[0]):
        nm = max(nm, models[i] + 1)
    return np.full(2 * max(nm, 1) * MODEL_SLOTS, PROB_INIT, np.int32)


@njit(cache=True, nogil=True)
def encode_ints(values, models, signed):
    """Code values[i] (int64) with integer model models[i]; signed or unsigned."""
    probs = _int_probs(models)
    st = np.array([0, 0xFFFFFFFF, 0, 1, 0], np.int64)
    out = np.empty(64, np.uint8)
    for i in range(values.shape[0]):
        out = _grow(out, st[4] + st[3] + 256)
        if signed:
            _enc_int(st, out, probs, models[i], values[i])
        else:
            _enc_uint(st, out, probs, models[i], values[i])
    out = _grow(out, st[4] + st[3] + 16)
    return _finish(st, out)


@njit(cache=True, nogil=True)
def decode_ints(inp, models, signed):
    """The inverse of encode_ints; returns (values, status) with status OK, E_SHORT or E_LONG."""
    probs = _int_probs(models)
    ds = _dec_init(inp)
    values = np.empty(models.shape[0], np.int64)
    for i in range(models.shape[0]):
        values[i] = _dec_int(ds, inp, probs, models[i]) if signed else _dec_uint(ds, inp, probs, models[i])
    return values, _dec_status(ds, inp)


@njit(cache=True, nogil=True)
def _dec_init(inp):
    ds = np.array([0, 0xFFFFFFFF, 0, 0], np.int64)
    for _ in range(4):
        byte = 0
        if ds[2] < inp.shape[0]:
            byte = inp[ds[2]]
        else:
            ds[3] = 1
        ds[2] += 1
        ds[0] = (ds[0] << 8) | byte
    return ds


@njit(cache=True, nogil=True)
def _dec_status(ds, inp):
    if ds[3] != 0:
        return E_SHORT
    if ds[2] != inp.shape[0]:
        return E_LONG
    return OK


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
def encode_channel(level, nseg, parent, pts, border, g, cap_contour, cap_band, cap_xy, cap_value,
                   s_p, s_c, s_v, levels, base_band, layout, account):
    """One channel's coded bytes (uint8 array), and the bits spent per model and flag slot
    (float64, N_MODELS + 18 entries; all 0 unless ``account``: it slows coding down).

    level, nseg, parent : (C,) int64.
    pts : (3 S, 2) int64: the stored points (no closing points) on the point grid.
    border : (S,) uint8.
    g : anchor grid shift (0: no anchor flags).
    cap_contour, cap_band : (K,) int64; cap_xy : (K, 2) int64 on the cap grid;
    cap_value : (K,) int64 on the value grid.
    s_p, s_c, s_v : the grids' shifts from 1/64; levels : (L,) float64; base_band : int.
    layout : 2, 3 or 4, the format version whose predictions to use (3: chords after half the
        previous chord, handles in the chord's frame; 4: 3 and the handle shifts).
    """
    probs = new_probs_kernel()
    st = np.zeros(5 + (N_MODELS + 18 if account else 0), np.int64)
    st[1] = 0xFFFFFFFF
    st[3] = 1
    c = level.shape[0]
    out = np.empty(64 + 4 * c + 8 * pts.shape[0] + 8 * cap_contour.shape[0], np.uint8)

    # contour table
    prev_rank = 0
    for k in range(c):
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

    # points
    half_g = (1 << g) >> 1
    prev_h = 0
    px0 = np.int64(0)
    py0 = np.int64(0)
    t = 0
    s0 = 0
    for k in range(c):
        n = nseg[k]
        x0 = pts[t, 0]
        y0 = pts[t, 1]
        out = _grow(out, st[4] + st[3] + 1024)
        f = 0
        if g > 0:
            f = (1 if (x0 & ((1 << g) - 1)) == 0 else 0) | (2 if (y0 & ((1 << g) - 1)) == 0 else 0)
            _enc_flag4(st, out, probs, 4, f)
        if f & 1:
            _enc_int(st, out, probs, M_P0C, (x0 >> g) - ((px0 + half_g) >> g))
        else:
            _enc_int(st, out, probs, M_P0F, x0 - px0)
        if f & 2:
            _enc_int(st, out, probs, M_P0C + 1, (y0 >> g) - ((py0 + half_g) >> g))
        else:
            _enc_int(st, out, probs, M_P0F + 1, y0 - py0)
        px0 = x0
        py0 = y0
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
                    f = (1 if (nx & ((1 << g) - 1)) == 0 else 0) | (2 if (ny & ((1 << g) - 1)) == 0 else 0)
                    _enc_flag4(st, out, probs, prev_f, f)
                prev_f = f
                bx = ax  # N's prediction: A (layout 2), A + half the previous chord (3)
                by = ay
                if layout >= 3:
                    bx += pdx >> 1
                    by += pdy >> 1
                if f & 1:
                    _enc_int(st, out, probs, M_DCX + b * NB + dbk, (nx >> g) - ((bx + half_g) >> g))
                else:
                    _enc_int(st, out, probs, M_DFX + b * NB + dbk, nx - bx)
                ybk = _bucket(nx - ax)
                if f & 2:
                    _enc_int(st, out, probs, M_DCY + b * NB + ybk, (ny >> g) - ((by + half_g) >> g))
                else:
                    _enc_int(st, out, probs, M_DFY + b * NB + ybk, ny - by)
            dx = nx - ax
            dy = ny - ay
            pdx = dx
            pdy = dy
            db = _bucket(max(abs(dx), abs(dy)))
            dbk = db
            hx = pts[t + 3 * i + 1, 0] - ax - _rnd3(dx)
            hy = pts[t + 3 * i + 1, 1] - ay - _rnd3(dy)
            gx = pts[t + 3 * i + 2, 0] - nx + _rnd3(dx)
            gy = pts[t + 3 * i + 2, 1] - ny + _rnd3(dy)
            sh = _enc_handles(st, out, probs, layout, b, db, dx, dy, hx, hy, gx, gy, prev_h)
            if b == 0:
                prev_h = sh
        t += 3 * n
        s0 += n

    # caps
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
    out = _grow(out, st[4] + st[3] + 16)
    bits = np.zeros(N_MODELS + 18)
    if account:
        bits[:] = st[5:] / 1e6
    return _finish(st, out), bits


@njit(cache=True, nogil=True)
def new_probs_kernel():
    """All the probabilities of one channel, at 1/2: (2 * N_SLOTS,) int32 (fast, slow)."""
    return np.full(2 * N_SLOTS, PROB_INIT, np.int32)


@njit(cache=True, nogil=True)
def decode_channel(inp, c, s, k, g, s_p, s_c, s_v, levels, base_band, layout):
    """The inverse of encode_channel (``layout`` 2, 3 or 4), checking as it goes.

    Returns (status, where, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy,
    cap_value): q is (3 S + C, 2) int64 in 1/64 px with every chain closed; cap_xy and
    cap_value in 1/64 units. ``status`` is OK or an E_* code, ``where`` the entry it concerns.
    """
    n_levels = levels.shape[0]
    probs = new_probs_kernel()
    ds = _dec_init(inp)
    level = np.zeros(c, np.int64)
    nseg = np.zeros(c, np.int64)
    parent = np.zeros(c, np.int64)
    q = np.zeros((3 * s + c, 2), np.int64)
    border = np.zeros(s, np.uint8)
    cap_contour = np.zeros(k, np.int64)
    cap_band = np.zeros(k, np.int64)
    cap_xy = np.zeros((k, 2), np.int64)
    cap_value = np.zeros(k, np.int64)

    # contour table
    prev_rank = 0
    total = 0
    for j in range(c):
        r = _dec_uint(ds, inp, probs, M_RANK + min(prev_rank, 3))
        if r == 0:
            p = j - _dec_int(ds, inp, probs, M_FAR)
            if p < -1 or p >= c:
                return (E_PARENT, j, p, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
        else:
            if r > PATH_MAX:
                return (E_RANK, j, r, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
            p = _candidate(parent, j, r)
            if p == -2:
                return (E_RANK, j, r, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
        parent[j] = p
        prev_rank = r
        if 0 <= p < j:
            lv = level[p] + _dec_int(ds, inp, probs, M_LEVEL_REL)
        else:
            lv = (level[j - 1] if j > 0 else 0) + _dec_int(ds, inp, probs, M_LEVEL_ABS)
        if lv < 0 or lv >= n_levels:
            return (E_LEVEL, j, lv, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
        level[j] = lv
        n = _dec_uint(ds, inp, probs, M_NSEG) + 1
        total += n
        if total > s:
            return (E_NSEG, j, total, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
        nseg[j] = n
    if total != s:
        return (E_NSEG_SHORT, c, total, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)

    # points (on the point grid while decoding; checked against the limit in 1/64 px)
    lim = LIMIT >> s_p  # |u << s_p| < LIMIT  <=>  |u| < lim (s_p <= 6)
    half_g = (1 << g) >> 1
    prev_h = 0
    px0 = np.int64(0)
    py0 = np.int64(0)
    t = 0
    s0 = 0
    first = np.zeros(c, np.int64)
    for j in range(c):
        n = nseg[j]
        first[j] = t
        f = 0
        if g > 0:
            f = _dec_flag4(ds, inp, probs, 4)
        if f & 1:
            x0 = (((px0 + half_g) >> g) + _dec_int(ds, inp, probs, M_P0C)) << g
        else:
            x0 = px0 + _dec_int(ds, inp, probs, M_P0F)
        if f & 2:
            y0 = (((py0 + half_g) >> g) + _dec_int(ds, inp, probs, M_P0C + 1)) << g
        else:
            y0 = py0 + _dec_int(ds, inp, probs, M_P0F + 1)
        if abs(x0) >= lim or abs(y0) >= lim:
            return (E_POINT, j, 0, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
        px0 = x0
        py0 = y0
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
                bx = ax
                by = ay
                if layout >= 3:
                    bx += pdx >> 1
                    by += pdy >> 1
                if f & 1:
                    nx = (((bx + half_g) >> g) + _dec_int(ds, inp, probs, M_DCX + b * NB + dbk)) << g
                else:
                    nx = bx + _dec_int(ds, inp, probs, M_DFX + b * NB + dbk)
                ybk = _bucket(nx - ax)
                if f & 2:
                    ny = (((by + half_g) >> g) + _dec_int(ds, inp, probs, M_DCY + b * NB + ybk)) << g
                else:
                    ny = by + _dec_int(ds, inp, probs, M_DFY + b * NB + ybk)
                if abs(nx) >= lim or abs(ny) >= lim:
                    return (E_POINT, j, 0, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
            else:
                nx = x0
                ny = y0
            dx = nx - ax
            dy = ny - ay
            pdx = dx
            pdy = dy
            db = _bucket(max(abs(dx), abs(dy)))
            dbk = db
            hx, hy, gx, gy, sh = _dec_handles(ds, inp, probs, layout, b, db, dx, dy, prev_h)
            if sh < 0:
                return (E_SHIFT, j, 0, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
            if b == 0:
                prev_h = sh
            cax = ax + _rnd3(dx) + hx
            cay = ay + _rnd3(dy) + hy
            cbx = nx - _rnd3(dx) + gx
            cby = ny - _rnd3(dy) + gy
            if abs(cax) >= lim or abs(cay) >= lim or abs(cbx) >= lim or abs(cby) >= lim:
                return (E_POINT, j, 0, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
            q[t + 3 * i + 1, 0] = cax
            q[t + 3 * i + 1, 1] = cay
            q[t + 3 * i + 2, 0] = cbx
            q[t + 3 * i + 2, 1] = cby
            q[t + 3 * i + 3, 0] = nx
            q[t + 3 * i + 3, 1] = ny
            ax = nx
            ay = ny
        t += 3 * n + 1
        s0 += n
    if s_p > 0:
        for i in range(q.shape[0]):
            q[i, 0] <<= s_p
            q[i, 1] <<= s_p

    # caps
    half_c = (1 << s_c) >> 1
    prev_cc = -1
    for i in range(k):
        cc = prev_cc + _dec_int(ds, inp, probs, M_CC)
        if cc < -1 or cc >= c:
            return (E_CAP_CONTOUR, i, cc, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
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
            return (E_CAP_XY, i, 0, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
        cap_xy[i, 0] = x << s_c
        cap_xy[i, 1] = y << s_c
        v = vpred + _dec_int(ds, inp, probs, M_CVAL + ctx)
        if abs(v << s_v) >= LIMIT:
            return (E_CAP_VALUE, i, 0, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
        cap_value[i] = v << s_v
    status = _dec_status(ds, inp)
    return (status, 0, 0, level, nseg, parent, q, border, cap_contour, cap_band, cap_xy, cap_value)
