"""Isolines (§3.3): marching squares over the mapped grid, all levels in one scan.

The grid is padded with a ring lying below every level, so every contour is closed; the
stretches that run along the image border are flagged (they are not isolines). Saddles are
resolved by the asymptotic decider, so isolines of one channel never cross or touch
(see _kernels/marching.py). Each loop is oriented with values >= its level on its left.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._kernels.marching import link_loops, march
from .levels import bands
from .ribbon import gradient_magnitude, tolerances


@dataclass(frozen=True)
class Isolines:
    """Closed polylines of one channel.

    points : (N, 2) float64; loop i is points[offsets[i]:offsets[i+1]] (first point not repeated);
        segment k of a loop runs from its point k to point k+1 (cyclically).
    border : (N,) bool, per segment: runs along the image border.
    tol : (N,) float64, ribbon half-width at each point (pixels).
    level : (C,) int32 level index of each loop.
    above, below : (N,) int64, per segment: the padded-grid samples at either end of the grid edge
        its start point lies on (the above one on the segment's left); for border segments the
        below one is padding.
    band : (Hp, Wp) int16 padded band grid; values : (Hp, Wp) float64 padded grid (pad = 0).
    base_band : the band of the root region; the loops of levels below it would lie wholly on
        the image border and are left out (see model.py).
    """

    points: np.ndarray
    offsets: np.ndarray
    border: np.ndarray
    tol: np.ndarray
    level: np.ndarray
    above: np.ndarray
    below: np.ndarray
    band: np.ndarray
    values: np.ndarray
    base_band: int = 0

    @property
    def n_loops(self) -> int:
        return int(self.level.shape[0])

    def loop(self, i: int) -> np.ndarray:
        return self.points[self.offsets[i] : self.offsets[i + 1]]


def pad_grid(grid: np.ndarray, levels: np.ndarray):
    """Padded values and bands: a ring of band 0 (below every level) around the grid."""
    hg, wg = grid.shape
    vals = np.zeros((hg + 2, wg + 2), np.float64)
    vals[1:-1, 1:-1] = grid
    band = np.zeros((hg + 2, wg + 2), np.int16)
    band[1:-1, 1:-1] = bands(grid, levels)
    return vals, band


def find_isolines(grid, grid_eps, levels, min_tol=0.05, max_tol=0.5) -> Isolines:
    """All isolines of a mapped grid (see encode.mapping for the grid layout)."""
    levels = np.asarray(levels, np.float64)
    vals, band = pad_grid(grid, levels)
    hp, wp = vals.shape
    seg = march(vals, band, levels)
    order, offs = link_loops(seg["skey"], seg["ekey"])
    if order.shape[0] != seg["skey"].shape[0]:
        raise RuntimeError("marching squares produced an open contour")  # a bug, never input
    below, above, t = seg["below"][order], seg["above"][order], seg["t"][order]
    rb, cb = np.divmod(below, wp)
    ra, ca = np.divmod(above, wp)
    # padded (r, c) -> image (x, y) = ((c - 1) / 2, (r - 1) / 2)
    x = ((cb - 1) + t * (ca - cb)) * 0.5
    y = ((rb - 1) + t * (ra - rb)) * 0.5
    points = np.column_stack([x, y])
    eps_p = np.zeros((hp, wp))
    eps_p[1:-1, 1:-1] = grid_eps
    grad_p = np.zeros((hp, wp))
    grad_p[1:-1, 1:-1] = gradient_magnitude(np.asarray(grid, np.float64))
    ef, gf = eps_p.ravel(), grad_p.ravel()
    tol = tolerances(ef[below], ef[above], gf[below], gf[above], t, min_tol, max_tol)
    first = order[offs[:-1]]
    border = seg["border"][order]
    level = seg["level"][first].astype(np.int32)
    # loops lying wholly on the border: the image border is above their level all round
    seg_loop = np.repeat(np.arange(len(first)), np.diff(offs))
    interior = np.zeros(len(first), bool)
    interior[seg_loop[~border]] = True
    base = int(np.count_nonzero(~interior))
    if base and not np.array_equal(np.sort(level[~interior]), np.arange(base)):
        raise RuntimeError("frame loops are not the lowest levels")  # a bug, never input
    keep_seg = interior[seg_loop]
    counts = np.diff(offs)[interior]
    return Isolines(
        points=points[keep_seg],
        offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
        border=border[keep_seg],
        tol=tol[keep_seg],
        level=level[interior],
        above=above[keep_seg],
        below=below[keep_seg],
        band=band,
        values=vals,
        base_band=base,
    )


def signed_area(loop: np.ndarray) -> float:
    """Shoelace area of a closed polyline (first point not repeated), in x-right y-down axes."""
    x, y = loop[:, 0], loop[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
