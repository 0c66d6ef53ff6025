"""Cubic Bezier arithmetic of the fit kernels (fit.py): a span's ends and control
differences, the Bernstein weights, the derivative and the straight segment's controls.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _ends(q, i, j):
    """The span's end points P0 = q[i, 2:4] and P3 = q[j, 2:4] (the joints)."""
    return q[i, 2], q[i, 3], q[j, 2], q[j, 3]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _span(q, i, j, c):
    """The span's ends and the differences of its four controls (P0, c, P3): the coefficients
    of the first derivative, B'(t) = 3 (s^2 d0 + 2 s t d1 + t^2 d2)."""
    p0x, p0y, p3x, p3y = _ends(q, i, j)
    return p0x, p0y, p3x, p3y, c[0] - p0x, c[1] - p0y, c[2] - c[0], c[3] - c[1], p3x - c[2], p3y - c[3]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _bernstein(s, t):
    """The cubic Bernstein weights at t (s = 1 - t)."""
    return s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _velocity(s, t, d0x, d0y, d1x, d1y, d2x, d2y):
    """B'(t) from the control differences (_span)."""
    return (3.0 * (s * s * d0x + 2.0 * s * t * d1x + t * t * d2x),
            3.0 * (s * s * d0y + 2.0 * s * t * d1y + t * t * d2y))


@njit(cache=True, nogil=True, error_model="numpy")
def _straight(q, i, j, c):
    """Inner controls of the straight segment q[i]-q[j], at its thirds."""
    c[0] = q[i, 2] + (q[j, 2] - q[i, 2]) / 3.0
    c[1] = q[i, 3] + (q[j, 3] - q[i, 3]) / 3.0
    c[2] = q[i, 2] + 2.0 * (q[j, 2] - q[i, 2]) / 3.0
    c[3] = q[i, 3] + 2.0 * (q[j, 3] - q[i, 3]) / 3.0
