"""Isolines (§3.3): marching squares over the mapped grid, all levels in one scan.

The grid is padded with a ring lying below every level, so every contour is closed; the
stretches that run along the image border are flagged (they are not isolines). Saddles are
resolved by the asymptotic decider, so isolines of one channel never cross or touch
(see _kernels/marching.py). Each loop is oriented with values >= its level on its left.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..shared.heap import release_read
from ._kernels.marching import march_loops, pad_bands
from .ribbon import tolerances


@dataclass(frozen=True)
class Isolines:
    """Closed polylines of one channel.

    along : (N,) float64, each point's coordinate along the grid edge it lies on (x on a
        horizontal edge, y on a vertical one); its other coordinate is its below sample's
        (``points``, points_of: 8 bytes a point rather than 16). Loop i is points
        offsets[i] .. offsets[i + 1] - 1 (first point not repeated); segment k of a loop runs
        from its point k to point k+1 (cyclically).
    border : (N,) bool, per segment: runs along the image border.
    tol : (N,) float64, ribbon half-width at each point (pixels).
    level : (C,) int32 level index of each loop.
    below : (N,) int32, per segment: the padded-grid sample at the below end of the grid edge
        its start point lies on (for border segments the padding); step : (N,) int8, which
        4-neighbour of it the edge's other end, the above sample (on the segment's left), is
        (STEP_RIGHT, STEP_LEFT, STEP_DOWN, STEP_UP: +1, -1, +Wp, -Wp; a byte a point rather
        than the sample's 4); ``above`` gives those samples (above_of).
    band : (Hp, Wp) padded band grid (int16; uint8 from the strips when it fits: levels.band_dtype); values : (Hp, Wp) float64 padded grid (pad = 0), or
        a row source giving rows of it (encoder/strips.py GridRows; hierarchy.value_rows).
    base_band : the band of the root region; the loops of levels below it would lie wholly on
        the image border and are left out (see model.py).
    saddles : None, or the (n, 2) flat sample pairs of the regions' diagonal joins that the
        values decide (_kernels/regions.py saddle_unions), so that the regions are labelled
        without the values (the strips record them).
    """

    along: np.ndarray
    offsets: np.ndarray
    border: np.ndarray
    tol: np.ndarray
    level: np.ndarray
    step: np.ndarray
    below: np.ndarray
    band: np.ndarray
    values: object
    base_band: int = 0
    saddles: np.ndarray | None = None

    @property
    def points(self) -> np.ndarray:
        """(N, 2) float64: the points (a new array; points_of)."""
        return points_of(self.below, self.step, self.along, self.band.shape[1])

    @property
    def above(self) -> np.ndarray:
        """(N,) int32: the above sample of each segment's grid edge (a new array)."""
        return above_of(self.below, self.step, self.band.shape[1])

    @property
    def n_loops(self) -> int:
        return int(self.level.shape[0])

    def loop(self, i: int) -> np.ndarray:
        a, b = self.offsets[i], self.offsets[i + 1]
        return points_of(self.below[a:b], self.step[a:b], self.along[a:b], self.band.shape[1])


STEP_RIGHT, STEP_LEFT, STEP_DOWN, STEP_UP = 0, 1, 2, 3


def step_codes(below: np.ndarray, above: np.ndarray, wp: int) -> np.ndarray:
    """(N,) int8: which 4-neighbour of its below sample each above sample is (Isolines.step;
    padded grid rows of ``wp`` samples)."""
    d = np.asarray(above, np.int64) - below
    code = np.full(d.shape, -1, np.int8)
    for c, delta in ((STEP_RIGHT, 1), (STEP_LEFT, -1), (STEP_DOWN, wp), (STEP_UP, -wp)):
        code[d == delta] = c
    if np.any(code < 0):
        raise RuntimeError("a crossing's samples are not 4-neighbours")  # a bug, never input
    return code


def above_of(below: np.ndarray, step: np.ndarray, wp: int) -> np.ndarray:
    """The above samples (int32) of below samples and their step codes (step_codes')."""
    delta = np.array([1, -1, wp, -wp], np.int64)
    return (below + delta[step]).astype(np.int32)


def along_of(points: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Each point's coordinate along its grid edge (Isolines.along): x where the edge is
    horizontal (step STEP_RIGHT or STEP_LEFT), y where it is vertical."""
    return np.where(step <= STEP_LEFT, points[:, 0], points[:, 1])


POINTS_CHUNK = 1 << 20  # points points_of makes at a time (bounds its temporaries)


def points_of(below: np.ndarray, step: np.ndarray, along: np.ndarray, wp: int) -> np.ndarray:
    """(N, 2) float64 points from their edges (below samples of a padded grid of ``wp``
    samples a row, step codes) and coordinates along them: the other coordinate is the
    below sample's, (c - 1) / 2 or (r - 1) / 2, exactly what the march gives a crossing of
    that edge (both ends of a horizontal edge share their row, of a vertical one their
    column)."""
    n = along.shape[0]
    out = np.empty((n, 2))
    for a in range(0, n, POINTS_CHUNK):
        b = min(a + POINTS_CHUNK, n)
        out[a:b, 0], out[a:b, 1] = _xy_rows(below[a:b], step[a:b], along[a:b], wp)
    return out


def _xy_rows(below, step, along, wp):
    """The x and y of some points from their compact form (points_of's rule)."""
    r, c = np.divmod(below.astype(np.int64), wp)
    horizontal = step <= STEP_LEFT
    return np.where(horizontal, along, (c - 1) * 0.5), np.where(horizontal, (r - 1) * 0.5, along)


def ranges(starts: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Concatenated index ranges [starts[k], starts[k] + lengths[k]) (int64): the points of
    some loops, the segments of some runs."""
    total = int(lengths.sum())
    before = np.cumsum(lengths) - lengths
    return np.repeat(starts - before, lengths) + np.arange(total, dtype=np.int64)


def xy_in_place(along: np.ndarray, below: np.ndarray, step: np.ndarray, wp: int, release: bool = False,
                pager=None):
    """(x, y): points_of's columns, y a new array and x made in ``along``'s own memory (which
    it consumes): 8 bytes a point beside the compact form rather than 16. With ``release``
    (for a caller that drops below and step afterwards) their pages go back chunk by chunk
    as y is made (shared/heap.py release_read): y's 8 bytes a point come as their 5 go.
    With a ``pager`` (shared/spill.py Pager), y is on its files and the pages of every
    array on them go after each chunk."""
    y = np.empty_like(along) if pager is None else pager.empty(along.shape, along.dtype)
    for a in range(0, along.shape[0], POINTS_CHUNK):
        b = min(a + POINTS_CHUNK, along.shape[0])
        along[a:b], y[a:b] = _xy_rows(below[a:b], step[a:b], along[a:b], wp)
        if release:
            release_read(below, a, b)
            release_read(step, a, b)
        if pager is not None:
            pager.release()
    return along, y


def pad_grid(grid: np.ndarray, levels: np.ndarray):
    """Padded values and bands: a ring of band 0 (below every level) around the grid."""
    return pad_bands(np.ascontiguousarray(grid, np.float64), np.ascontiguousarray(levels, np.float64))


def find_isolines(grid, grid_eps, levels, min_tol=0.05, max_tol=0.5) -> Isolines:
    """All isolines of a mapped grid (see encode.mapping for the grid layout).

    One compiled pass (_kernels/marching.py: march_loops) marches, links the segments into
    loops and gathers, per point, the sample errors and gradient magnitudes that
    ribbon.tolerances turns into tolerances (the gradient as ribbon.gradient_magnitude's,
    at the samples next to a crossing only; tests/encoder/test_encoder_kernels.py holds them equal).
    """
    levels = np.ascontiguousarray(levels, np.float64)
    grid = np.ascontiguousarray(grid, np.float64)
    grid_eps = np.ascontiguousarray(np.broadcast_to(grid_eps, grid.shape), np.float64)
    vals, band = pad_grid(grid, levels)
    (ok, points, border, below, above, t, eps_b, eps_a, grad_b, grad_a, level, offsets,
     frame_levels) = march_loops(vals, band, levels, grid, grid_eps)
    if not ok:
        raise RuntimeError("marching squares produced an open contour")  # a bug, never input
    # loops lying wholly on the border (the image border is above their level all round)
    # are left out: they must be the lowest levels
    base = frame_levels.shape[0]
    if base and not np.array_equal(np.sort(frame_levels), np.arange(base)):
        raise RuntimeError("frame loops are not the lowest levels")  # a bug, never input
    step = step_codes(below, above, band.shape[1])
    return Isolines(
        along=along_of(points, step),
        offsets=offsets,
        border=border,
        tol=tolerances(eps_b, eps_a, grad_b, grad_a, t, min_tol, max_tol),
        level=level,
        step=step,
        below=below,
        band=band,
        values=vals,
        base_band=base,
    )


def signed_area(loop: np.ndarray) -> float:
    """Shoelace area of a closed polyline (first point not repeated), in x-right y-down axes."""
    x, y = loop[:, 0], loop[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))
