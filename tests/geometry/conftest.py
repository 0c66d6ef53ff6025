"""Chains with known geometry for the geometry tests."""

import numpy as np
import pytest

from isophote.geometry import line_segment
from isophote.model import Channel

K = 4.0 / 3.0 * (np.sqrt(2.0) - 1.0)  # the usual handle length of a 4-cubic circle


def circle(cx, cy, r, clockwise=True):
    """(13, 2) a circle of four cubics from (cx + r, cy), clockwise on screen (y down) unless
    told otherwise."""
    d = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0], [1.0, 0.0]])  # exact joints
    quarters = []
    for q in range(4):
        pa, pb = d[q], d[q + 1]
        ta, tb = pb, -pa  # the tangent at a joint points to the next joint's direction
        quarters.append([pa, pa + K * ta, pb - K * tb, pb])
    segs = np.array(quarters) * r + [cx, cy]
    if not clockwise:
        segs = segs[::-1, ::-1]
    return chain_of(segs)


def chain_of(segs):
    """(1 + 3n, 2) chain points of consecutive segments (n, 4, 2)."""
    return np.concatenate([segs[:, :3].reshape(-1, 2), segs[-1:, 3]])


def square(x, y, s, clockwise=True):
    """(13, 2) a square of straight cubics (handles at the thirds) from (x, y), clockwise on
    screen unless told otherwise."""
    c = np.array([[x, y], [x + s, y], [x + s, y + s], [x, y + s], [x, y]], float)
    if not clockwise:
        c = c[::-1]
    return chain_of(np.array([line_segment(a, b) for a, b in zip(c[:-1], c[1:])]))


def channel_of(chains, border_chains=()):
    """A channel holding the chains (their segments isolines) then the border chains."""
    allc = list(chains) + list(border_chains)
    sizes = [len(c) for c in allc]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    nseg = [(n - 1) // 3 for n in sizes]
    border = np.concatenate([np.full(n, i >= len(chains)) for i, n in enumerate(nseg)])
    c = len(allc)
    return Channel(name="Y", levels=np.array([100.0]), contour_level=np.zeros(c, np.int32),
                   offsets=offsets, points=np.concatenate(allc), border=border,
                   parent=np.full(c, -1, np.int32), cap_band=np.zeros(0, np.int32),
                   cap_contour=np.zeros(0, np.int32), cap_xy=np.zeros((0, 2)), cap_value=np.zeros(0))


@pytest.fixture
def two_contours():
    """A circle of radius 5 at (10, 10) and a 4-pixel border square at (20, 2)."""
    return channel_of([circle(10.0, 10.0, 5.0)], [square(20.0, 2.0, 4.0)])
