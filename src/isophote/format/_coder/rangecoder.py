"""The .isoph range coder (kernels): an adaptive binary range coder with context-modelled
integers, on which format/_coder/entropy.py builds the channel layout. Its plain-Python twin is
rangecoder_ref.py (the same coder from the specification's text).

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

# decoder status codes of the stream itself (entropy.py adds the layout's)
OK = 0
E_SHORT = 10
E_LONG = 11


# =============================================================================================
# The coder
# =============================================================================================


@njit(cache=True, nogil=True)
def _shift_low(st, out):
    # st: low, range, cache, cache_size, pos (then, when accounting, see _enc_bit)
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
        n_ms = st[5]  # the slots of the integer models, before the flags' (encode_channel)
        i = slot // MODEL_SLOTS if slot < n_ms else n_ms // MODEL_SLOTS + slot - n_ms
        st[6 + i] += np.int64(-1e6 * np.log2(p0 if bit == 0 else 1.0 - p0))
    low = st[0]
    if bit == 0:
        rng = bound
        probs[2 * slot] = a + ((PROB_ONE - a) >> RATE_FAST)
        probs[2 * slot + 1] = b + ((PROB_ONE - b) >> RATE_SLOW)
    else:
        low += bound
        rng -= bound
        probs[2 * slot] = a - (a >> RATE_FAST)
        probs[2 * slot + 1] = b - (b >> RATE_SLOW)
    # _shift_low written out, low kept in a local: with the call here the coder codes a bit
    # 6-8 x slower than the decoder reads one (27 against 3.5 ns; numba inlines neither), and
    # a shared helper that takes and returns low is as slow, plain or inline="always" (5 M
    # integers 1.78 s against 0.75; the mosaic's luma 13.1 s against 6.1)
    while rng < TOP:
        rng <<= 8
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
        low = (low & 0x00FFFFFF) << 8
    st[0] = low
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
