"""The plain-Python twin of ``rangecoder.py``: the same range coder and integer models,
written as directly from the specification (format/isoph.py, "Range-coded channels") as
possible, with Python integers and objects. entropy_ref.py builds the channel layout on it.
"""

from __future__ import annotations

# The constants are the specification's; they are repeated here, not imported, so that a
# change to one implementation cannot silently change the other.
PROB_ONE = 1 << 15
KMAX = 40


class Bit:
    """One adaptive probability: the mean of a fast and a slow estimate of P(bit = 0)."""

    __slots__ = ("fast", "slow")

    def __init__(self):
        self.fast = self.slow = PROB_ONE // 2

    def p0(self) -> int:
        return (self.fast + self.slow) >> 1

    def update(self, bit: int) -> None:
        if bit == 0:
            self.fast += (PROB_ONE - self.fast) >> 4
            self.slow += (PROB_ONE - self.slow) >> 7
        else:
            self.fast -= self.fast >> 4
            self.slow -= self.slow >> 7


class Encoder:
    def __init__(self):
        self.low = 0
        self.range = 0xFFFFFFFF
        self.cache = 0
        self.pending = 1  # bytes held back: the cache and a run of 0xFF after it
        self.out = bytearray()

    def _shift_low(self):
        if self.low < 0xFF000000 or self.low >= 1 << 32:
            carry = self.low >> 32
            byte = self.cache
            while self.pending:
                self.out.append((byte + carry) & 0xFF)
                byte = 0xFF
                self.pending -= 1
            self.cache = (self.low >> 24) & 0xFF
        self.pending += 1
        self.low = (self.low & 0x00FFFFFF) << 8

    def bit(self, model: Bit, bit: int) -> None:
        bound = (self.range >> 15) * model.p0()
        if bit == 0:
            self.range = bound
        else:
            self.low += bound
            self.range -= bound
        model.update(bit)
        while self.range < 1 << 24:
            self.range <<= 8
            self._shift_low()

    def finish(self) -> bytes:
        for _ in range(5):
            self._shift_low()
        assert self.out[0] == 0
        return bytes(self.out[1:])


class Decoder:
    def __init__(self, data: bytes):
        self.data = data
        self.pos = 0
        self.overrun = False
        self.range = 0xFFFFFFFF
        self.code = 0
        for _ in range(4):
            self.code = (self.code << 8) | self._byte()

    def _byte(self) -> int:
        if self.pos < len(self.data):
            b = self.data[self.pos]
        else:
            b, self.overrun = 0, True
        self.pos += 1
        return b

    def bit(self, model: Bit) -> int:
        bound = (self.range >> 15) * model.p0()
        if self.code < bound:
            self.range = bound
            bit = 0
        else:
            self.code -= bound
            self.range -= bound
            bit = 1
        model.update(bit)
        while self.range < 1 << 24:
            self.range <<= 8
            self.code = ((self.code << 8) | self._byte()) & 0xFFFFFFFF
        return bit

    def status(self) -> str:
        if self.overrun:
            return "short"
        return "ok" if self.pos == len(self.data) else "long"


class IntModel:
    """An adaptive model of integers: unary bit length, the top two mantissa bits in a bit
    tree per bit length, a probability per position of the lower mantissa bits (the same
    for every bit length), and a sign."""

    def __init__(self):
        self.unary = [Bit() for _ in range(KMAX - 1)]
        self.mant = {}  # (k, tree node) or ("low", position) -> Bit, made when first used
        self.sign = Bit()

    def _m(self, k, i):
        b = self.mant.get((k, i))
        if b is None:
            b = self.mant[(k, i)] = Bit()
        return b

    def put_uint(self, enc: Encoder, v: int) -> None:
        assert 0 <= v <= (1 << KMAX) - 2
        m = v + 1
        k = m.bit_length() - 1
        for j in range(KMAX - 1):
            if j == k:
                enc.bit(self.unary[j], 0)
                break
            enc.bit(self.unary[j], 1)
        node = 1
        for pos in range(k):
            bit = (m >> (k - 1 - pos)) & 1
            if pos < 2:
                enc.bit(self._m(k, node), bit)
                node = 2 * node + bit
            else:
                enc.bit(self._m("low", pos), bit)

    def get_uint(self, dec: Decoder) -> int:
        k = 0
        while k < KMAX - 1 and dec.bit(self.unary[k]):
            k += 1
        m = node = 1
        for pos in range(k):
            if pos < 2:
                bit = dec.bit(self._m(k, node))
                node = 2 * node + bit
            else:
                bit = dec.bit(self._m("low", pos))
            m = 2 * m + bit
        return m - 1

    def put(self, enc: Encoder, v: int) -> None:
        self.put_uint(enc, abs(v))
        if v:
            enc.bit(self.sign, 1 if v < 0 else 0)

    def get(self, dec: Decoder) -> int:
        a = self.get_uint(dec)
        return -a if a and dec.bit(self.sign) else a
