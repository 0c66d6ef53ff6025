"""Isolines level group by level group, so that marching holds one group's segments at a time.

The encoder marches strips of rows instead (encoder/strips.py), which bound the same working
set and the grid with it; it uses :func:`merge_groups` to put the strips' loops in order.

The loops of one level depend on that level alone (its crossings, its saddle decisions:
_kernels/marching.py), so marching a channel's levels in groups gives exactly the loops of
one march over all of them. A group [a, b) is marched on the band grid clipped to [a, b]
and shifted by a: a sample is above the group's level l' exactly when it is above level
a + l' of the channel. The loops of all groups are then put in the one march's order, by
their smallest start key (edge id x levels + level), which is the key of each loop's first
segment (loops start there) and is read back from its start crossing's grid edge.

Groups are cut so that each holds at most ``max_segments`` segments, counted beforehand
from the grid edges each level crosses (one segment starts at every crossing). What a
channel holds at its peak is then the padded grid and the per-point results of the groups
so far (41 bytes a point: points, border flag, samples, tolerance), not the 300-odd bytes a
segment of the whole march's working set (encoder/budget.py).
"""

from __future__ import annotations

import numpy as np

from ._kernels.marching import march_loops
from .isolines import Isolines, pad_grid
from .mapping import map_pixels
from .ribbon import tolerances

ROWS_PER_COUNT = 256  # grid rows counted at a time (bounds the counting's temporaries)


def crossings_per_level(band: np.ndarray, n_levels: int) -> np.ndarray:
    """(L,) int64: how many grid edges of the padded band grid each level crosses."""
    diff = np.zeros(n_levels + 1, np.int64)
    hp = band.shape[0]
    for r0 in range(0, hp, ROWS_PER_COUNT):
        blk = band[r0 : min(r0 + ROWS_PER_COUNT + 1, hp)]
        pairs = [(blk[:, :-1], blk[:, 1:])]
        if blk.shape[0] > 1:
            pairs.append((blk[:-1], blk[1:]))
        for a, b in pairs:
            diff += np.bincount(np.minimum(a, b).ravel(), minlength=n_levels + 1)
            diff -= np.bincount(np.maximum(a, b).ravel(), minlength=n_levels + 1)
    return np.cumsum(diff)[:n_levels]


def level_groups(per_level: np.ndarray, max_segments: int) -> list[tuple[int, int]]:
    """Consecutive level ranges [a, b), each of at most max_segments crossings (or one level)."""
    groups, a, total = [], 0, 0
    for l, n in enumerate(per_level.tolist()):
        if l > a and total + n > max_segments:
            groups.append((a, l))
            a, total = l, 0
        total += n
    if len(per_level):
        groups.append((a, len(per_level)))
    return groups


def loop_keys(below, above, offsets, level, hp, wp, n_levels):
    """Each loop's smallest start key (marching.py's edge id x levels + level), from the grid
    edge of its first point's crossing (the loop starts at that segment)."""
    first = offsets[:-1]
    b, a = below[first], above[first]
    lo = np.minimum(a, b)
    edge = np.where(np.abs(a - b) == 1, lo, hp * wp + lo)
    return edge * n_levels + level.astype(np.int64)


def find_isolines_grouped(grid, grid_eps, levels, min_tol=0.05, max_tol=0.5,
                          max_segments=None) -> Isolines:
    """encoder.isolines.find_isolines, marched in level groups of at most ``max_segments``
    segments (None: one group). The same Isolines whatever the grouping."""
    levels = np.ascontiguousarray(levels, np.float64)
    vals, band = pad_grid(grid, levels)
    return march_groups(vals, band, grid_eps, levels, min_tol, max_tol, max_segments)


def plane_isolines(plane, eps, levels, opts, max_segments=None) -> Isolines:
    """map_pixels and find_isolines_grouped, holding the mapped grid only through its
    padded copy (the grid is the padded values' interior, 32 bytes a grid sample less)."""
    levels = np.ascontiguousarray(levels, np.float64)
    grid, grid_eps = map_pixels(plane, eps, opts.carrato_p, opts.carrato_scale, opts.carrato_cubic)
    vals, band = pad_grid(grid, levels)
    del grid
    held = [grid_eps]  # handed over: march_groups drops the last reference once marched
    del grid_eps
    return march_groups(vals, band, held, levels, opts.min_tolerance, opts.max_tolerance, max_segments)


def march_groups(vals, band, grid_eps, levels, min_tol, max_tol, max_segments) -> Isolines:
    """The isolines of padded values and bands, level group by level group (grid_eps: the
    grid's sample errors, or a one-element list holding them, emptied here)."""
    nl = levels.shape[0]
    inner = vals[1:-1, 1:-1]
    if isinstance(grid_eps, list):
        grid_eps = grid_eps.pop()
    grid_eps = np.ascontiguousarray(np.broadcast_to(grid_eps, inner.shape), np.float64)
    hp, wp = vals.shape
    if max_segments is None or nl == 0:
        groups = [(0, nl)]
    else:
        groups = level_groups(crossings_per_level(band, nl), max_segments)
    parts, frame = [], []
    scratch = np.empty_like(band) if len(groups) > 1 else None  # one group's bands at a time
    for a, b in groups:
        if scratch is None:
            sub = band
        else:
            sub = np.clip(band, a, b, out=scratch)
            sub -= np.int16(a)
        (ok, points, border, below, above, t, eps_b, eps_a, grad_b, grad_a, level, offsets,
         frame_levels) = march_loops(vals, sub, levels[a:b], inner, grid_eps)
        if not ok:
            raise RuntimeError("marching squares produced an open contour")  # a bug, never input
        tol = tolerances(eps_b, eps_a, grad_b, grad_a, t, min_tol, max_tol)
        del t, eps_b, eps_a, grad_b, grad_a
        level = (level + a).astype(np.int32)
        frame.append(frame_levels + a)
        parts.append(dict(points=points, border=border, below=below, above=above, tol=tol,
                          level=level, offsets=offsets))
    del grid_eps, scratch, sub
    frame_levels = np.concatenate(frame) if frame else np.zeros(0, np.int64)
    base = frame_levels.shape[0]
    if base and not np.array_equal(np.sort(frame_levels), np.arange(base)):
        raise RuntimeError("frame loops are not the lowest levels")  # a bug, never input
    merged = parts[0] if len(parts) == 1 else merge_groups(parts, hp, wp, nl)
    return Isolines(band=band, values=vals, base_band=base, **merged)


def merge_groups(parts, hp, wp, nl) -> dict:
    """The loops of all groups (or strips: a part may bring its loops' keys, "keys") in order
    of their smallest start key, field by field: each
    group's points are scattered to their places in the output and dropped, so the merge
    holds the groups' results, one output field and one group's destinations at a time."""
    keys = np.concatenate([p.pop("keys") if "keys" in p else
                           loop_keys(p["below"], p["above"], p["offsets"], p["level"], hp, wp, nl)
                           for p in parts])
    order = np.argsort(keys, kind="stable")
    del keys
    lengths = np.concatenate([np.diff(p["offsets"]) for p in parts])
    rank = np.empty_like(order)
    rank[order] = np.arange(order.shape[0])  # each loop's place in the output
    offsets = np.zeros(order.shape[0] + 1, np.int64)
    np.cumsum(lengths[order], out=offsets[1:])
    out = {"offsets": offsets, "level": np.concatenate([p["level"] for p in parts])[order]}
    n_out = int(offsets[-1])
    first = np.cumsum([0] + [p["offsets"].shape[0] - 1 for p in parts])
    for name in ("points", "tol", "below", "above", "border"):
        sample = parts[0][name]
        dest = np.empty((n_out,) + sample.shape[1:], sample.dtype)
        for k, p in enumerate(parts):
            loops = slice(first[k], first[k + 1])
            n = lengths[loops]
            at = np.repeat(offsets[:-1][rank[loops]] - p["offsets"][:-1], n) + np.arange(int(p["offsets"][-1]))
            dest[at] = p.pop(name)
            del at
        out[name] = dest
    return out
