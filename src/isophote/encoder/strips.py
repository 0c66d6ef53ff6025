"""Isolines strip by strip (issue 22, docs/streaming.md): the channel's grid never exists whole
in the marching's working set.

The Carrato grid of a strip of rows is computed from the plane (mapping.map_rows, the whole
grid's rows to the bit) with a margin of one padded row above and below, and marched
(_kernels/strips.py). Loops that close inside the strip come out rotated and keyed as in one
march of the whole grid; open pieces (their ends on the strip's top or bottom edge) are
carried and joined across strips by key, in strip order: after strip k every open chain has
both ends on strip k's lower edge, and the next strip's pieces that start (end) there
continue (precede) them. A chain that closes is rotated to its smallest start key. The
loops of all strips are put in the order of one march (by that key) at the end, so the
Isolines are the same whatever the strip height (tests/encoder/test_strips.py).

What is held whole: the padded bands (the hierarchy and the joint reaches read them) and the
loops' per-point results (points, tolerances, samples, border flags); the padded values,
which only the hierarchy's caps read, are computed again from the plane when they are
(GridRows: rows of them at a time), not held. A
strip's working set (its window of the grid, the cell table, links, per-point temporaries)
is bounded by its height, which the budget sets (encoder/budget.py: strip_rows).
"""

from __future__ import annotations

from collections import deque
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ._kernels.marching import band_of
from ._kernels.regions import saddle_unions
from ._kernels.strips import march_strip
from .isolines import Isolines, along_of, step_codes
from .looporder import merge_loops
from .mapping import map_rows_into, x_pass_rows, x_rows
from .budget import trim_heap
from .levels import band_dtype
from ..shared.spill import ArrayFile

FIELDS = ("along", "border", "below", "step", "tol")


def grid_window(v, e, levels, opts, w0, w1, hp, wp):
    """Padded values, bands and sample errors of padded rows [w0, w1) (the padding ring is
    value 0, band 0, error 0). The grid's rows are computed in place (mapping.map_rows_into)
    and banded by a kernel: no copies beside the window."""
    wv, we, a, rows = _window(v, e, opts, w0, w1, hp, wp, True)
    wb = np.empty((w1 - w0, wp), np.int16)
    band_of(wv, np.ascontiguousarray(levels, np.float64), wb)  # pad_bands' rule
    wb[:a] = 0
    wb[a + rows :] = 0
    wb[:, 0] = 0
    wb[:, -1] = 0
    return wv, wb, we


def _window(v, e, opts, w0, w1, hp, wp, errors):
    """Padded values (and, with ``errors``, sample errors, from e, a row source of the
    plane's errors: error_source's; else None) of padded rows [w0, w1), the padding ring
    and the rows outside the grid 0; and where the grid's rows lie in them (a, rows). v is
    the plane, or the file it waits in (ArrayFile: its rows read when asked)."""
    g0, g1 = max(w0, 1) - 1, min(w1, hp - 1) - 1
    a = g0 + 1 - w0
    rows = max(g1 - g0, 0)
    wv = np.empty((w1 - w0, wp))
    we = np.empty((w1 - w0, wp)) if errors else None
    h = v.shape[0]
    xr = x_pass_rows(h, g0, g1)
    i0, i1 = x_rows(h, g0, g1) if rows else (0, 0)  # the pixel rows these grid rows read
    v0 = 0
    if callable(v):
        v, v0 = np.ascontiguousarray(v(i0, i1), np.float64), i0
    if errors:  # asked of the errors' row source
        e = np.ascontiguousarray(e(i0, i1), np.float64)
    else:
        e = v  # not read
    args = (v, e, float(opts.carrato_p), float(opts.carrato_scale), float(opts.carrato_cubic), g0, g1,
            wv[a : a + rows, 1:-1])
    if errors:  # errors left at its default: numba compiles the flag in, the march's loops stay lean
        map_rows_into(*args, we[a : a + rows, 1:-1], np.empty((xr, wp - 2)), np.empty((xr, wp - 2)), e0=i0,
                      v0=v0, h=h)
    else:
        unused = np.empty((1, wp - 2))  # the errors' arrays, not written
        map_rows_into(*args, unused, np.empty((xr, wp - 2)), unused, False, v0=v0, h=h)
    for z in (wv, we) if errors else (wv,):
        z[:a] = 0.0
        z[a + rows :] = 0.0
        z[:, 0] = 0.0
        z[:, -1] = 0.0
    return wv, we, a, rows


class GridRows:
    """The padded value grid of a channel, row by row, computed again from its plane when
    asked (rows(w0, w1): padded rows [w0, w1), the padding ring 0; the same bits as the
    march's windows; the values alone, not their errors): the hierarchy's caps read the
    values once (_kernels/regions.py value_sums_rows; the joins of regions that the values
    decide are recorded by the march, saddle_unions), and holding them whole was 8 bytes a
    sample, 32 a pixel, at the march's peak (issue 22). Holds the plane (8 bytes a pixel),
    or, once spilled, reads the rows it needs from a temporary file."""

    def __init__(self, v, opts, hp, wp):
        self.v, self.opts, self.hp, self.wp = v, opts, hp, wp  # the errors are not needed

    def __call__(self, w0: int, w1: int) -> np.ndarray:
        return _window(self.v, None, self.opts, w0, w1, self.hp, self.wp, False)[0]

    def spill(self) -> bool:
        """Move the plane to a temporary file (shared/spill.py ArrayFile), read back a few rows at a time
        when the caps ask: between the march and the caps (the joint moves, the fit, the
        regions' labels) it is not read. False, and the plane kept, where no temporary
        file can be written."""
        if callable(self.v):
            return True
        try:
            self.v = ArrayFile(self.v)
        except OSError:
            return False
        return True


def error_source(eps, shape):
    """A row source (rows(a, b): pixel rows [a, b)) of a plane's sample errors ``eps``: a
    float, an (H, W) array, or already a row source (noise.ErrorRows, which computes each
    strip's rows when asked: the per-pixel errors are not held whole through the march)."""
    if callable(eps):
        return eps
    e = np.asarray(eps, np.float64)
    if e.ndim == 0:
        value = float(e)
        return lambda a, b: np.full((max(b - a, 0), shape[1]), value)
    e = np.ascontiguousarray(np.broadcast_to(e, shape))
    return lambda a, b: e[a:b]


class _Chain:
    """An open polyline carried between strips: its first segment's start key, the key its
    last segment ends on, its level, whether it has an isoline segment, and its pieces'
    per-point arrays in order."""

    __slots__ = ("start", "end", "level", "inner", "frags")

    def __init__(self, start, end, level, inner, frags):
        self.start, self.end, self.level, self.inner, self.frags = start, end, level, inner, frags


def _march(v, e, levels, opts, hp, wp, r0, r1, band):
    """One strip (``levels`` contiguous float64): its rows of the grid's bands go into
    ``band`` (strips' rows are disjoint); returns its loops (a part for merge_loops), its
    pieces, its frame loops' levels and its cells' saddle unions (_kernels/regions.py
    saddle_unions)."""
    w0, w1 = max(r0 - 1, 0), min(r1 + 2, hp)
    wv, wb, we = grid_window(v, e, levels, opts, w0, w1, hp, wp)
    (ok, n_kept, offsets, level, key, end_key, inner, points, border, below, above, tol, skey,
     frame_levels) = march_strip(wv, wb, we, w0, hp, r0, r1, levels, float(opts.min_tolerance),
                                 float(opts.max_tolerance))
    del we
    if not ok:
        raise RuntimeError("marching squares produced an open contour")  # a bug, never input
    m = int(offsets[n_kept])
    step = step_codes(below, above, wp)  # a byte a point rather than the above sample's 4
    along = along_of(points, step)  # 8 bytes a point rather than 16 (isolines.py)
    del above, points
    # the loops' points are held until the merge: copies of their part alone, so that the
    # kernel's arrays (which also hold the pieces' points, copied below) go with the strip
    loops = dict(along=along[:m].copy(), border=border[:m].copy(), below=below[:m].copy(),
                 step=step[:m].copy(), tol=tol[:m].copy(),
                 level=level[:n_kept], offsets=offsets[: n_kept + 1], keys=key[:n_kept])
    pieces = []
    for i in range(n_kept, level.shape[0]):
        o0, o1 = int(offsets[i]), int(offsets[i + 1])
        frag = dict(along=along[o0:o1].copy(), border=border[o0:o1].copy(), below=below[o0:o1].copy(),
                    step=step[o0:o1].copy(), tol=tol[o0:o1].copy(), skey=skey[o0:o1].copy())
        pieces.append(_Chain(int(key[i]), int(end_key[i]), int(level[i]), bool(inner[i]), [frag]))
    ra, rb = r0, (r1 + 1 if r1 == hp - 1 else r1)
    band[ra:rb] = wb[ra - w0 : rb - w0]
    # the regions' diagonal joins that the values decide, while the values are at hand
    saddles = saddle_unions(wv, wb, w0, hp, r0, r1, levels)
    return loops, pieces, frame_levels, saddles


def _join(carried: dict, pieces: list, closed: list, frame: list) -> dict:
    """The carried chains (by start key) continued by one strip's pieces: the chains still
    open (by start key); the loops they close go to ``closed`` as (key, level, fields),
    frame loops' levels to ``frame``."""
    nodes = list(carried.values()) + pieces
    by_start = {c.start: c for c in nodes}
    succ = {id(c): by_start.get(c.end) for c in nodes}
    has_pred = {id(s) for s in succ.values() if s is not None}
    done = set()
    out = {}
    for c in nodes:
        if id(c) in has_pred:
            continue
        path = [c]
        done.add(id(c))
        while succ[id(path[-1])] is not None:
            path.append(succ[id(path[-1])])
            done.add(id(path[-1]))
        out[c.start] = _Chain(c.start, path[-1].end, c.level, any(p.inner for p in path),
                              [f for p in path for f in p.frags])
    for c in nodes:
        if id(c) in done:
            continue
        path = [c]
        done.add(id(c))
        x = succ[id(c)]
        while x is not c:
            if x is None or id(x) in done:
                raise RuntimeError("marching squares produced an open contour")  # a bug
            path.append(x)
            done.add(id(x))
            x = succ[id(x)]
        if not any(p.inner for p in path):
            frame.append(c.level)
            continue
        frags = [f for p in path for f in p.frags]
        skey = np.concatenate([f["skey"] for f in frags])
        at = int(np.argmin(skey))
        fields = {}
        for name in FIELDS:
            a = np.concatenate([f[name] for f in frags])
            fields[name] = np.roll(a, -at, axis=0) if at else a
        closed.append((int(skey[at]), c.level, fields))
    return out


def _closed_part(closed: list) -> dict | None:
    """The loops joined in one strip as a part for merge_loops."""
    if not closed:
        return None
    lengths = np.array([f["tol"].shape[0] for _, _, f in closed], np.int64)
    part = {name: np.concatenate([f[name] for _, _, f in closed]) for name in FIELDS}
    part["level"] = np.array([lv for _, lv, _ in closed], np.int32)
    part["offsets"] = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    part["keys"] = np.array([k for k, _, _ in closed], np.int64)
    return part


def _paged(part: dict, pager) -> dict:
    """A part's per-point arrays moved to the pager's files (none: as they are)."""
    if pager is not None:
        for name in FIELDS:
            part[name] = pager.put(part[name])
    return part


def strip_isolines(plane, eps, levels, opts, rows: int, workers: int = 1, pager=None) -> Isolines:
    """The isolines of the channel ``plane`` (its sample errors ``eps``: a float, a plane or
    a row source of one, error_source),
    marched in strips of ``rows`` cell rows of the padded grid, ``workers`` strips at a
    time: the Isolines of encoder.isolines.find_isolines on map_pixels' grid, to the bit.
    With a ``pager`` (shared/spill.py Pager), each strip's loops wait on its files until
    the merge, and the loops' per-point arrays are made there (the same values)."""
    levels = np.ascontiguousarray(levels, np.float64)
    v = np.ascontiguousarray(plane, np.float64)
    e = error_source(eps, v.shape)
    h, w = v.shape
    hp, wp = 2 * h + 3, 2 * w + 3
    rows = max(int(rows), 1)
    band = np.zeros((hp, wp), band_dtype(levels.shape[0]))  # the windows' are int16
    bounds = [(r0, min(r0 + rows, hp - 1)) for r0 in range(0, hp - 1, rows)]
    parts, frame, carried, saddles = [], [], {}, []
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        pending = deque()
        todo = iter(bounds)
        for _ in range(max(1, workers)):
            b = next(todo, None)
            if b is not None:
                pending.append(pool.submit(_march, v, e, levels, opts, hp, wp, *b, band))
        while pending:
            loops, pieces, frame_levels, strip_saddles = pending.popleft().result()
            saddles.append(strip_saddles)
            b = next(todo, None)
            if b is not None:
                pending.append(pool.submit(_march, v, e, levels, opts, hp, wp, *b, band))
            frame.extend(frame_levels.tolist())
            if loops["level"].shape[0]:
                parts.append(_paged(loops, pager))
            closed = []
            carried = _join(carried, pieces, closed, frame)
            part = _closed_part(closed)
            if part is not None:
                parts.append(_paged(part, pager))
            del loops, pieces, closed, part
            trim_heap()  # the strip's freed results go back (encoder/budget.py)
    if carried:
        raise RuntimeError("marching squares produced an open contour")  # a bug, never input
    frame_levels = np.array(sorted(frame), np.int64)
    base = frame_levels.shape[0]
    if base and not np.array_equal(frame_levels, np.arange(base)):
        raise RuntimeError("frame loops are not the lowest levels")  # a bug, never input
    if not parts:
        merged = dict(along=np.zeros(0), border=np.zeros(0, bool), below=np.zeros(0, np.int32),
                      step=np.zeros(0, np.int8), tol=np.zeros(0), level=np.zeros(0, np.int32),
                      offsets=np.zeros(1, np.int64))
    else:
        merged = merge_loops(parts, pager)
    return Isolines(band=band, values=GridRows(v, opts, hp, wp), base_band=base,
                    saddles=np.concatenate(saddles) if saddles else np.zeros((0, 2), np.int64), **merged)
