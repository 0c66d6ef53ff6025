"""Bezier chains fitted inside the error ribbon of a polyline (paper §3.3).

"The resulting polyline approximation to the 'true' contour is simplified by finding the
Bézier chain with the fewest segments which fit within the error ribbon the polyline
approximation defines." Each polyline point carries its own tolerance (the half-width of
the ribbon there). Segments are fitted first ignoring continuity, then joints whose
tangents are within ``snap`` degrees of continuing each other are made G1 ("snapping",
§1) wherever the chain stays inside the ribbon.

Guarantees of :func:`fit_polyline` and :func:`fit_many` (up to rounding), for every
polyline point k and every point x of the returned chain:

* ``dist(points[k], chain) <= tol[k]``;
* ``dist(x, polyline) <= max(tol[e], tol[e+1])`` for some edge e = [e, e+1] of the span of
  polyline points that x's segment covers, so the curve cannot bulge between points. This
  holds for the whole curve, not only at samples: the check bounds the curve's excursion
  between samples by its second derivative;
* between two polyline points the curve runs the way of their edge (checked at samples),
  so no segment ties a loop inside the ribbon;
* open chains start at ``points[0]`` and end at ``points[-1]``; closed chains start and end
  at the same joint (``chain[-1] == chain[0]``); every joint is an input point, or with
  ``anchor_grid`` > 0 one moved onto that grid by at most its reach (<= its tolerance;
  the joint is then where the tests above place the curve's end);
* with ``coarsen`` > 0 (the file's grids) every joint, ends included, is then rounded to
  the 1/64 px grid, and each segment's handles are put on a grid of the file's and checked
  there: the coarsest that fits, else the 1/64 px grid itself, else another rounding of
  their four coordinates to it; only a segment none of those fits (a small fraction of the
  encoder's; measured: benchmarks/results/design_choices.md#handle-grid-fallback) keeps
  handles off that grid. So the file's rounding moves nothing
  but those handles (by up to 1/128 px a coordinate), and the tests above hold for the
  stored chain elsewhere;
* output is finite and deterministic (same input, same bytes).

The chain layout and the coordinate convention are those of :mod:`isophote.model`.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from scipy.spatial import cKDTree

from .. import threads
from ._kernels.fit import fit_many_kernel

__all__ = ["fit_polyline", "fit_many", "chain_distance"]


def _cos_snap(snap: float) -> float:
    snap = float(snap)
    if not (0.0 <= snap < 90.0):
        raise ValueError(f"snap must be in [0, 90) degrees, got {snap}")
    # snap == 0 disables snapping: no angle is below 0 degrees
    return math.cos(math.radians(snap)) if snap > 0.0 else 1.0


def _anchor_grid(grid: float) -> float:
    grid = float(grid)
    if not (math.isfinite(grid) and grid >= 0.0):
        raise ValueError(f"anchor_grid must be finite and >= 0, got {grid}")
    return grid


# How far a joint may move onto the anchor grid when no reach is given, in tolerances.
ANCHOR_REACH = 0.75


def _reach(reach, tol: np.ndarray) -> np.ndarray:
    if reach is None:
        return ANCHOR_REACH * tol
    reach = np.ascontiguousarray(reach, dtype=np.float64)
    if reach.shape != tol.shape:
        raise ValueError(f"reach must have shape {tol.shape}, got {reach.shape}")
    if not np.all((reach >= 0.0) & (reach <= tol)):
        raise ValueError("reach must lie in [0, tol]")
    return reach


def _check_points(points, tol):
    points = np.ascontiguousarray(points, dtype=np.float64)
    tol = np.ascontiguousarray(tol, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 2:
        raise ValueError(f"points must have shape (n, 2), got {points.shape}")
    if tol.shape != (points.shape[0],):
        raise ValueError(f"tol must have shape ({points.shape[0]},), got {tol.shape}")
    if not np.all(np.isfinite(points)):
        raise ValueError("points must be finite")
    if not np.all(np.isfinite(tol) & (tol > 0.0)):
        raise ValueError("tol must be finite and > 0")
    return points, tol


def fit_polyline(points, tol, closed, snap=20.0, coarsen=0, anchor_grid=0.0, reach=None):
    """Fit a Bezier chain with few segments inside the error ribbon of a polyline.

    Parameters
    ----------
    points : (n, 2) float64 array_like
        The polyline, in pixel units (see :mod:`isophote.model`). Open: n >= 2. Closed: the
        loop WITHOUT its first point repeated at the end, n >= 3.
    tol : (n,) float64 array_like
        Tolerance of each point (> 0): the half-width of the error ribbon, in the units of
        ``points``.
    closed : bool
        Whether the polyline is a loop.
    snap : float, optional
        G1 snapping threshold in degrees, in [0, 90); 0 disables snapping.
    coarsen : int, optional
        > 0 puts the joints on the file's 1/64 px grid and each segment's handles on the
        coarsest of the file's handle grids (up to 2**coarsen / 64 px, in the chord's
        frame, down to 1/64 px) on which it still fits; 0 leaves them.
    anchor_grid : float, optional
        > 0 moves each joint onto the multiples of ``anchor_grid`` px in every coordinate
        within its point's ``reach`` of one (not the ends of an open polyline); 0 leaves
        the joints at their points.
    reach : (n,) float64 array_like, optional
        How far each point may move as a joint, in [0, tol]; None: ``ANCHOR_REACH * tol``.

    Returns
    -------
    chain : (1 + 3m, 2) float64 ndarray
        ``P0, C0a, C0b, P1, ..., Pm`` with m >= 1. Open: ``P0 == points[0]`` and
        ``Pm == points[-1]`` (rounded to 1/64 px with ``coarsen`` > 0). Closed:
        ``Pm == P0``, the sharpest turn's point (moved onto the anchor grid if it may be).

    Notes
    -----
    Greedy longest fit: from each joint the next segment is grown (a first try as long as
    the previous segment, galloping on while it fits, then a binary search over the end
    point) as far as a cubic still fits. A span's cubic keeps the
    span's end points; its two inner controls come from least squares over chord-length
    parameters [1]_ (weights 1/tol^2), then up to two Gauss-Newton steps of tangent
    distance minimisation [2]_, each followed by a Newton reparameterisation; Schneider's
    plain alternation converges too slowly to recover even an exact cubic. Then joints
    whose handles differ in direction by less than ``snap`` degrees get both handles
    rotated onto their length-weighted bisector, if both segments still fit. A two-point
    open polyline gives the straight segment with controls at its thirds. The kernels and
    their NumPy reference twin are in :mod:`isophote._kernels.fit`.

    References
    ----------
    .. [1] P. J. Schneider, "An algorithm for automatically fitting digitized curves",
       Graphics Gems, 1990.
    .. [2] W. Wang, H. Pottmann, Y. Liu, "Fitting B-spline curves to point clouds by
       curvature-based squared distance minimization", ACM TOG 25(2), 2006.
    """
    points, tol = _check_points(points, tol)
    closed = bool(closed)
    n = points.shape[0]
    if n < (3 if closed else 2):
        raise ValueError(f"a {'closed' if closed else 'open'} polyline needs at least "
                         f"{3 if closed else 2} points, got {n}")
    chains, _ = fit_many_kernel(points, tol, np.array([0, n], np.int64), np.array([closed]),
                                _cos_snap(snap), int(coarsen), _anchor_grid(anchor_grid),
                                _reach(reach, tol))
    return chains


def fit_many(points, tol, offsets, closed, snap=20.0, coarsen=0, anchor_grid=0.0, reach=None):
    """Fit many polylines at once; equal to :func:`fit_polyline` on each.

    Large batches are fitted in parallel: groups of consecutive polylines with about equal
    point counts go to the compiled kernel in threads (it releases the GIL). Each chain
    depends on its own polyline alone, so the output is the same bytes whatever the number
    of threads.

    Parameters
    ----------
    points : (N, 2) float64 array_like
        All polylines concatenated; polyline k is ``points[offsets[k]:offsets[k+1]]``.
    tol : (N,) float64 array_like
        Per-point tolerances (> 0).
    offsets : (K + 1,) int array_like
        Non-decreasing, ``offsets[0] == 0`` and ``offsets[-1] == N``.
    closed : (K,) bool array_like
        Whether each polyline is a loop (given without its first point repeated).
    snap, coarsen, anchor_grid, reach : optional, as :func:`fit_polyline` (reach (N,)).

    Returns
    -------
    chains : (P, 2) float64 ndarray
        All chains concatenated.
    chain_offsets : (K + 1,) int64 ndarray
        Chain k is ``chains[chain_offsets[k]:chain_offsets[k+1]]``.
    """
    points, tol = _check_points(points, tol)
    offsets = np.asarray(offsets)
    closed = np.asarray(closed)
    if offsets.ndim != 1 or offsets.shape[0] < 1 or not np.issubdtype(offsets.dtype, np.integer):
        raise ValueError("offsets must be a 1-d integer array of length K + 1 >= 1")
    offsets = np.ascontiguousarray(offsets, dtype=np.int64)
    if closed.shape != (offsets.shape[0] - 1,):
        raise ValueError(f"closed must have shape ({offsets.shape[0] - 1},), got {closed.shape}")
    closed = np.ascontiguousarray(closed, dtype=np.bool_)
    if offsets[0] != 0 or offsets[-1] != points.shape[0]:
        raise ValueError("offsets must start at 0 and end at len(points)")
    sizes = np.diff(offsets)
    if np.any(sizes < np.where(closed, 3, 2)):
        raise ValueError("every open polyline needs >= 2 points and every closed one >= 3")
    cos_snap = _cos_snap(snap)
    workers = _workers()
    coarsen = int(coarsen)
    grid = _anchor_grid(anchor_grid)
    reach = _reach(reach, tol)
    if workers < 2 or points.shape[0] < PARALLEL_POINTS:
        return fit_many_kernel(points, tol, offsets, closed, cos_snap, coarsen, grid, reach)
    # groups of consecutive polylines, about equal in points, several per thread so that
    # a thread that finishes early takes another
    cuts = np.searchsorted(offsets, np.linspace(0, points.shape[0], 4 * workers + 1)[1:-1])
    bounds = np.unique(np.concatenate([[0], cuts, [len(closed)]]))

    def part(k):
        o = offsets[bounds[k] : bounds[k + 1] + 1]
        return fit_many_kernel(points[o[0] : o[-1]], tol[o[0] : o[-1]], o - o[0],
                               closed[bounds[k] : bounds[k + 1]], cos_snap, coarsen, grid,
                               reach[o[0] : o[-1]])

    with ThreadPoolExecutor(max_workers=workers) as pool:
        parts = list(pool.map(part, range(len(bounds) - 1)))
    chains = np.concatenate([c for c, _ in parts])
    lengths = np.concatenate([np.diff(co) for _, co in parts])
    return chains, np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)


# Batches of fewer points are fitted in the calling thread (threads would cost more than
# they save).
PARALLEL_POINTS = 20_000


def _workers() -> int:
    """Threads for fit_many: the processors this process may use, at most 8."""
    return threads.available(8)


def _eval_chain(chain, seg, t):
    """Points of segment(s) ``seg`` of a chain at parameters ``t`` (same shape): (..., 2)."""
    t = t[..., None]
    s = 1.0 - t
    return (s * s * s * chain[3 * seg] + 3.0 * s * s * t * chain[3 * seg + 1]
            + 3.0 * s * t * t * chain[3 * seg + 2] + t * t * t * chain[3 * seg + 3])


def chain_distance(chain, pts, samples=200):
    """Distance from each point to a Bezier chain, by brute force.

    Independent of the fitter: the chain is sampled densely (``samples`` intervals per
    segment), each point's nearest sample is found, and the distance is refined by a
    ternary search over the curve on both sides of that sample. Every value returned is
    the distance to an actual curve point, so it never underestimates the true distance
    by more than rounding; it overestimates it only when the nearest sample is not next to
    the nearest curve point (then by at most half a sample spacing).

    Parameters
    ----------
    chain : (1 + 3m, 2) float64 array_like
        A chain of m >= 1 cubic segments (see :mod:`isophote.model`).
    pts : (k, 2) float64 array_like
        Query points.
    samples : int, optional
        Sample intervals per segment.

    Returns
    -------
    dist : (k,) float64 ndarray
    """
    chain = np.asarray(chain, dtype=np.float64)
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    if chain.ndim != 2 or chain.shape[1] != 2 or chain.shape[0] < 4 or (chain.shape[0] - 1) % 3:
        raise ValueError(f"chain must have shape (1 + 3m, 2) with m >= 1, got {chain.shape}")
    m = (chain.shape[0] - 1) // 3
    if pts.shape[0] == 0:
        return np.zeros(0)
    # sample g (0 .. m*samples) is segment g // samples at t = (g % samples) / samples;
    # the last one is the end of the last segment
    g = np.arange(m * samples + 1)
    seg = np.minimum(g // samples, m - 1)
    t = (g - seg * samples) / samples
    best, gi = cKDTree(_eval_chain(chain, seg, t)).query(pts)
    # refine over the sample intervals [gi - 1, gi] and [gi, gi + 1], both at once
    lo = np.concatenate([gi - 1, gi])
    who = np.concatenate([np.arange(len(pts))] * 2)
    ok = (lo >= 0) & (lo < m * samples)
    lo, who = lo[ok], who[ok]
    p = pts[who]
    sg = lo // samples
    a = (lo - sg * samples) / samples
    b = a + 1.0 / samples
    sg2 = np.concatenate([sg, sg])
    p2 = np.concatenate([p, p])
    for _ in range(40):
        x1 = a + (b - a) / 3.0
        x2 = b - (b - a) / 3.0
        d = np.sum((_eval_chain(chain, sg2, np.concatenate([x1, x2])) - p2) ** 2, axis=-1)
        left = d[: len(a)] <= d[len(a) :]
        b = np.where(left, x2, b)
        a = np.where(left, a, x1)
    d = np.sqrt(np.sum((_eval_chain(chain, sg, 0.5 * (a + b)) - p) ** 2, axis=-1))
    np.minimum.at(best, who, d)
    return best
