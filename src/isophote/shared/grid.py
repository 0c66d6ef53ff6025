"""What the fitter and the coder agree on: the file's coordinate grid and the handle frame.

Control points are stored on a 1/QUANT source-pixel grid and cap values on a 1/QUANT
grey-level grid (docs/format.md). The coder writes a segment's handles in the frame of its
chord (layout 3: an integer rotation by three lifting shears, exactly invertible), and the
fitter checks each segment's handles after the same rounding, so that writing the file moves
nothing it checked (encoder/_kernels/fit.py). Both therefore import these definitions; the
numba kernels come first, their plain-Python twins after (tests/shared/test_grid.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

QUANT = 64  # the file's grid: 1/64 source pixel for coordinates, 1/64 grey level for cap values


@njit(cache=True, nogil=True)
def rnd3(v):
    """v / 3 rounded to the nearest integer (never a tie for an integer v)."""
    return (v + 1) // 3


@njit(cache=True, nogil=True)
def rnd(x):
    return np.int64(np.floor(x + 0.5))


@njit(cache=True, nogil=True)
def chord_frame(dx, dy):
    """The chord frame of layout 3: (sign, p, q) of the integer rotation that turns the chord
    d = (dx, dy) onto the +x axis (see to_frame); (1, 0.0, 0.0), the identity, for d = 0."""
    sg = np.int64(1)
    if dx < 0 or (dx == 0 and dy < 0):  # rotate by pi first (exact): |angle| <= pi / 2 left
        dx = -dx
        dy = -dy
        sg = np.int64(-1)
    if dx == 0 and dy == 0:
        return sg, 0.0, 0.0
    fx = np.float64(dx)
    fy = np.float64(dy)
    length = np.sqrt(fx * fx + fy * fy)
    return sg, fy / (length + fx), -fy / length


@njit(cache=True, nogil=True)
def to_frame(sg, p, q, vx, vy):
    """(along, across): v rotated by the chord frame's angle with three lifting shears
    (x += [p y], y += [q x], x += [p y], [.] rounding to nearest; p = tan(theta/2), q = -sin
    theta), then times sg. Exactly invertible in integers (from_frame)."""
    x = vx + rnd(p * vy)
    y = vy + rnd(q * x)
    x = x + rnd(p * y)
    return sg * x, sg * y


@njit(cache=True, nogil=True)
def from_frame(sg, p, q, a, c):
    x = sg * a
    y = sg * c
    x = x - rnd(p * y)
    y = y - rnd(q * x)
    x = x - rnd(p * y)
    return x, y
