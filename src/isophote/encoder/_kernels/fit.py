"""Kernels of the Bezier chain fitter (paper §3.3); the plain NumPy twin is fit_ref.py.

Used by :mod:`isophote.encoder.fit`, which documents and validates; nothing here checks its
arguments. The numba kernels and fit_ref.py implement the same algorithm with
the same floating-point expressions, so they agree to rounding (tests compare them).

The algorithm, for one polyline ``q`` (N points) with per-point tolerance ``tol``:

1. Greedy longest fit. From the current start point i, the span end j is first tried g
   edges on, g the previous segment's edges (FIRST_GUESS for a polyline's first segment):
   neighbouring segments are alike. While the span fits, j gallops on by g/2, g, 2g, ...
   edges (at least 1); then a binary search between the last fitting and the first failing
   end keeps the longest end found to fit. A span of one edge always fits (the straight
   segment through its two points). Against growing from i+2 by doubling, this tries
   fewer spans for slightly more segments (measured:
   benchmarks/results/design_choices.md#fit-first-guess).
2. A span fits when a cubic with the span's end points passes two tests after one of up
   to ``ITERATIONS`` fits of its inner controls. The first fit is Schneider's: least squares
   (weights 1/tol^2) over chord-length parameters. Each later one is a Gauss-Newton step of
   tangent distance minimisation (the residuals' components along the curve normals at the
   points' foot parameters, plus TANGENTIAL times the tangential ones): it converges in a
   few steps where Schneider's alternation crawls. After every fit a Newton step moves each
   point's parameter towards its foot on the curve. The tests: every point k lies within
   tol[k] of the curve point B(u[k]) (an upper bound of its distance to the curve), and
   the whole curve lies within max(tol[e], tol[e+1]) of some edge e of the span (so it
   cannot bulge between points): on each interval u[k]..u[k+1] either the curve's
   excursion from its chord (curv du^2 / 8) plus the larger point error of the interval's
   ends is within edge k's tolerance (a bound, no sampling: it settles most intervals, and
   fitting is faster than sampling every interval; measured:
   benchmarks/results/design_choices.md#fit-chord-bound), or every
   two neighbouring curve samples (at u[k], between, at u[k+1]) lie within one same edge's
   tolerance less a margin that bounds the curve's excursion from their chord. Between
   points the curve must also run the way of its edge (no fish-tail loops inside the
   ribbon).
3. G1 snapping: at each joint whose incoming and outgoing handles differ in direction by
   less than the threshold, both handles are rotated onto their length-weighted bisector
   (P - Cb + Ca - P) keeping their lengths; the change is kept only if both adjacent
   segments still pass both tests.

4. Coarse handles (``coarsen`` > 0, the encoder's "quantisation inside the ribbon"): each
   segment of more than one edge gets its handles moved onto the coarsest grid of the
   file's handle coding (format/isoph.py: the residual against the straight segment's
   thirds, in the chord's frame, a multiple of 2**sh / QUANT px, sh = coarsen .. 1, the
   anchors rounded to 1/QUANT px) on which it still passes both tests (after one Newton
   reparameterisation step: the handles move little), down to sh = 0, the 1/QUANT grid
   itself (segments of one edge try only that one); where none fits, the other roundings
   of the four handle coordinates to that grid are tried in turn, and a segment none of
   them fits keeps its handles. The file then codes those residuals divided by 2**sh.
   With ``coarsen`` > 0 the joints are on the 1/QUANT grid too (_joint_at), so the file's
   rounding moves nothing the tests have passed.

5. Joints on the anchor grid (``anchor_grid`` > 0; the encoder's 2x sample grid, 0.5 px):
   a polyline point that becomes a joint is moved onto that grid in each coordinate that
   lies within the point's ``reach`` of it (_joint_at; the ends of open polylines, shared
   with the runs beside them, stay); with ``coarsen`` > 0 every joint is then rounded to
   the 1/QUANT grid. Every fit and test above uses the moved joints, so the guarantees
   hold for them. The file codes a coordinate on the sample grid
   5 bits shorter (format/isoph.py, anchor flags), and crossings near a sample are common
   where the ribbon is wide.

Closed polylines are rotated to start at their sharpest turn and closed by repeating that
point, then fitted as open ones; their closing joint is snapped last.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ...shared.grid import QUANT as _GRID, chord_frame as _frame, from_frame as _from_frame, rnd as _round, rnd3 as _rnd3, to_frame as _to_frame  # noqa: E501
from .bezier import _bernstein, _ends, _span, _straight, _velocity

# Edges tried first for a polyline's first segment (step 1).
FIRST_GUESS = 4
# Fits per span (one least-squares fit, then Gauss-Newton steps), and Newton
# reparameterisation steps when a snapped segment is checked.
ITERATIONS = 3
NEWTON_STEPS = 2
# Newton reparameterisation steps when a segment's coarse handles are checked: the handles
# move little, so the fitted parameters are close already.
COARSEN_STEPS = 1
# A span whose worst point is still farther than GIVE_UP[it] tolerances from its curve after
# fit `it` is rejected at once: later steps rarely rescue fits that bad (each step cuts the
# error several times over), and rejecting early keeps the search cheap.
GIVE_UP = (16.0, 4.0)
# Weight of the tangential residual component in the Gauss-Newton steps (1 would be
# Schneider's point distance, 0 pure tangent distance, which can be singular).
TANGENTIAL = 0.01
# Most curve samples strictly between two consecutive points in the bulge test.
MAX_SAMPLES = 32
# Relative Tikhonov term, pulling the inner controls towards the straight segment's thirds
# in the least-squares fit and towards the current controls in the Gauss-Newton steps: it
# makes spans with few inner points well posed and is negligible otherwise.
RIDGE = 1e-6
# The file's point grid (1/QUANT px, shared/grid.py), on which _coarsen rounds the anchors
# and builds the handles' coarser grids; a float, as the kernels compute in floats.
QUANT = float(_GRID)


# ---------------------------------------------------------------------------------------
# numba kernels
# ---------------------------------------------------------------------------------------


@njit(cache=True, nogil=True, error_model="numpy")
def _lsq(q, w, i, j, u, c):
    """Least-squares inner controls of the span i..j for parameters u; writes c[0:4]."""
    p0x, p0y, p3x, p3y = _ends(q, i, j)
    a11 = a12 = a22 = 0.0  # the normal equations (symmetric) and the right-hand sides
    r1x = r1y = r2x = r2y = 0.0
    for k in range(i + 1, j):
        t = u[k]
        s = 1.0 - t
        b0, b1, b2, b3 = _bernstein(s, t)
        wk = w[k]
        rx = q[k, 0] - b0 * p0x - b3 * p3x
        ry = q[k, 1] - b0 * p0y - b3 * p3y
        a11 += wk * b1 * b1
        a12 += wk * b1 * b2
        a22 += wk * b2 * b2
        r1x += wk * b1 * rx
        r1y += wk * b1 * ry
        r2x += wk * b2 * rx
        r2y += wk * b2 * ry
    lam = RIDGE * (a11 + a22)
    if not lam > 0.0:
        lam = 1.0
    a11 += lam
    a22 += lam
    r1x += lam * (p0x + (p3x - p0x) / 3.0)
    r1y += lam * (p0y + (p3y - p0y) / 3.0)
    r2x += lam * (p0x + 2.0 * (p3x - p0x) / 3.0)
    r2y += lam * (p0y + 2.0 * (p3y - p0y) / 3.0)
    det = a11 * a22 - a12 * a12
    c[0] = (a22 * r1x - a12 * r2x) / det
    c[1] = (a22 * r1y - a12 * r2y) / det
    c[2] = (a11 * r2x - a12 * r1x) / det
    c[3] = (a11 * r2y - a12 * r1y) / det


@njit(cache=True, nogil=True, error_model="numpy")
def _tdm(q, w, i, j, u, c, a):
    """One Gauss-Newton step of tangent distance minimisation for the inner controls c
    (updated in place), linearised at the foot parameters u on the current curve. a is a
    (4, 5) scratch array for the normal equations."""
    p0x, p0y, p3x, p3y, d0x, d0y, d1x, d1y, d2x, d2y = _span(q, i, j, c)
    # A = sum w (b b^T kron M), M = TANGENTIAL I + (1 - TANGENTIAL) n n^T; unknowns
    # (c1x, c1y, c2x, c2y)
    s11xx = s11xy = s11yy = 0.0
    s12xx = s12xy = s12yy = 0.0
    s22xx = s22xy = s22yy = 0.0
    r1x = r1y = r2x = r2y = 0.0
    for k in range(i + 1, j):
        t = u[k]
        s = 1.0 - t
        gx, gy = _velocity(s, t, d0x, d0y, d1x, d1y, d2x, d2y)
        gl = gx * gx + gy * gy
        if gl > 0.0:
            mxx = TANGENTIAL + (1.0 - TANGENTIAL) * gy * gy / gl
            myy = TANGENTIAL + (1.0 - TANGENTIAL) * gx * gx / gl
            mxy = -(1.0 - TANGENTIAL) * gx * gy / gl
        else:
            mxx = 1.0
            myy = 1.0
            mxy = 0.0
        b0, b1, b2, b3 = _bernstein(s, t)
        wk = w[k]
        rx = q[k, 0] - b0 * p0x - b3 * p3x
        ry = q[k, 1] - b0 * p0y - b3 * p3y
        f = wk * b1 * b1
        s11xx += f * mxx
        s11xy += f * mxy
        s11yy += f * myy
        f = wk * b1 * b2
        s12xx += f * mxx
        s12xy += f * mxy
        s12yy += f * myy
        f = wk * b2 * b2
        s22xx += f * mxx
        s22xy += f * mxy
        s22yy += f * myy
        mrx = wk * (mxx * rx + mxy * ry)
        mry = wk * (mxy * rx + myy * ry)
        r1x += b1 * mrx
        r1y += b1 * mry
        r2x += b2 * mrx
        r2y += b2 * mry
    a[0, 0] = s11xx
    a[0, 1] = s11xy
    a[0, 2] = s12xx
    a[0, 3] = s12xy
    a[1, 1] = s11yy
    a[1, 2] = s12xy
    a[1, 3] = s12yy
    a[2, 2] = s22xx
    a[2, 3] = s22xy
    a[3, 3] = s22yy
    for r in range(4):
        for col in range(r):
            a[r, col] = a[col, r]
    a[0, 4] = r1x
    a[1, 4] = r1y
    a[2, 4] = r2x
    a[3, 4] = r2y
    # Levenberg-Marquardt style ridge towards the current controls
    lam = RIDGE * (a[0, 0] + a[1, 1] + a[2, 2] + a[3, 3])
    if not lam > 0.0:
        lam = 1.0
    for r in range(4):
        a[r, r] += lam
        a[r, 4] += lam * c[r]
    _solve4(a, c)


@njit(cache=True, nogil=True, error_model="numpy")
def _solve4(a, x):
    """Solve the symmetric positive definite system a[:, :4] x = a[:, 4] (a is destroyed)
    by Gaussian elimination without pivoting."""
    for r in range(4):
        for k in range(r + 1, 4):
            f = a[k, r] / a[r, r]
            for col in range(r, 5):
                a[k, col] -= f * a[r, col]
    for r in range(3, -1, -1):
        v = a[r, 4]
        for col in range(r + 1, 4):
            v -= a[r, col] * x[col]
        x[r] = v / a[r, r]


@njit(cache=True, nogil=True, error_model="numpy")
def _newton(q, w, ed, i, j, u, c, limit):
    """One Newton step of every inner parameter towards its point's foot on the curve,
    clamped to [0, 1] and to the previous parameter (parameters never decrease). Returns
    the largest (|B(u[k]) - q[k]| / tol[k])^2 at the new parameters, stopping early (with
    the rest of u untouched) once it exceeds limit; notes each |B(u[k]) - q[k]|^2 in
    ed[k, 4] for _bulge_ok."""
    # first and second derivative coefficients
    p0x, p0y, p3x, p3y, d0x, d0y, d1x, d1y, d2x, d2y = _span(q, i, j, c)
    e0x = d1x - d0x
    e0y = d1y - d0y
    e1x = d2x - d1x
    e1y = d2y - d1y
    worst = 0.0
    for k in range(i + 1, j):
        t = u[k]
        s = 1.0 - t
        b0, b1, b2, b3 = _bernstein(s, t)
        dx = b0 * p0x + b1 * c[0] + b2 * c[2] + b3 * p3x - q[k, 0]
        dy = b0 * p0y + b1 * c[1] + b2 * c[3] + b3 * p3y - q[k, 1]
        gx, gy = _velocity(s, t, d0x, d0y, d1x, d1y, d2x, d2y)
        hx = 6.0 * (s * e0x + t * e1x)
        hy = 6.0 * (s * e0y + t * e1y)
        num = dx * gx + dy * gy
        den = gx * gx + gy * gy + dx * hx + dy * hy
        if den > 0.0:
            t = t - num / den
            if t < 0.0:
                t = 0.0
            elif t > 1.0:
                t = 1.0
        if t < u[k - 1]:
            t = u[k - 1]
        u[k] = t
        s = 1.0 - t
        b0, b1, b2, b3 = _bernstein(s, t)
        dx = b0 * p0x + b1 * c[0] + b2 * c[2] + b3 * p3x - q[k, 0]
        dy = b0 * p0y + b1 * c[1] + b2 * c[3] + b3 * p3y - q[k, 1]
        d2 = dx * dx + dy * dy
        ed[k, 4] = d2
        e = d2 * w[k]
        if e > worst:
            worst = e
            if e > limit:
                break
    return worst


@njit(cache=True, nogil=True, error_model="numpy")
def _within(q, ed, e, x, y, margin):
    """Is (x, y) within max(tol[e], tol[e+1]) - margin of the polyline edge e? (ed: see
    _edges)"""
    lim = ed[e, 3] - margin
    if lim < 0.0:
        return False
    ax = q[e, 0]
    ay = q[e, 1]
    h = ((x - ax) * ed[e, 0] + (y - ay) * ed[e, 1]) * ed[e, 2]
    if h < 0.0:
        h = 0.0
    elif h > 1.0:
        h = 1.0
    dx = ax + h * ed[e, 0] - x
    dy = ay + h * ed[e, 1] - y
    return dx * dx + dy * dy <= lim * lim


@njit(cache=True, nogil=True, error_model="numpy")
def _edges(q, tol, n, ed):
    """Per polyline edge e of q[:n]: its vector, the inverse of its squared length (0 for
    a repeated point) and its tolerance max(tol[e], tol[e+1]), in ed[e, 0:4] (ed[:, 4]:
    _newton's squared point errors)."""
    for e in range(n - 1):
        ex = q[e + 1, 0] - q[e, 0]
        ey = q[e + 1, 1] - q[e, 1]
        ll = ex * ex + ey * ey
        ed[e, 0] = ex
        ed[e, 1] = ey
        ed[e, 2] = 1.0 / ll if ll > 0.0 else 0.0
        ed[e, 3] = max(tol[e], tol[e + 1])


@njit(cache=True, nogil=True, error_model="numpy")
def _samples(ed, u, curv, k):
    """Samples strictly inside the interval u[k]..u[k+1], and their margin: enough that
    the curve's excursion from the chords between them, curv * delta^2 / 8, stays below
    an eighth of the interval's tolerance."""
    tl = ed[k, 3]
    du = u[k + 1] - u[k]
    need = du * math.sqrt(curv / tl)
    ns = 1
    if need >= MAX_SAMPLES:
        ns = MAX_SAMPLES
    elif need > 1.0:
        ns = int(need)
    delta = du / (ns + 1)
    return ns, curv * (delta * delta) / 8.0


@njit(cache=True, nogil=True, error_model="numpy")
def _bulge_ok(q, ed, i, j, u, c):
    """True when the whole curve stays inside the ribbon of the span's edges and runs
    forwards along them (ed[:, 4]: the squared point errors at u, from _newton).

    Interval by interval (u[k]..u[k+1], polyline edge k): the curve must run the edge's
    way at the interval's inner samples. Then, first, a bound: the curve lies within
    curv * du^2 / 8 of the chord between its ends (|B''| <= curv), and that chord within
    the larger of the two point errors of edge k, so the interval is inside when their sum
    is at most the edge's tolerance. Where it is not, every two neighbouring samples
    (u[k], the inner ones, u[k+1]) must lie within one same edge's tolerance less a margin
    that bounds the curve's excursion from their chord (the distance to an edge is convex
    along the chord). Edges are searched outwards from the interval's own edge, after the
    edge that served the previous pair.
    """
    p0x, p0y, p3x, p3y = _ends(q, i, j)
    # |B''(t)| <= curv, so between samples delta apart in t the curve is within
    # curv * delta^2 / 8 of their chord
    ax = p0x - 2.0 * c[0] + c[2]
    ay = p0y - 2.0 * c[1] + c[3]
    bx = c[0] - 2.0 * c[2] + p3x
    by = c[1] - 2.0 * c[3] + p3y
    curv = 6.0 * math.sqrt(max(ax * ax + ay * ay, bx * bx + by * by))
    for k in range(i, j):
        du = u[k + 1] - u[k]
        ns, margin = _samples(ed, u, curv, k)
        # no backtracking: between polyline points the curve runs the edge's way, so a
        # fit cannot tie a loop (a fish-tail) inside the ribbon
        for m in range(1, ns + 1):
            t = u[k] + du * m / (ns + 1)
            s = 1.0 - t
            dx = s * s * (c[0] - p0x) + 2.0 * s * t * (c[2] - c[0]) + t * t * (p3x - c[2])
            dy = s * s * (c[1] - p0y) + 2.0 * s * t * (c[3] - c[1]) + t * t * (p3y - c[3])
            if dx * ed[k, 0] + dy * ed[k, 1] < 0.0:
                return False
        # the chord bound (the span's ends lie on the curve, at their joints: a joint's
        # point error is its move onto the anchor grid)
        if k > i:
            e0 = ed[k, 4]
        else:
            e0 = (q[k, 2] - q[k, 0]) ** 2 + (q[k, 3] - q[k, 1]) ** 2
        if k + 1 < j:
            e1 = ed[k + 1, 4]
        else:
            e1 = (q[j, 2] - q[j, 0]) ** 2 + (q[j, 3] - q[j, 1]) ** 2
        slack = ed[k, 3] - curv * du * du / 8.0
        if slack >= 0.0 and max(e0, e1) <= slack * slack:
            continue
        cur = -1
        x0 = 0.0
        y0 = 0.0
        for m in range(0, ns + 2):
            t = u[k] + du * m / (ns + 1) if 0 < m <= ns else (u[k] if m == 0 else u[k + 1])
            s = 1.0 - t
            b0, b1, b2, b3 = _bernstein(s, t)
            x = b0 * p0x + b1 * c[0] + b2 * c[2] + b3 * p3x
            y = b0 * p0y + b1 * c[1] + b2 * c[3] + b3 * p3y
            if m > 0 and (cur < 0 or not _within(q, ed, cur, x, y, margin)):
                cur = -1
                for r in range(j - i):
                    for e in (k - r, k + r):
                        if e < i or e >= j or (r == 0 and e != k - r):
                            continue
                        if _within(q, ed, e, x, y, margin) and _within(q, ed, e, x0, y0, margin):
                            cur = e
                            break
                    if cur >= 0 or (k - r < i and k + r >= j - 1):
                        break
                if cur < 0:
                    return False
            x0 = x
            y0 = y
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _fit_span(q, ed, w, cum, i, j, u, c, work):
    """Fit the span i..j; True when it passes (then c holds the controls, u[i..j] the
    parameters). work is a (4, 5) scratch array."""
    if j == i + 1:
        _straight(q, i, j, c)
        u[i] = 0.0
        u[j] = 1.0
        return True
    length = cum[j] - cum[i]
    for k in range(i, j):
        if length > 0.0:
            u[k] = (cum[k] - cum[i]) / length
        else:
            u[k] = (k - i) / (j - i)
    u[j] = 1.0
    for it in range(ITERATIONS):
        if it == 0:
            _lsq(q, w, i, j, u, c)
        else:
            _tdm(q, w, i, j, u, c, work)
        limit = GIVE_UP[it] * GIVE_UP[it] if it < len(GIVE_UP) else 1.0
        worst = _newton(q, w, ed, i, j, u, c, limit)
        if worst <= 1.0 and _bulge_ok(q, ed, i, j, u, c):
            return True
        if worst > limit:
            return False
    return False


@njit(cache=True, nogil=True, error_model="numpy")
def _check_fixed(q, ed, w, i, j, u, c, steps=NEWTON_STEPS):
    """Does the cubic with controls c still fit the span i..j? Reparameterises u first
    (``steps`` Newton steps)."""
    # a joint's point is shared by two segments: its parameter is 0 in one, 1 in the other
    u[i] = 0.0
    u[j] = 1.0
    worst = 0.0
    for it in range(steps):
        worst = _newton(q, w, ed, i, j, u, c, 1.0 if it == steps - 1 else np.inf)
    if worst > 1.0:
        return False
    return _bulge_ok(q, ed, i, j, u, c)


@njit(cache=True, nogil=True, error_model="numpy")
def _snap_joint(q, ed, w, ends, ctrl, u, ut, a, b, cos_snap, ca, cb):
    """Snap the joint between segment a (incoming) and b (outgoing) if it qualifies and
    both segments still fit. ut, ca, cb are scratch."""
    px = q[ends[a + 1], 2]
    py = q[ends[a + 1], 3]
    ix = px - ctrl[a, 2]
    iy = py - ctrl[a, 3]
    ox = ctrl[b, 0] - px
    oy = ctrl[b, 1] - py
    li = math.sqrt(ix * ix + iy * iy)
    lo = math.sqrt(ox * ox + oy * oy)
    if not (li > 0.0 and lo > 0.0):
        return
    dot = ix * ox + iy * oy
    cross = ix * oy - iy * ox
    if cross == 0.0 or dot <= cos_snap * li * lo:
        return
    bx = ix + ox
    by = iy + oy
    bl = math.sqrt(bx * bx + by * by)
    bx /= bl
    by /= bl
    for k in range(4):
        ca[k] = ctrl[a, k]
        cb[k] = ctrl[b, k]
    ca[2] = px - li * bx
    ca[3] = py - li * by
    if a == b:
        cb = ca
    cb[0] = px + lo * bx
    cb[1] = py + lo * by
    nseg = 1 if a == b else 2
    for r in range(nseg):
        g = a if r == 0 else b
        for k in range(ends[g], ends[g + 1] + 1):
            ut[k] = u[k]
        if not _check_fixed(q, ed, w, ends[g], ends[g + 1], ut, ca if r == 0 else cb):
            return
    for r in range(nseg):
        g = a if r == 0 else b
        for k in range(ends[g], ends[g + 1] + 1):
            u[k] = ut[k]
    for k in range(4):
        ctrl[a, k] = ca[k]
        ctrl[b, k] = cb[k]


@njit(cache=True, nogil=True, error_model="numpy")
def _handle_frame(q, i, j, c):
    """What the file's handle coding (format/isoph.py) makes of the span i..j's handles c:
    the anchors rounded to 1/QUANT px (ax, ay, nx, ny), the thirds of their chord (tx, ty),
    the chord frame (sg, p, qq) and the handles' residuals in it (ha, hc, ra, rc), in
    1/QUANT px units."""
    ax = _round(q[i, 2] * QUANT)
    ay = _round(q[i, 3] * QUANT)
    nx = _round(q[j, 2] * QUANT)
    ny = _round(q[j, 3] * QUANT)
    dx = nx - ax
    dy = ny - ay
    sg, p, qq = _frame(dx, dy)
    tx = _rnd3(dx)
    ty = _rnd3(dy)
    ha, hc = _to_frame(sg, p, qq, _round(c[0] * QUANT) - ax - tx, _round(c[1] * QUANT) - ay - ty)
    ra, rc = _to_frame(sg, p, qq, _round(c[2] * QUANT) - nx + tx, _round(c[3] * QUANT) - ny + ty)
    return ax, ay, nx, ny, tx, ty, sg, p, qq, ha, hc, ra, rc


@njit(cache=True, nogil=True, error_model="numpy")
def _on_grid(v, shift):
    """v rounded to the nearest multiple of 2**shift (halves up)."""
    return ((v + (np.int64(1) << (shift - 1))) >> shift) << shift


@njit(cache=True, nogil=True, error_model="numpy")
def _take_if_fits(q, ed, w, i, j, u, ut, ca, ctrl, g):
    """Segment g (the span i..j) takes the handles ca if it still fits with them
    (_check_fixed from the parameters u, in ut); True if it did."""
    for k in range(i, j + 1):
        ut[k] = u[k]
    if not _check_fixed(q, ed, w, i, j, ut, ca, COARSEN_STEPS):
        return False
    for k in range(4):
        ctrl[g, k] = ca[k]
    return True


@njit(cache=True, nogil=True, error_model="numpy")
def _coarsen(q, ed, w, ends, ctrl, m, u, ut, max_shift, ca):
    """Each segment's handles on the coarsest grid (shift max_shift down to 0) on which the
    segment still fits its span (_check_fixed); segments of one edge try shift 0 alone. The
    handles' residuals are rounded to multiples of 2**shift in the chord's frame (see
    _handle_frame; shift 0 is the 1/QUANT px grid itself, where that frame is exact: the
    handles rounded to it); a grid that rounds them as the coarser one before did is not
    checked again. Where even the 1/QUANT grid fails, the other roundings of the four
    coordinates (up instead of to the nearest, down instead) are tried in turn; a segment
    none of them fits keeps its handles."""
    for g in range(m):
        i = ends[g]
        j = ends[g + 1]
        top = max_shift if j - i >= 2 else 0
        ax, ay, nx, ny, tx, ty, sg, p, qq, ha, hc, ra, rc = _handle_frame(q, i, j, ctrl[g])
        p1 = p2 = p3 = p4 = np.int64(0)  # the previous grid's terms
        placed = False
        for shift in range(top, -1, -1):
            if shift > 0:
                a1 = _on_grid(ha, shift)
                c1 = _on_grid(hc, shift)
                a2 = _on_grid(ra, shift)
                c2 = _on_grid(rc, shift)
            else:
                a1, c1, a2, c2 = ha, hc, ra, rc
            if shift < top and a1 == p1 and c1 == p2 and a2 == p3 and c2 == p4:
                continue
            p1, p2, p3, p4 = a1, c1, a2, c2
            hx, hy = _from_frame(sg, p, qq, a1, c1)
            rx, ry = _from_frame(sg, p, qq, a2, c2)
            ca[0] = (ax + tx + hx) / QUANT
            ca[1] = (ay + ty + hy) / QUANT
            ca[2] = (nx - tx + rx) / QUANT
            ca[3] = (ny - ty + ry) / QUANT
            placed = _take_if_fits(q, ed, w, i, j, u, ut, ca, ctrl, g)
            if placed:
                break
        for flip in range(1, 16):
            if placed:
                break
            for k in range(4):
                v = ctrl[g, k] * QUANT
                r = math.floor(v + 0.5)
                if (flip >> k) & 1:
                    r = r - 1.0 if r > v else r + 1.0
                ca[k] = r / QUANT
            placed = _take_if_fits(q, ed, w, i, j, u, ut, ca, ctrl, g)


@njit(cache=True, nogil=True, error_model="numpy")
def _fit_open(
    q, ed, w, n, closed, cos_snap, cum, u, ut, c, cbest, work, ends, ctrl, ca, cb, coarsen
):
    """Fit q[:n] (already closed by repetition when `closed`); fills ends[0:m+1] and
    ctrl[0:m]; returns m."""
    cum[0] = 0.0
    for k in range(1, n):
        dx = q[k, 0] - q[k - 1, 0]
        dy = q[k, 1] - q[k - 1, 1]
        cum[k] = cum[k - 1] + math.sqrt(dx * dx + dy * dy)
    last = n - 1
    ends[0] = 0
    i = ends[0]  # read back: a literal 0 here would make numba compile callees twice
    m = 0
    guess = FIRST_GUESS
    while i < last:
        # galloping search (hi < 0) then binary search for the longest span that fits;
        # one call site of _fit_span keeps the compiled code small
        lo = i + 1
        _straight(q, i, lo, cbest)
        hi = -1
        step = 0
        while True:
            if hi < 0:
                if lo >= last:
                    break
                if step == 0:
                    j = min(i + guess, last)
                    step = max(1, guess // 2)
                else:
                    j = min(lo + step, last)
                    step *= 2
            else:
                if hi - lo <= 1:
                    break
                j = (lo + hi) // 2
            if _fit_span(q, ed, w, cum, i, j, u, c, work):
                lo = j
                for k in range(4):
                    cbest[k] = c[k]
                for k in range(i, j + 1):
                    ut[k] = u[k]
            else:
                hi = j
        # the accepted span's parameters live in ut when it was not the trivial one
        if lo > i + 1:
            for k in range(i, lo + 1):
                u[k] = ut[k]
        else:
            u[i] = 0.0
            u[lo] = 1.0
        for k in range(4):
            ctrl[m, k] = cbest[k]
        m += 1
        ends[m] = lo
        guess = max(2, lo - i)
        i = lo
    if cos_snap < 1.0:
        # interior joints in order, then the closing joint of a closed chain
        for a in range(m - 1 + (1 if closed else 0)):
            _snap_joint(q, ed, w, ends, ctrl, u, ut, a, (a + 1) % m, cos_snap, ca, cb)
    if coarsen > 0:
        _coarsen(q, ed, w, ends, ctrl, m, u, ut, coarsen, ca)
    return m


@njit(cache=True, nogil=True, error_model="numpy")
def _start_index(pts, o, n):
    """Index (from o) of the sharpest turn of the closed polyline pts[o:o+n] (the first
    one on ties)."""
    best = -1.0
    ibest = 0
    for k in range(n):
        a = o + (k - 1 if k > 0 else n - 1)
        b = o + k
        c = o + (k + 1 if k + 1 < n else 0)
        x1 = pts[b, 0] - pts[a, 0]
        y1 = pts[b, 1] - pts[a, 1]
        x2 = pts[c, 0] - pts[b, 0]
        y2 = pts[c, 1] - pts[b, 1]
        ang = math.atan2(abs(x1 * y2 - y1 * x2), x1 * x2 + y1 * y2)
        if ang > best:
            best = ang
            ibest = k
    return ibest


@njit(cache=True, nogil=True, error_model="numpy")
def _joint_at(q, reach, k, grid, on_file_grid):
    """Where point k goes when it is a joint, in q[k, 2:4]: each coordinate within reach[k]
    of a multiple of grid (> 0) moves onto it, x first, y if the move in both stays within
    that reach; the point stays where it is when grid is 0. With on_file_grid the result
    is then rounded to the 1/QUANT px grid (halves up: at most 1/(2 QUANT) px more a
    coordinate; none for a coordinate on an anchor grid of multiples of 1/QUANT)."""
    x = q[k, 0]
    y = q[k, 1]
    q[k, 2] = x
    q[k, 3] = y
    if grid > 0.0:
        lim = reach[k]
        rx = math.floor(x / grid + 0.5) * grid
        dx = rx - x
        if abs(dx) <= lim:
            q[k, 2] = rx
        else:
            dx = 0.0
        ry = math.floor(y / grid + 0.5) * grid
        dy = ry - y
        if dx * dx + dy * dy <= lim * lim:
            q[k, 3] = ry
    if on_file_grid:
        q[k, 2] = math.floor(q[k, 2] * QUANT + 0.5) / QUANT
        q[k, 3] = math.floor(q[k, 3] * QUANT + 0.5) / QUANT


@njit(cache=True, nogil=True, error_model="numpy")
def fit_many_kernel(points, tol, offsets, closed, cos_snap, coarsen, anchor_grid, reach):
    """Fit every polyline; returns (chains (P, 2), chain_offsets (K+1,) int64). coarsen > 0
    puts the handles on the file's coarse grids, shifts up to coarsen (_coarsen);
    anchor_grid > 0 moves each joint onto that grid within its point's reach (_joint_at,
    step 5)."""
    npoly = offsets.shape[0] - 1
    nmax = 0
    for p in range(npoly):
        nmax = max(nmax, offsets[p + 1] - offsets[p])
    size = nmax + 1
    q = np.empty((size, 4))  # the points, and where each goes as a joint (_joint_at)
    tq = np.empty(size)
    rq = np.empty(size)
    wq = np.empty(size)
    ed = np.empty((size, 5))
    cum = np.empty(size)
    u = np.empty(size)
    ut = np.empty(size)
    ends = np.empty(size, np.int64)
    ctrl = np.empty((size, 4))
    c = np.empty(4)
    cbest = np.empty(4)
    ca = np.empty(4)
    cb = np.empty(4)
    work = np.empty((4, 5))
    cap = max(16, points.shape[0])
    out = np.empty((cap, 2))
    chain_offsets = np.empty(npoly + 1, np.int64)
    chain_offsets[0] = 0
    used = 0
    for p in range(npoly):
        o = offsets[p]
        n = offsets[p + 1] - o
        if closed[p]:
            s = _start_index(points, o, n)
            for k in range(n):
                r = s + k
                if r >= n:
                    r -= n
                q[k, 0] = points[o + r, 0]
                q[k, 1] = points[o + r, 1]
                tq[k] = tol[o + r]
                rq[k] = reach[o + r]
            q[n, 0] = q[0, 0]
            q[n, 1] = q[0, 1]
            tq[n] = tq[0]
            rq[n] = rq[0]
            nn = n + 1
        else:
            for k in range(n):
                q[k, 0] = points[o + k, 0]
                q[k, 1] = points[o + k, 1]
                tq[k] = tol[o + k]
                rq[k] = reach[o + k]
            nn = n
        for k in range(nn):
            wq[k] = 1.0 / (tq[k] * tq[k])
            _joint_at(q, rq, k, anchor_grid if closed[p] or 0 < k < nn - 1 else 0.0, coarsen > 0)
        _edges(q, tq, nn, ed)
        m = _fit_open(
            q, ed, wq, nn, closed[p], cos_snap, cum, u, ut, c, cbest, work, ends, ctrl, ca, cb, coarsen
        )
        need = used + 1 + 3 * m
        if need > cap:
            while cap < need:
                cap *= 2
            grown = np.empty((cap, 2))
            for r in range(used):
                grown[r, 0] = out[r, 0]
                grown[r, 1] = out[r, 1]
            out = grown
        out[used, 0] = q[0, 2]
        out[used, 1] = q[0, 3]
        for g in range(m):
            r = used + 1 + 3 * g
            out[r, 0] = ctrl[g, 0]
            out[r, 1] = ctrl[g, 1]
            out[r + 1, 0] = ctrl[g, 2]
            out[r + 1, 1] = ctrl[g, 3]
            out[r + 2, 0] = q[ends[g + 1], 2]
            out[r + 2, 1] = q[ends[g + 1], 3]
        used = need
        chain_offsets[p + 1] = used
    chains = np.empty((used, 2))
    for r in range(used):
        chains[r, 0] = out[r, 0]
        chains[r, 1] = out[r, 1]
    return chains, chain_offsets
