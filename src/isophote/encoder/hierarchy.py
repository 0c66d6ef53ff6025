"""The encloses tree (§4) and cap annotations.

parent(loop) is the innermost loop enclosing it, found by winding numbers along a ray
(loops never cross, so one point of a loop decides; _kernels/enclose.py). Loops lying wholly
on the image border are not kept (see isolines.py), so every loop has an isoline stretch.
A region is a footprint minus its children's footprints.

Caps: a connected region (of the labelled band grid, _kernels/regions.py) whose bounding
contours all have one level is a peak (band above that level)
or a pit (band at or below it); it is annotated with a least-squares cap value (the profile
of model.py) at its deepest sample, the one farthest from the region's edges. A region with
no bounding contour at all (a channel that never crosses a level) gets its mean.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .. import threads
from ..geometry.areas import polyline_areas, polyline_areas_range
from ..model import CAP_RAMP
from ..shared.spill import RELEASE_POINTS
from ._kernels.enclose import (
    count_rows, innermost_enclosing, innermost_enclosing_rows, loop_blocks, place_rows, sweep_enclosing_rows,
)
from ._kernels.regions import (
    label_regions_rows, label_regions_saddles, loop_levels, region_bands, region_deep, slots_of_regions,
    value_sums_rows,
    whole,
)
from .isolines import Isolines, ranges, xy_in_place


@dataclass(frozen=True)
class Hierarchy:
    parent: np.ndarray  # (C,) int32
    n_regions: int
    cap_band: np.ndarray
    cap_contour: np.ndarray
    cap_xy: np.ndarray
    cap_value: np.ndarray


def loop_areas(iso: Isolines) -> np.ndarray:
    """Signed shoelace area of every loop, vectorised."""
    return polyline_areas(iso.points, iso.offsets)


def value_rows(values):
    """A row source (rows(w0, w1): padded rows [w0, w1) of the value grid) for an Isolines'
    values: the grid itself, or the encoder's GridRows, which computes rows again from the
    channel's plane (encoder/strips.py) rather than hold the grid."""
    return values if callable(values) else whole(values)


def _cap_fit(num, den, has_edge, rows, labels, L):
    """Least-squares cap values for the profile of model.py from value_sums_rows' sums, per
    cap (d is measured on the grid: the distance to the nearest sample of another region,
    not the padding, plus half a grid step, in pixels: _kernels/regions.py cap_sums)."""
    if not has_edge:  # one region: the mean of the whole grid (made whole here, the same bits)
        return np.array([float(rows(0, labels.shape[0])[1:-1, 1:-1].mean())] * L.shape[0])
    out = L + num / np.maximum(den, 1e-12)
    return np.clip(out, 0.0, 255.0)


def segment_table(iso: Isolines, n_rows: int | None = None, xy=None, pager=None):
    """Segments as (x, y, offsets, blocks) arrays and their bucketing by half-pixel grid
    row: segment s runs from point s, (x[s], y[s]), to the next point of its loop (its
    loop's first after its last: successors; loop i is points offsets[i] .. offsets[i + 1]
    - 1, blocks its index, _kernels/enclose.py loop_blocks); its row is that of its
    upper end, clamped to the n_rows rows (by default those of the Isolines' band grid);
    ``xy``: the points' x and y, where the caller has made them.

    x and y are views of the points (or the caller's); the row order is int32 (a channel's
    points are far below 2**31): 4 bytes a point in all. The rows are bucketed as
    bucket_rows does (a stable counting sort), found twice a chunk of ROW_CHUNK segments at
    a time rather than held (4 bytes a point less at the table's peak). With a ``pager``,
    the row order is on its files, and its pages go after each chunk."""
    if xy is None:
        p = iso.points
        xy = p[:, 0], p[:, 1]
    x, y = xy
    n = x.shape[0]
    offsets = np.ascontiguousarray(iso.offsets, np.int64)
    if n_rows is None:
        n_rows = max(iso.band.shape[0] - 3, 1)

    def rows(a):  # the row of each segment's upper end, clamped
        b = min(a + ROW_CHUNK, n)
        t = np.minimum(y[a:b], y[successors_of_range(a, b, offsets)])
        t *= 2.0
        return np.clip(np.floor(t), 0, n_rows - 1).astype(np.int32)

    # bucket_rows' counting sort, the rows found twice a chunk at a time rather than held
    row_start = np.zeros(n_rows + 1, np.int64)
    for a in range(0, n, ROW_CHUNK):
        count_rows(rows(a), row_start)
        if pager is not None:
            pager.release()
    np.cumsum(row_start, out=row_start)
    fill = row_start[:-1].copy()
    row_order = np.empty(n, np.int32) if pager is None else pager.empty(n, np.int32)
    for a in range(0, n, ROW_CHUNK):
        place_rows(rows(a), a, fill, row_order)
        if pager is not None:
            pager.release()
    return x, y, offsets, loop_blocks(offsets), row_start, row_order, n_rows


def successors(s: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """The point each segment of ``s`` runs to: the next of its loop, its loop's first after
    its last (enclose._succ's rule)."""
    lp = np.searchsorted(offsets, s, "right") - 1
    nx = s + 1
    last = nx == offsets[lp + 1]
    nx[last] = offsets[lp[last]]
    return nx


def successors_of_range(a: int, b: int, offsets: np.ndarray) -> np.ndarray:
    """successors(np.arange(a, b), offsets), from the loops that end in the range alone."""
    nx = np.arange(a + 1, b + 1, dtype=np.int64)
    l0, l1 = np.searchsorted(offsets, [a + 1, b], "left")  # the loops whose last point is in [a, b)
    ends = offsets[l0 : l1 + 1]
    ends = ends[(ends > a) & (ends <= b)]
    nx[ends - 1 - a] = offsets[np.searchsorted(offsets, ends, "left") - 1]
    return nx


ROW_CHUNK = 1 << 20  # segments segment_table rows at a time (bounds its temporaries)


def crossing_levels(iso: Isolines, labels: np.ndarray, m: int, release=None):
    """The lowest and highest level of the isoline (not border) crossings that bound each
    region (_kernels/regions.py loop_levels, loop by loop). With ``release`` (a Pager's),
    runs of loops of about RELEASE_POINTS points, release() called after each (the same
    levels: the lowest and highest of the runs')."""
    args = (labels, iso.band, iso.step, iso.below, iso.border)
    if release is None:
        return loop_levels(*args, iso.offsets, iso.level, m)
    lo = hi = None
    for i0, i1 in loop_runs(iso.offsets, RELEASE_POINTS):
        a, b = loop_levels(*args, iso.offsets[i0 : i1 + 1], iso.level[i0:i1], m)
        release()
        lo, hi = (a, b) if lo is None else (np.minimum(lo, a, out=lo), np.maximum(hi, b, out=hi))
        del a, b
    return lo, hi


def loop_runs(offsets: np.ndarray, points: int) -> list:
    """Runs [i0, i1) of consecutive loops of about ``points`` points each (at least one
    loop a run; offsets: the loops' offsets), covering every loop."""
    n_loops = offsets.shape[0] - 1
    if n_loops == 0:
        return []
    cuts = np.searchsorted(offsets, np.arange(points, int(offsets[-1]), points), "left")
    cuts = np.unique(np.clip(np.concatenate([[0], cuts, [n_loops]]), 0, n_loops))
    return [(int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]


def build_hierarchy(iso: Isolines, levels: np.ndarray) -> Hierarchy:
    """Parents (geometrically, by winding numbers) and caps (on the band grid's regions).

    Isolines of several levels can pass between the same two grid samples, so some regions
    of the hierarchy hold no sample; the tree is therefore built from the loops' geometry.
    Caps always hold samples (a region above or below its only level contains a sample on
    that side), so they are found on the labelled band grid: a region's bounding levels are
    the levels of the crossings next to its samples.
    """
    labels, m = _labels(iso, levels)
    bounds = list(crossing_levels(iso, labels, m))
    p = iso.points
    return _enclosing(iso, (p[:, 0], p[:, 1]), *_caps(iso, levels, [labels], m, bounds, [iso.band]))


def build_hierarchy_held(held: list, levels: np.ndarray, pager=None) -> Hierarchy:
    """build_hierarchy of the one Isolines in ``held`` (no one else may hold it), which is
    put back with its points, offsets, levels and border flags alone once the caps are
    fitted. The saddle joins go once the regions' bounding levels are found, the bands
    once the candidate caps' bands are read, both before the caps' distances and sums; the
    values' row source (the plane it computes them from) once the caps are fitted; then the
    points are made from their compact form (x in its own memory) before the parents'
    segment table. With a ``pager`` (shared/spill.py Pager: the Isolines' per-point arrays
    on its files), y and the segment table's row order go on its files too, and the pages
    go between the runs of loops and rows (the same hierarchy)."""
    iso = held.pop()
    release = None if pager is None else pager.release
    labels, m = _labels(iso, levels)
    bounds = list(crossing_levels(iso, labels, m, release))
    iso = replace(iso, saddles=None)
    lab = [labels]
    del labels
    hp, wp = iso.band.shape
    bands = [iso.band]
    iso = replace(iso, band=None)  # the bands go once the caps' bands are read
    caps = _caps(iso, levels, lab, m, bounds, bands)
    n_rows = max(hp - 3, 1)
    iso = replace(iso, values=None)  # the plane goes
    # the points' x and y (x in along's memory), the compact form's samples going with them
    xy = xy_in_place(iso.along, iso.below, iso.step, wp, release=True, pager=pager)
    held.append(replace(iso, along=None, below=None, step=None))
    del iso
    return _enclosing(held[0], xy, *caps, n_rows=n_rows, pager=pager)


def _labels(iso: Isolines, levels: np.ndarray):
    """The regions of the band grid: (labels, m)."""
    if iso.saddles is not None:  # the strips recorded what the values decide
        return label_regions_saddles(iso.band, iso.saddles)
    return label_regions_rows(value_rows(iso.values), iso.band, np.asarray(levels, np.float64))


def _caps(iso: Isolines, levels: np.ndarray, lab: list, m: int, bounds: list, bands: list):
    """The caps on the labelled band grid (the one labels array in ``lab``, emptied: it goes
    once the caps are fitted; ``bounds``: [lo, hi], the regions' bounding levels,
    crossing_levels', emptied once the candidates are known; ``bands``: [the band grid],
    emptied once the candidates' bands are read, before the regions' distances):
    (n_regions, cap_band, cap_xy, cap_value).

    A region is a cap when its bounding levels are one (border stretches are no isolines:
    the decoder takes no distance from them, so a region that one level closes against the
    frame is a cap, whatever levels run along the frame). What is found of the regions
    (deepest samples, counts, sums) is held per cap, not per region (_kernels/regions.py
    slots_of: the mosaic's luma has 5.2 M regions, 0.66 M caps)."""
    labels = lab.pop()
    hi = bounds.pop()
    lo = bounds.pop()
    c = iso.n_loops
    is_cap = (hi >= 0) & (lo == hi)
    if c == 0:
        is_cap = np.ones(m, bool)
    cand = np.flatnonzero(is_cap)
    lo, hi = lo[cand], hi[cand]
    del is_cap
    slot = slots_of_regions(m, cand)
    band = bands.pop()
    wp = band.shape[1]
    cap_band = region_bands(labels, band, slot)
    del band
    deep, count = region_deep(labels, slot)
    keep = count > 0  # the padding-only part of the root has no samples
    regs = cand[keep]
    slot[cand] = -1
    slot[regs] = np.arange(regs.shape[0], dtype=np.int32)
    deep, count, lo, hi, cap_band = deep[keep], count[keep], lo[keep], hi[keep], cap_band[keep]
    del cand, keep
    rows = value_rows(iso.values)
    no_contour = hi < 0  # the mean
    single = ~no_contour  # a least-squares profile (_cap_fit)
    level_value = np.where(single, np.asarray(levels, np.float64)[np.maximum(lo, 0) * single], 0.0)
    # one pass over the values: the caps' sums and least-squares sums
    total, num, den, has_edge = value_sums_rows(labels, rows, slot, level_value, float(CAP_RAMP))
    with np.errstate(invalid="ignore", divide="ignore"):
        cap_value = total / count
    if len(regs):
        fitted = _cap_fit(num, den, has_edge, rows, labels, level_value)
        cap_value = np.where(single, fitted, cap_value)
    cap_idx = deep.astype(np.int64)
    del labels, deep, total, count, slot
    # the cap is placed at the region's deepest sample: the annotation only names its region,
    # and a sample far from the region's edges keeps naming it when the fitted contours move
    # within their ribbons (an extremum on a plateau would be the plateau's first sample in
    # scan order, on its edge)
    r, cc = np.divmod(cap_idx, wp)
    cap_xy = np.column_stack([(cc - 1) * 0.5, (r - 1) * 0.5]).astype(np.float64).reshape(-1, 2)
    return m, np.asarray(cap_band, np.int32), cap_xy, np.asarray(cap_value, np.float64)


def _enclosing(iso: Isolines, xy, m, cap_band, cap_xy, cap_value, n_rows=None, pager=None) -> Hierarchy:
    """The parents of the loops and the caps' enclosing contours, from the loops' geometry
    (the caps' regions labelled first: the region labels and the segment table are not held
    at once). With a ``pager``, the pages of its files go between runs of loops and of rows."""
    c = iso.n_loops
    lev_loop = iso.level.astype(np.int64)
    release = None if pager is None else pager.release
    area = polyline_areas(xy, iso.offsets) if pager is None else _areas_in_runs(xy, iso.offsets, release)
    x, y, offsets, blocks, row_start, row_order, n_rows = segment_table(iso, n_rows, xy, pager)
    # parents: one sweep along every half-pixel row (linear); the rare loop no scanline
    # crosses asks along a ray from the midpoint of one of its segments instead
    table = (x, y, offsets, blocks, row_start, row_order)
    n_runs = threads.available()
    if pager is not None:  # runs of rows of about RELEASE_POINTS segments, threads' runs at a time
        n_runs = max(n_runs, -(-int(row_start[-1]) // RELEASE_POINTS))
    runs = row_runs(row_start, n_rows, n_runs)
    parent, seen = sweep_parents(table, lev_loop, c, runs, release)
    unseen = np.flatnonzero(~seen)
    cand = ranges(offsets[unseen], np.diff(offsets)[unseen])  # the points of the unseen loops
    cand = cand[~iso.border[cand] & (y[cand] != y[successors(cand, offsets)])]
    has_q, first = np.unique(np.searchsorted(offsets, cand, "right") - 1, return_index=True)
    qs = cand[first]
    if qs.size:
        qe = successors(qs, offsets)
        parent[has_q] = innermost_enclosing(
            0.5 * (x[qs] + x[qe]), 0.5 * (y[qs] + y[qe]), has_q.astype(np.int64),
            x, y, offsets, blocks, row_start, row_order, area, lev_loop, n_rows,
        )
    cap_contour = enclosing_rows(cap_xy[:, 0].copy(), cap_xy[:, 1].copy(), table, area, lev_loop, n_rows, runs,
                                 release) if c else np.full(len(cap_xy), -1, np.int64)
    return Hierarchy(
        parent=parent.astype(np.int32),
        n_regions=m,
        cap_band=np.asarray(cap_band, np.int32),
        cap_contour=cap_contour.astype(np.int32),
        cap_xy=cap_xy,
        cap_value=np.asarray(cap_value, np.float64),
    )


def row_runs(row_start: np.ndarray, n_rows: int, n: int) -> list:
    """At most ``n`` runs of rows [k0, k1) covering 0 .. n_rows - 1, with about equal numbers
    of segments (row_start: the segment table's row buckets)."""
    if n <= 1 or n_rows <= 1:
        return [(0, n_rows)]
    total = int(row_start[n_rows])
    cuts = np.searchsorted(row_start[: n_rows + 1], np.arange(1, n) * total / n, "left")
    cuts = np.unique(np.clip(np.concatenate([[0], cuts, [n_rows]]), 0, n_rows))
    return [(int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:]) if b > a]


def sweep_parents(table: tuple, level: np.ndarray, n_loops: int, runs: list, release=None):
    """_kernels/enclose.py sweep_enclosing over the segment ``table`` (x, y, offsets,
    blocks, row_start, row_order), its ``runs`` of rows (row_runs') swept on the threads,
    as many at a time as there are threads (``release``, where given, called after each):
    a loop's parent is the first run's that sees it, each run's first scanline's, so the
    same as one sweep's (each scanline's sweep starts from an empty stack)."""
    parent = seen = None
    for wave in _waves(runs):
        with threads.pool(len(wave)) as pool:
            parts = list(pool.map(lambda r: sweep_enclosing_rows(*table, level, n_loops, *r), wave))
        if release is not None:
            release()
        for p, s in parts:
            if parent is None:
                parent, seen = p, s
                continue
            new = s & ~seen
            parent[new] = p[new]
            seen |= s
        del parts
    return parent, seen


def _waves(runs: list) -> list:
    """The runs, as many at a time as there are threads."""
    n = threads.available()
    return [runs[i : i + n] for i in range(0, len(runs), n)]


def enclosing_rows(px, py, table: tuple, area, level, n_rows: int, runs: list, release=None) -> np.ndarray:
    """_kernels/enclose.py innermost_enclosing_rows of the queries (px, py) (none excluded)
    over the segment ``table`` (sweep_parents'), the queries of each run of rows (row_runs')
    answered on a thread of their own, as many runs at a time as there are threads
    (``release``, where given, called after each): each query's answer is found along its
    own row."""
    out = np.full(px.shape[0], -1, np.int64)
    if len(runs) == 1:
        runs = [(0, n_rows)]
    row = np.clip(np.floor(py * 2.0), 0, n_rows - 1)  # enclose._row_of
    picks = [np.flatnonzero((row >= k0) & (row < k1)) for k0, k1 in runs]

    def run(q):
        return innermost_enclosing_rows(px[q], py[q], np.full(q.shape[0], -1, np.int64), *table, area, level, n_rows)

    for wave in _waves(picks):
        with threads.pool(len(wave)) as pool:
            for q, found in zip(wave, pool.map(run, wave)):
                out[q] = found
        if release is not None:
            release()
    return out


def _areas_in_runs(xy, offsets: np.ndarray, release) -> np.ndarray:
    """geometry/areas.py polyline_areas in runs of loops (loop_runs'), release() after each:
    the running sum carried from run to run, so the same bits."""
    out = np.empty(offsets.shape[0] - 1)
    x, y = xy
    offsets = np.ascontiguousarray(offsets, np.int64)
    total = 0.0
    for i0, i1 in loop_runs(offsets, RELEASE_POINTS):
        total = polyline_areas_range(x, y, offsets, out, i0, i1, total)
        release()
    return out
