"""Marching squares over one strip of rows (kernel): the cells of padded rows [r0, r1) of a
channel's grid, given those rows and a margin (encoder/strips.py joins the strips).

The segments, their links and their per-point data are those of marching.march_loops on
the whole grid, restricted to the strip's cells: a segment's start key, samples, border
flag and crossing depend on its cell and the samples one step beyond (the cubic crossing,
the gradient), which the margin holds. What differs is only that a contour may leave the
strip: linking stops where the next cell lies outside it. The strip's segments then form

* loops: closed in the strip, rotated to start at their smallest start key as march_loops
  does (loops with no isoline segment, wholly on the frame, left out, their levels kept);
* pieces: open polylines from a segment that starts on the strip's top or bottom edge (its
  previous cell lies outside) to one that ends on it, in travel order, not rotated; the
  caller joins them across strips by key (the end key of a piece is the start key of the
  segment that continues it) and rotates each loop they close.

Tested against march_loops on the whole grid (tests/encoder/test_strips.py): the joined
strips give its loops, to the bit, at every strip height.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .marching import _crossing_t, _edge_id, _march_cells_rows, link_rows


@njit(cache=True, nogil=True)
def _grad_win(wv, w0, r, c, hg, wg):
    """marching._grad_at(grid, r, c) with the unpadded grid read from the padded window wv
    (padded rows from w0 on): grid[r, c] = wv[r + 1 - w0, c + 1]."""
    o = 1 - w0
    if r == 0:
        gy = (wv[1 + o, c + 1] - wv[0 + o, c + 1]) / 0.5
    elif r == hg - 1:
        gy = (wv[hg - 1 + o, c + 1] - wv[hg - 2 + o, c + 1]) / 0.5
    else:
        gy = (wv[r + 1 + o, c + 1] - wv[r - 1 + o, c + 1]) / (2.0 * 0.5)
    if c == 0:
        gx = (wv[r + o, 2] - wv[r + o, 1]) / 0.5
    elif c == wg - 1:
        gx = (wv[r + o, wg] - wv[r + o, wg - 1]) / 0.5
    else:
        gx = (wv[r + o, c + 2] - wv[r + o, c]) / (2.0 * 0.5)
    return math.hypot(gx, gy)


@njit(cache=True, nogil=True)
def march_strip(wv, wb, we, w0, hp, r0, r1, levels, min_tol, max_tol):
    """The loops and pieces of the cells of padded rows [r0, r1) (module docstring).

    wv, wb, we : padded values, bands and sample errors of rows [w0, w0 + len) of a grid of
        hp rows; they must hold rows r0 - 1 .. r1 + 1 where the grid has them.
    min_tol, max_tol : the ribbon's clamp (ribbon.tolerances, computed here point by point
        with the same expressions, so no per-point sample errors and gradients are held).
    Returns (ok, n_loops, offsets, level, key, end_key, inner, points, border, below, above,
    tol, skey, frame_levels): chains 0 .. n_loops - 1 are the kept loops in order of their
    smallest start key (key), the rest the pieces (key: the start key of their first segment,
    end_key: the key their last segment ends on); per point, in chain order, what
    march_loops gives with the ribbon's tolerance, and skey, the start key of the segment
    the point starts.
    """
    wp = wv.shape[1]
    hg = hp - 2
    wg = wp - 2
    nl = levels.shape[0]
    n, s_cell, s_lev, s_ea, s_eb, rec, s_t, cell_start = _march_cells_rows(wv, wb, levels, w0, hp, r0, r1)
    # links inside the strip; -2: the next cell lies outside the strip
    nxt, has_pred, ok = link_rows(n, s_cell, s_lev, s_ea, s_eb, cell_start, hp, wp, r0, r1)
    # walk: pieces from the segments nothing leads to, then the loops that remain
    trav = np.empty(n, np.int64)
    ch_start = np.empty(n + 1, np.int64)
    ch_start[0] = 0
    visited = np.zeros(n, np.bool_)
    n_ch = 0
    m = 0
    n_pieces = 0
    if ok:
        for s0 in range(n):
            if has_pred[s0]:
                continue
            j = s0
            while True:
                if visited[j]:
                    ok = False
                    break
                visited[j] = True
                trav[m] = j
                m += 1
                if nxt[j] == -2:
                    break
                j = nxt[j]
            if not ok:
                break
            n_ch += 1
            ch_start[n_ch] = m
        n_pieces = n_ch
    if ok:
        for s0 in range(n):
            if visited[s0]:
                continue
            j = s0
            while not visited[j]:
                visited[j] = True
                trav[m] = j
                m += 1
                j = nxt[j]
                if j < 0:
                    ok = False
                    break
            if not ok or j != s0:
                ok = False
                break
            n_ch += 1
            ch_start[n_ch] = m
    if not ok:
        n_ch = 0
        n_pieces = 0
    n_lp = n_ch - n_pieces
    # per loop: smallest start key and where; whether it has an isoline segment
    lp_key = np.empty(n_lp, np.int64)
    lp_at = np.empty(n_lp, np.int64)
    lp_inner = np.empty(n_lp, np.bool_)
    n_kept = 0
    n_out = 0
    n_frame = 0
    for a in range(n_lp):
        o = ch_start[n_pieces + a]
        length = ch_start[n_pieces + a + 1] - o
        bkey = rec[trav[o], 1]
        at = 0
        inner = False
        for k in range(length):
            j = trav[o + k]
            if rec[j, 1] < bkey:
                bkey = rec[j, 1]
                at = k
            inner = inner or (rec[j, 4] & 1) == 0
        lp_key[a] = bkey
        lp_at[a] = at
        lp_inner[a] = inner
        if inner:
            n_kept += 1
            n_out += length
        else:
            n_frame += 1
    for a in range(n_pieces):
        n_out += ch_start[a + 1] - ch_start[a]
    n_chains = n_kept + n_pieces
    order = np.argsort(lp_key)
    offsets = np.empty(n_chains + 1, np.int64)
    level = np.empty(n_chains, np.int32)
    key = np.empty(n_chains, np.int64)
    end_key = np.full(n_chains, -1, np.int64)
    inner_out = np.ones(n_chains, np.bool_)
    frame_levels = np.empty(n_frame, np.int64)
    points = np.empty((n_out, 2))
    border = np.empty(n_out, np.bool_)
    below = np.empty(n_out, np.int32)  # sample indices: the padded grid of MAX_PIXELS has under 2**31
    above = np.empty(n_out, np.int32)
    tol = np.empty(n_out)
    skey = np.empty(n_out, np.int64)
    wv_f = wv.ravel()
    off = w0 * wp
    offsets[0] = 0
    mo = 0
    ch = 0
    fl = 0
    for q in range(n_lp + n_pieces):
        if q < n_lp:
            lp = order[q]
            if not lp_inner[lp]:
                frame_levels[fl] = s_lev[trav[ch_start[n_pieces + lp]]]
                fl += 1
                continue
            o = ch_start[n_pieces + lp]
            length = ch_start[n_pieces + lp + 1] - o
            at = lp_at[lp]
            key[ch] = lp_key[lp]
        else:
            pc = q - n_lp
            o = ch_start[pc]
            length = ch_start[pc + 1] - o
            at = 0
            key[ch] = rec[trav[o], 1]
            last = trav[o + length - 1]
            cell = s_cell[last]
            rr = cell // (wp - 1)
            end_key[ch] = _edge_id(rr + r0, cell - rr * (wp - 1), s_eb[last], hp, wp) * nl + s_lev[last]
            inner = False
            for k in range(length):
                inner = inner or (rec[trav[o + k], 4] & 1) == 0
            inner_out[ch] = inner
        level[ch] = s_lev[trav[o]]
        for k in range(length):
            src = at + k
            if src >= length:
                src -= length
            j = trav[o + src]
            b = rec[j, 2]
            ab = rec[j, 3]
            rb = b // wp
            cb = b - rb * wp
            ra = ab // wp
            ca = ab - ra * wp
            tt = _crossing_t(wv_f, b - off, ab - off, s_t[j], rb, cb, ra, ca, hp, wp)
            points[mo, 0] = ((cb - 1) + tt * (ca - cb)) * 0.5
            points[mo, 1] = ((rb - 1) + tt * (ra - rb)) * 0.5
            if rb > 0 and cb > 0 and rb < hp - 1 and cb < wp - 1:
                eps_b = we[rb - w0, cb]
                grad_b = _grad_win(wv, w0, rb - 1, cb - 1, hg, wg)
            else:
                eps_b = 0.0
                grad_b = 0.0
            eps_a = we[ra - w0, ca]
            grad_a = _grad_win(wv, w0, ra - 1, ca - 1, hg, wg)
            # ribbon.tolerances, expression for expression
            eps = (1.0 - tt) * eps_b + tt * eps_a
            grad = (1.0 - tt) * grad_b + tt * grad_a
            d = eps / max(grad, 1e-12)
            tol[mo] = min(max(d, min_tol), max_tol)
            below[mo] = b
            above[mo] = ab
            border[mo] = (rec[j, 4] & 1) != 0
            skey[mo] = rec[j, 1]
            mo += 1
        ch += 1
        offsets[ch] = mo
    return (ok, n_kept, offsets, level, key, end_key, inner_out, points, border, below, above,
            tol, skey, frame_levels)
