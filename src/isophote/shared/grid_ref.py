"""Plain-Python twins of shared/grid.py's kernels, under the same names (what the pure-Python
coder format/_coder/entropy_ref.py and the fitter's twin use)."""

from __future__ import annotations

import math

from .grid import QUANT  # noqa: F401  (one definition of the grid)


def rnd3(v: int) -> int:
    return (v + 1) // 3


def rnd(x: float) -> int:
    return math.floor(x + 0.5)


def chord_frame(dx: int, dy: int):
    """Version 3's rotation onto the chord d: (sign, tan(theta / 2), -sin(theta)) of the
    angle theta of d, after d is turned by pi (sign -1) when it points left or straight up."""
    sign = 1
    if dx < 0 or (dx == 0 and dy < 0):
        dx, dy, sign = -dx, -dy, -1
    if dx == 0 and dy == 0:
        return sign, 0.0, 0.0
    length = math.sqrt(float(dx) * float(dx) + float(dy) * float(dy))
    return sign, float(dy) / (length + float(dx)), -float(dy) / length


def to_frame(frame, x: int, y: int):
    """(along, across): three lifting shears, exactly invertible in integers."""
    sign, p, q = frame
    x += rnd(p * y)
    y += rnd(q * x)
    x += rnd(p * y)
    return sign * x, sign * y


def from_frame(frame, a: int, c: int):
    sign, p, q = frame
    x, y = sign * a, sign * c
    x -= rnd(p * y)
    y -= rnd(q * x)
    x -= rnd(p * y)
    return x, y
