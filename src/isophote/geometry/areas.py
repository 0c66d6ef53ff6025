"""Exact areas and moments of closed cubic chains and polylines (Green's theorem).

Coordinates are model.py's (y down). The signed area of a closed curve here is the shoelace
sum 1/2 ∮ (x dy - y dx) = ∮ x dy: positive for a curve that runs clockwise on screen. For a
cubic Bezier the integrals are polynomials in the control points, so the areas are exact up
to rounding.

Two formulas for the same integral are kept because their roundings differ and files depend
on both: :func:`signed_areas` (the cross-product form, the SVG writer's orientation flags)
and :func:`segment_moments` (relative to each segment's start, better conditioned far from
the origin: equalisation's level areas).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .chains import segment_starts


def _cross(a, b):
    return a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]


def cubic_signed_areas(p0, p1, p2, p3) -> np.ndarray:
    """(S,) 1/2 ∮ (x dy - y dx) along each cubic (the rows of the four (S, 2) control-point
    arrays); over a closed chain they add up to its signed area."""
    return (6 * _cross(p0, p1) + 3 * _cross(p0, p2) + _cross(p0, p3)
            + 3 * _cross(p1, p2) + 3 * _cross(p1, p3) + 6 * _cross(p2, p3)) / 20.0


def signed_areas(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(C,) exact signed areas of the closed cubic chains (shoelace sign convention)."""
    c = offsets.shape[0] - 1
    if c == 0:
        return np.zeros(0)
    first, nseg = segment_starts(offsets)
    seg = cubic_signed_areas(*(points[first + i] for i in range(4)))
    return np.bincount(np.repeat(np.arange(c), nseg), weights=seg, minlength=c)


def cubic_moments(p0, p1, p2, p3) -> np.ndarray:
    """(S,) ∮ x dy along each cubic, computed relative to its start point."""
    x0 = p0[:, 0]
    x1, y1 = (p1 - p0).T
    x2, y2 = (p2 - p0).T
    x3, y3 = (p3 - p0).T
    # ∫ x dy = ∫ (x0 + X) dY = x0 Y3 + ∫ X dY with X, Y relative to P0, and
    # ∫ X dY = X3 Y3 - ∫ Y dX = X3 Y3 / 2 - 3/20 (X1 (-Y2 - Y3) + X2 (Y1 - 2 Y3) + X3 (Y1 + 2 Y2))
    # (the bracket is 20/3 of the area between the curve and its chord: fontTools' AreaPen term).
    chord = 0.5 * x3 * y3
    bulge = -0.15 * (x1 * (-y2 - y3) + x2 * (y1 - 2.0 * y3) + x3 * (y1 + 2.0 * y2))
    return x0 * y3 + chord + bulge


def segment_moments(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """∮ x dy along every cubic segment of concatenated chains, exactly.

    Parameters
    ----------
    points : (P, 2) float64, offsets : (C + 1,) int64
        A channel's concatenated chains (model.py layout).

    Returns
    -------
    (S,) float64
        For segment P0, P1, P2, P3: the integral of x dy along it. Over a closed chain they
        add up to the enclosed area counted positively for a chain that runs clockwise on
        screen (y down), i.e. minus the area on the chain's left.
    """
    first, _ = segment_starts(offsets)
    if len(first) == 0:
        return np.zeros(0)
    return cubic_moments(*(points[first + i] for i in range(4)))


def polyline_areas(points, offsets: np.ndarray) -> np.ndarray:
    """(C,) signed shoelace areas of closed polylines (loop k: ``points[offsets[k]:offsets[k+1]]``,
    its last point joined back to its first; ``points`` (P, 2), or the pair of their x and
    y arrays).

    A kernel: one running sum of the cross products over all loops in order, each loop's
    area half the sum's growth over it (the bits of areas_ref.polyline_areas, NumPy's
    cumulative sum, on which the hierarchy's tie-breaks depend; no array a point: the loops
    of a whole channel come here)."""
    out = np.empty(offsets.shape[0] - 1)
    if isinstance(points, tuple):
        x, y = points
    else:
        p = np.ascontiguousarray(points, np.float64)
        x, y = p[:, 0], p[:, 1]
    _polyline_areas(x, y, np.ascontiguousarray(offsets, np.int64), out)
    return out


@njit(cache=True, nogil=True)
def _polyline_areas(x, y, offsets, out):
    polyline_areas_range(x, y, offsets, out, 0, out.shape[0], 0.0)


@njit(cache=True, nogil=True)
def polyline_areas_range(x, y, offsets, out, k0, k1, s):
    """_polyline_areas for loops k0 .. k1 - 1 alone, the running sum ``s`` carried in from
    the loops before and returned (runs of loops give the whole pass's bits)."""
    for k in range(k0, k1):
        a = offsets[k]
        b = offsets[k + 1]
        before = s if a > 0 else 0.0
        for i in range(a, b):
            j = i + 1 if i + 1 < b else a
            c = x[i] * y[j] - x[j] * y[i]
            s = c if i == 0 else s + c
        out[k] = 0.5 * (s - before)
    return s
