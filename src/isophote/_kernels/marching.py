"""Marching squares over all levels of a channel in one scan (kernel + NumPy twin).

Input is a padded grid: the outer ring (row 0, last row, column 0, last column) is padding
that lies below every level (band 0), so every contour closes; segments in cells that touch
the padding run exactly along the image border and are flagged as border.

Cell corners: 0 = top-left (r, c), 1 = top-right (r, c+1), 2 = bottom-right (r+1, c+1),
3 = bottom-left (r+1, c). Edge k joins corner k and corner (k+1) % 4.
A segment from a crossing on edge ea to one on edge eb has corners ea+1 .. eb (cyclically)
on its left as seen on screen (y down); segments are oriented so that the corners at or
above the level are on the left.

Saddles: the asymptotic decider. The bilinear interpolant's value at its saddle point is
s = (a c - b d) / (a + c - b - d) for corners a, b, c, d = 0, 1, 2, 3. If s >= level the
centre is above and the below corners are cut off singly; otherwise the above corners are.

Per segment the kernel reports: start and end keys (edge id * n_levels + level; a crossing
is shared by the two cells of its edge, so keys link segments into loops), the level, the
border flag, and the start crossing as (below sample, above sample, t): the point lies at
t of the way from the below sample to the above sample (t = 1 when the below one is padding).
"""

from __future__ import annotations

import numpy as np
from numba import njit

# corner offsets (dr, dc) and edge -> (corner a, corner b)
_CDR = np.array([0, 0, 1, 1], np.int64)
_CDC = np.array([0, 1, 1, 0], np.int64)


@njit(cache=True, nogil=True)
def _edge_id(r, c, k, hp, wp):
    # horizontal edges: id = r * wp + c for (r, c)-(r, c+1); vertical: hp*wp + r*wp + c for (r, c)-(r+1, c)
    if k == 0:
        return r * wp + c
    if k == 1:
        return hp * wp + r * wp + (c + 1)
    if k == 2:
        return (r + 1) * wp + c
    return hp * wp + r * wp + c


@njit(cache=True, nogil=True)
def _march(vals, band, levels, fill, skey, ekey, lev, border, s_below, s_above, s_t):
    hp, wp = vals.shape
    nl = levels.shape[0]
    n = 0
    cv = np.empty(4, np.float64)
    cb = np.empty(4, np.int64)
    cidx = np.empty(4, np.int64)
    cpad = np.empty(4, np.bool_)
    above = np.empty(4, np.bool_)
    cross = np.empty(4, np.int64)
    segs_a = np.empty(2, np.int64)
    segs_b = np.empty(2, np.int64)
    for r in range(hp - 1):
        for c in range(wp - 1):
            bmin = 1 << 30
            bmax = -1
            anypad = False
            for k in range(4):
                rr = r + _CDR[k]
                cc = c + _CDC[k]
                cv[k] = vals[rr, cc]
                cb[k] = band[rr, cc]
                cidx[k] = rr * wp + cc
                cpad[k] = rr == 0 or cc == 0 or rr == hp - 1 or cc == wp - 1
                anypad = anypad or cpad[k]
                if cb[k] < bmin:
                    bmin = cb[k]
                if cb[k] > bmax:
                    bmax = cb[k]
            for l in range(bmin, bmax):
                L = levels[l]
                for k in range(4):
                    above[k] = cb[k] > l
                nc = 0
                for k in range(4):
                    if above[k] != above[(k + 1) % 4]:
                        cross[nc] = k
                        nc += 1
                ns = 0
                if nc == 2:
                    ea = cross[0]
                    eb = cross[1]
                    if above[(ea + 1) % 4]:
                        segs_a[0] = ea
                        segs_b[0] = eb
                    else:
                        segs_a[0] = eb
                        segs_b[0] = ea
                    ns = 1
                else:
                    # saddle: above corners are {0, 2} or {1, 3}
                    den = cv[0] + cv[2] - cv[1] - cv[3]
                    s = (cv[0] * cv[2] - cv[1] * cv[3]) / den
                    centre_above = s >= L
                    for k in range(4):
                        if above[k] != centre_above:
                            # cut off corner k, between edges k-1 and k
                            ep = (k + 3) % 4
                            if above[k]:
                                segs_a[ns] = ep
                                segs_b[ns] = k
                            else:
                                segs_a[ns] = k
                                segs_b[ns] = ep
                            ns += 1
                for q in range(ns):
                    if fill:
                        ea = segs_a[q]
                        eb = segs_b[q]
                        skey[n] = _edge_id(r, c, ea, hp, wp) * nl + l
                        ekey[n] = _edge_id(r, c, eb, hp, wp) * nl + l
                        lev[n] = l
                        border[n] = anypad
                        ka = ea
                        kb = (ea + 1) % 4
                        if above[ka]:
                            ka, kb = kb, ka
                        s_below[n] = cidx[ka]
                        s_above[n] = cidx[kb]
                        if cpad[ka]:
                            s_t[n] = 1.0
                        else:
                            s_t[n] = (L - cv[ka]) / (cv[kb] - cv[ka])
                    n += 1
    return n


def march(vals, band, levels):
    """Run the kernel: returns a dict of per-segment arrays (see module docstring)."""
    vals = np.ascontiguousarray(vals, np.float64)
    band = np.ascontiguousarray(band, np.int64)
    levels = np.ascontiguousarray(levels, np.float64)
    e64 = np.zeros(0, np.int64)
    n = _march(vals, band, levels, False, e64, e64, np.zeros(0, np.int32), np.zeros(0, np.bool_), e64, e64, np.zeros(0))
    out = dict(
        skey=np.empty(n, np.int64), ekey=np.empty(n, np.int64), level=np.empty(n, np.int32),
        border=np.empty(n, np.bool_), below=np.empty(n, np.int64), above=np.empty(n, np.int64),
        t=np.empty(n, np.float64),
    )
    _march(vals, band, levels, True, out["skey"], out["ekey"], out["level"], out["border"],
           out["below"], out["above"], out["t"])
    return out


def march_ref(vals, band, levels):
    """Plain NumPy twin of :func:`march`: vectorised per level over all cells.

    Returns the same segments, in (level, key) order rather than scan order.
    """
    vals = np.asarray(vals, np.float64)
    band = np.asarray(band, np.int64)
    hp, wp = vals.shape
    nl = len(levels)
    r, c = np.meshgrid(np.arange(hp - 1), np.arange(wp - 1), indexing="ij")
    r, c = r.ravel(), c.ravel()
    rr = [r + dr for dr in (0, 0, 1, 1)]
    cc = [c + dc for dc in (0, 1, 1, 0)]
    v = [vals[rr[k], cc[k]] for k in range(4)]
    pad = [(rr[k] == 0) | (cc[k] == 0) | (rr[k] == hp - 1) | (cc[k] == wp - 1) for k in range(4)]
    anypad = pad[0] | pad[1] | pad[2] | pad[3]
    idx = [rr[k] * wp + cc[k] for k in range(4)]

    def edge_id(k, sel):
        r_, c_ = r[sel], c[sel]
        return {
            0: r_ * wp + c_,
            1: hp * wp + r_ * wp + c_ + 1,
            2: (r_ + 1) * wp + c_,
            3: hp * wp + r_ * wp + c_,
        }[k]

    rows = []
    for l in range(nl):
        ab = [band[rr[k], cc[k]] > l for k in range(4)]
        den = v[0] + v[2] - v[1] - v[3]
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (v[0] * v[2] - v[1] * v[3]) / den
        saddle = (ab[0] == ab[2]) & (ab[1] == ab[3]) & (ab[0] != ab[1])
        centre_above = s >= levels[l]
        pairs = []  # (selection mask, edge a, edge b) with corners a+1..b on the left = above
        # saddles: cut off each corner k that differs from the centre
        for k in range(4):
            ep = (k + 3) % 4
            sel = saddle & (ab[k] != centre_above)
            pairs.append((sel & ab[k], ep, k))
            pairs.append((sel & ~ab[k], k, ep))
        # two crossings: the crossing edges ea < eb, oriented by corner ea+1
        crossing = [ab[k] != ab[(k + 1) % 4] for k in range(4)]
        ncross = sum(x.astype(int) for x in crossing)
        for ea in range(4):
            for eb in range(ea + 1, 4):
                sel = (ncross == 2) & crossing[ea] & crossing[eb]
                up = ab[(ea + 1) % 4]
                pairs.append((sel & up, ea, eb))
                pairs.append((sel & ~up, eb, ea))
        for sel, ea, eb in pairs:
            if not sel.any():
                continue
            ka, kb = ea, (ea + 1) % 4
            # below corner first
            below_is_a = ~ab[ka][sel]
            va = np.where(below_is_a, v[ka][sel], v[kb][sel])
            vb = np.where(below_is_a, v[kb][sel], v[ka][sel])
            ia = np.where(below_is_a, idx[ka][sel], idx[kb][sel])
            ib = np.where(below_is_a, idx[kb][sel], idx[ka][sel])
            pa = np.where(below_is_a, pad[ka][sel], pad[kb][sel])
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.where(pa, 1.0, (levels[l] - va) / (vb - va))
            rows.append(dict(
                skey=edge_id(ea, sel) * nl + l, ekey=edge_id(eb, sel) * nl + l,
                level=np.full(sel.sum(), l, np.int32), border=anypad[sel],
                below=ia, above=ib, t=t,
            ))
    if not rows:
        return {k: np.zeros(0, dt) for k, dt in (("skey", np.int64), ("ekey", np.int64), ("level", np.int32),
                                                ("border", bool), ("below", np.int64), ("above", np.int64), ("t", float))}
    out = {k: np.concatenate([row[k] for row in rows]) for k in rows[0]}
    order = np.lexsort((out["skey"],))
    return {k: a[order] for k, a in out.items()}


def link_loops(skey, ekey):
    """Follow segments into closed loops.

    Returns (order, loop_offsets): segments order[loop_offsets[i]:loop_offsets[i+1]] form loop
    i in travel order. Each key must start exactly one segment and end exactly one (else
    both arrays come back empty). Loops start at their segment of smallest start key
    (deterministic). The sort and the look-up are NumPy's; the walk is compiled.
    """
    skey = np.asarray(skey, np.int64)
    ekey = np.asarray(ekey, np.int64)
    n = skey.shape[0]
    srt = np.argsort(skey, kind="stable")
    sk = skey[srt]
    j = np.searchsorted(sk, ekey)
    if n and (j.max() >= n or not np.array_equal(sk[np.minimum(j, n - 1)], ekey)):
        return np.empty(0, np.int64), np.empty(0, np.int64)  # broken topology
    return _walk(srt[j] if n else np.empty(0, np.int64), srt)


@njit(cache=True, nogil=True)
def _walk(nxt, srt):
    n = nxt.shape[0]
    seen = np.zeros(n, np.bool_)
    order = np.empty(n, np.int64)
    offs = np.empty(n + 1, np.int64)
    offs[0] = 0
    n_loops = 0
    m = 0
    for q in range(n):
        i = srt[q]  # visiting in key order makes each loop start at its smallest key
        if seen[i]:
            continue
        j = i
        while not seen[j]:
            seen[j] = True
            order[m] = j
            m += 1
            j = nxt[j]
        n_loops += 1
        offs[n_loops] = m
    return order, offs[: n_loops + 1].copy()
