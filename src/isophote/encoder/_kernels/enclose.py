"""Innermost enclosing loop of test points, by winding numbers along a leftward ray.

Loops never cross, so a loop encloses a point exactly when its winding number there is
non-zero; among the loops that enclose it, the innermost has the smallest |area| (ties, which
only coincident border loops produce, go to the higher level, which lies inside).
Segments are bucketed by the row of the mapped grid (half-pixel rows) they lie in, so each
query looks only at the segments of its own row.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _row_of(y, n_rows):
    """The half-pixel row (y in [k/2, (k+1)/2]) a query at height y looks along, clamped."""
    return min(max(int(np.floor(y * 2.0)), 0), n_rows - 1)


# A segment's loop is found from the loops' offsets and a block index (the loop of every
# 2**LOOP_BLOCK_SHIFT-th point: loop_blocks) by stepping forward from its block's loop: loops
# average 35 points on textured photographs, so a step or two; 4 bytes a point less than a
# loop id a point (217 MiB of the 16 MP mosaic's luma, at the hierarchy's peak).
LOOP_BLOCK_SHIFT = 6


def loop_blocks(offsets: np.ndarray) -> np.ndarray:
    """The loop of points 0, 2**LOOP_BLOCK_SHIFT, 2 * 2**LOOP_BLOCK_SHIFT, ... (int32) of the
    loops ``offsets`` (loop i is points offsets[i] .. offsets[i + 1] - 1)."""
    n = int(offsets[-1])
    at = np.arange(0, n, 1 << LOOP_BLOCK_SHIFT, dtype=np.int64)
    return (np.searchsorted(offsets, at, "right") - 1).astype(np.int32)


@njit(cache=True, nogil=True, inline="always")
def _loop_of(s, offsets, blocks):
    """The loop of point s (loop_blocks' index, then forward)."""
    lp = blocks[s >> LOOP_BLOCK_SHIFT]
    while offsets[lp + 1] <= s:
        lp += 1
    return lp


@njit(cache=True, nogil=True, inline="always")
def _succ(s, lp, offsets):
    """The point segment s (of loop lp) runs to: the next of its loop, or the loop's first
    after its last (loops are contiguous runs of points; no array a point is held for it)."""
    if s + 1 < offsets[lp + 1]:
        return s + 1
    return offsets[lp]


@njit(cache=True, nogil=True)
def innermost_enclosing(px, py, exclude, x, y, offsets, blocks, row_start, row_order,
                        area, level, n_rows):
    """For each query point (px[q], py[q]) the innermost loop enclosing it, -1 if none.

    Segment s runs from point s, (x[s], y[s]), to the next point of its loop (the loop's
    first after its last: _succ; loop i is points offsets[i] .. offsets[i + 1] - 1, blocks:
    loop_blocks(offsets)); the segments of row k
    (y in [k/2, (k+1)/2]) are row_order[row_start[k]:row_start[k+1]].
    exclude[q] is a loop id the query ignores (its own loop) or -1.
    """
    nq = px.shape[0]
    nloops = area.shape[0]
    wind = np.zeros(nloops, np.int32)  # per-loop scratch int32: 12 bytes a loop
    touched = np.empty(nloops, np.int32)
    stamp = np.full(nloops, -1, np.int64)  # query that last listed the loop in `touched`
    out = np.full(nq, -1, np.int64)
    for q in range(nq):
        k = _row_of(py[q], n_rows)
        nt = 0
        for a in range(row_start[k], row_start[k + 1]):
            s = row_order[a]
            lp = _loop_of(s, offsets, blocks)
            if lp == exclude[q]:
                continue
            e = _succ(s, lp, offsets)
            ya = y[s]
            yb = y[e]
            if ya == yb:
                continue
            if (ya <= py[q] < yb) or (yb <= py[q] < ya):
                xc = x[s] + (py[q] - ya) * (x[e] - x[s]) / (yb - ya)
                if xc < px[q]:
                    # list each loop once per query, however often its winding returns to 0
                    if stamp[lp] != q:
                        stamp[lp] = q
                        touched[nt] = lp
                        nt += 1
                    wind[lp] += 1 if yb > ya else -1
        best = -1
        for i in range(nt):
            lp = touched[i]
            if wind[lp] != 0:
                if best < 0:
                    best = lp
                else:
                    ab = abs(area[best])
                    al = abs(area[lp])
                    if al < ab or (al == ab and level[lp] > level[best]):
                        best = lp
            wind[lp] = 0
        out[q] = best
    return out


SWEEP_NUDGE = 2.0**-21  # scanlines sit this far below the sample rows (see _kernels/raster.py)


@njit(cache=True, nogil=True)
def _row_crossings(x, y, offsets, blocks, row_start, row_order, k, yl):
    """The crossings of bucket k's segments with the line yl (half-open in y): per crossing
    its x, loop, direction (+1 down) and place in row_order; returns (xs, ls, ds, ps, n)."""
    a0 = row_start[k]
    a1 = row_start[k + 1]
    xs = np.empty(a1 - a0)
    ls = np.empty(a1 - a0, np.int64)
    ds = np.empty(a1 - a0, np.int64)
    ps = np.empty(a1 - a0, np.int64)
    n = 0
    for a in range(a0, a1):
        s = row_order[a]
        lp = _loop_of(s, offsets, blocks)
        e = _succ(s, lp, offsets)
        ya = y[s]
        yb = y[e]
        if (ya <= yl < yb) or (yb <= yl < ya):
            xs[n] = x[s] + (yl - ya) * (x[e] - x[s]) / (yb - ya)
            ls[n] = lp
            ds[n] = 1 if yb > ya else -1
            ps[n] = a
            n += 1
    return xs, ls, ds, ps, n


@njit(cache=True, nogil=True)
def sweep_enclosing(x, y, offsets, blocks, row_start, row_order, level, n_loops, n_rows):
    """Parents of all loops, in one left-to-right sweep per half-pixel row (linear in the
    number of crossings).

    Along the scanline y = k/2 + SWEEP_NUDGE the crossings of non-crossing loops nest like
    parentheses: a loop is entered at its first crossing and left at its next, and what is
    open when it is entered is its parent. Crossings at the same x (loops sharing a stretch
    of border) leave before they enter, and enter outer (lower) levels first.
    Returns (parent (n_loops,), seen (n_loops,) bool); a loop no scanline crosses has seen
    False.
    """
    return sweep_enclosing_rows(x, y, offsets, blocks, row_start, row_order, level, n_loops, 0, n_rows)


@njit(cache=True, nogil=True)
def sweep_enclosing_rows(x, y, offsets, blocks, row_start, row_order, level, n_loops, k0, k1):
    """:func:`sweep_enclosing` over the rows k0 .. k1 - 1 alone: each row's sweep starts from
    an empty stack, so a loop's parent is the one its first scanline in the range gives,
    and runs of rows can be swept apart (hierarchy.sweep_parents: the first run that sees a
    loop gives its parent, as one sweep would)."""
    parent = np.full(n_loops, -1, np.int64)
    seen = np.zeros(n_loops, np.bool_)
    stack = np.empty(n_loops + 1, np.int64)
    on_stack = np.zeros(n_loops, np.bool_)
    for k in range(k0, k1):
        yc = 0.5 * k + SWEEP_NUDGE
        xs, ls, _, _, n = _row_crossings(x, y, offsets, blocks, row_start, row_order, k, yc)
        order = np.argsort(xs[:n], kind="mergesort")
        sp = 0
        i = 0
        while i < n:
            xnext = xs[order[i]]
            j = i
            while j < n and xs[order[j]] == xnext:
                j += 1
            # leave: the group's loops that are open, innermost first
            changed = True
            while changed:
                changed = False
                for g in range(i, j):
                    lp = ls[order[g]]
                    if sp > 0 and stack[sp - 1] == lp and on_stack[lp]:
                        sp -= 1
                        on_stack[lp] = False
                        ls[order[g]] = -1
                        changed = True
            # enter: the rest, lower levels first
            while True:
                best = -1
                for g in range(i, j):
                    lp = ls[order[g]]
                    if lp >= 0 and (best < 0 or level[lp] < level[ls[order[best]]]):
                        best = g
                if best < 0:
                    break
                lp = ls[order[best]]
                ls[order[best]] = -1
                if not seen[lp]:
                    seen[lp] = True
                    parent[lp] = stack[sp - 1] if sp > 0 else -1
                stack[sp] = lp
                sp += 1
                on_stack[lp] = True
            i = j
        for g in range(sp):
            on_stack[stack[g]] = False
    return parent, seen


@njit(cache=True, nogil=True)
def innermost_enclosing_rows(px, py, exclude, x, y, offsets, blocks, row_start, row_order,
                             area, level, n_rows):
    """:func:`innermost_enclosing` (same arguments, same answers) for many queries per row.

    Queries of one row and one y share one pass: the row's crossings of the line y are
    sorted by x once and swept left to right, the queries in order of x, keeping the
    winding number of every loop crossed so far and the set of loops where it is non-zero.
    Among those (the loops enclosing the query), the innermost is chosen as the ray query
    does: smallest |area|, then higher level, then the loop whose first crossing comes
    first in the row's segment order.
    """
    nq = px.shape[0]
    nloops = area.shape[0]
    out = np.full(nq, -1, np.int64)
    if nq == 0:
        return out
    kq = np.empty(nq, np.int64)
    for q in range(nq):
        kq[q] = _row_of(py[q], n_rows)
    # queries by row, then y, then x
    o = np.argsort(px, kind="mergesort")
    o = o[np.argsort(py[o], kind="mergesort")]
    o = o[np.argsort(kq[o], kind="mergesort")]
    # per-loop scratch, int32 (20 bytes a loop; row_order's places are int32 too)
    wind = np.zeros(nloops, np.int32)
    first = np.full(nloops, np.iinfo(np.int32).max, np.int32)
    where = np.full(nloops, -1, np.int32)
    members = np.empty(nloops, np.int32)
    touched = np.empty(nloops, np.int32)
    g0 = 0
    while g0 < nq:
        k = kq[o[g0]]
        yq = py[o[g0]]
        g1 = g0
        while g1 < nq and kq[o[g1]] == k and py[o[g1]] == yq:
            g1 += 1
        xs, ls, ds, ps, nc = _row_crossings(x, y, offsets, blocks, row_start, row_order, k, yq)
        order = np.argsort(xs[:nc])
        nm = 0
        nt = 0
        p = 0
        for g in range(g0, g1):
            q = o[g]
            while p < nc and xs[order[p]] < px[q]:
                c = order[p]
                lp = ls[c]
                if first[lp] == np.iinfo(np.int32).max:
                    touched[nt] = lp
                    nt += 1
                if ps[c] < first[lp]:
                    first[lp] = ps[c]
                wind[lp] += ds[c]
                if wind[lp] != 0 and where[lp] < 0:
                    where[lp] = nm
                    members[nm] = lp
                    nm += 1
                elif wind[lp] == 0 and where[lp] >= 0:
                    last = members[nm - 1]
                    members[where[lp]] = last
                    where[last] = where[lp]
                    where[lp] = -1
                    nm -= 1
                p += 1
            best = -1
            for i in range(nm):
                lp = members[i]
                if lp == exclude[q]:
                    continue
                if best < 0:
                    best = lp
                else:
                    ab = abs(area[best])
                    al = abs(area[lp])
                    if al < ab or (al == ab and (level[lp] > level[best]
                                                 or (level[lp] == level[best] and first[lp] < first[best]))):
                        best = lp
            out[q] = best
        for i in range(nt):
            lp = touched[i]
            wind[lp] = 0
            first[lp] = np.iinfo(np.int32).max
            where[lp] = -1
        g0 = g1
    return out


@njit(cache=True, nogil=True)
def bucket_rows(row, n_rows):
    """Counting sort of row indices in [0, n_rows): (row_start (n_rows + 1,) int64, row_order int32), equal
    to np.argsort(row, kind="stable") and np.searchsorted(row[row_order], arange(n_rows + 1))."""
    row_start = np.zeros(n_rows + 1, np.int64)
    count_rows(row, row_start)
    for k in range(n_rows):
        row_start[k + 1] += row_start[k]
    row_order = np.empty(row.shape[0], np.int32)  # segment indices: a channel's are far below 2**31
    place_rows(row, 0, row_start[:-1].copy(), row_order)
    return row_start, row_order


@njit(cache=True, nogil=True)
def count_rows(row, counts):
    """counts[k + 1] += the number of k in ``row`` (bucket_rows' first pass, a run of rows
    at a time)."""
    for s in range(row.shape[0]):
        counts[row[s] + 1] += 1


@njit(cache=True, nogil=True)
def place_rows(row, base, fill, row_order):
    """bucket_rows' second pass over a run of rows, of segments base, base + 1, ...: each
    goes to the next free place of its row's bucket (fill, advanced)."""
    for s in range(row.shape[0]):
        row_order[fill[row[s]]] = base + s
        fill[row[s]] += 1
