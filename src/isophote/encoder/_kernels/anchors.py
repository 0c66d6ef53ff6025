"""Which isoline crossings may become joints on the sample grid (kernel; its NumPy twin is anchors_ref.py).

Used by :mod:`isophote.encoder` (its ``_joint_reach``). A crossing may move onto the nearer
end S of its grid edge when S lies within ``frac`` of its tolerance and inside the image (not
on its frame, where the contour would touch the border), no other crossing of that edge lies
between it and S (S is in the band next to its level: an edge's crossings come in level
order), no crossing of another level is nearer S (then the first in point order among
equals), and at most PER_LOOP crossings of its loop lie nearer S (so no loop shrinks onto a
sample). Grid samples are flat indices of the padded grid (``wp`` samples a row; sample
(r, c) sits at ((c - 1) / 2, (r - 1) / 2) px); ``band`` is the padded band grid, flat.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ... import threads
from ...shared.spill import RELEASE_POINTS

# At most this many crossings of one loop move onto one sample: two are a corner the loop
# cuts at the sample; four would shrink a loop round the sample onto it (area 0; a perspective
# warp turned such a loop inside out; measured: benchmarks/results/design_choices.md#per-loop).
PER_LOOP = 2


@njit(cache=True, nogil=True, inline="always")
def _nearer(along, below, step, k, wp):
    """Crossing k's nearer grid sample S (the lower-numbered one on ties), S's row and
    column and its city-block distance. Its edge runs from its below sample to the
    4-neighbour that step[k] names (isolines.py: +1, -1, +wp, -wp), and the crossing lies
    ``along`` it (its other coordinate is the below sample's): one division finds both
    samples' rows."""
    lo = below[k]
    rl = lo // wp
    cl = lo - rl * wp
    code = step[k]
    if code == 0:
        hi, rh, ch = lo + 1, rl, cl + 1
    elif code == 1:
        hi, rh, ch = lo - 1, rl, cl - 1
    elif code == 2:
        hi, rh, ch = lo + wp, rl + 1, cl
    else:
        hi, rh, ch = lo - wp, rl - 1, cl
    x, y = _xy(along, code, k, rl, cl)
    a = abs(x - (cl - 1) * 0.5) + abs(y - (rl - 1) * 0.5)
    b = abs(x - (ch - 1) * 0.5) + abs(y - (rh - 1) * 0.5)
    if a < b or (a == b and lo < hi):
        return lo, rl, cl, a
    return hi, rh, ch, b


@njit(cache=True, nogil=True, inline="always")
def _xy(along, code, k, rl, cl):
    """Crossing k's point, its below sample at row rl, column cl (isolines.points_of)."""
    if code <= 1:
        return along[k], (rl - 1) * 0.5
    return (cl - 1) * 0.5, along[k]


def joint_reach(along, below, step, band, offsets, loop_level, tol, wp, frac, workers=1):
    """(N,) float64: frac * tol[k] for the crossings that may move, 0 for the others."""
    moves = joint_moves(along, below, step, band, offsets, loop_level, tol, wp, frac, workers=workers)
    return np.where(moves, frac * tol, 0.0)


# Sample rows whose candidates joint_moves chains at a time (its per-sample heads are a band's,
# not the grid's: 4 bytes a sample of the band)
BAND_ROWS = 256


@njit(cache=True, nogil=True, inline="always")
def _candidate(along, below, step, band, lev, k, wp, hp, frac, tol):
    """Crossing k's nearer sample and its row if it is a candidate to move there (within
    frac of its tolerance, in the band next to its level, inside the image), else (-1, -1)."""
    s, r, c, d = _nearer(along, below, step, k, wp)
    if (d <= frac * tol[k] and 1 < r < hp - 2 and 1 < c < wp - 2
            and band[s] == (lev if s == below[k] else lev + 1)):
        return s, r
    return -1, -1


def joint_moves(along, below, step, band, offsets, loop_level, tol, wp, frac, band_rows=BAND_ROWS, workers=1,
                max_candidates=None, release=None):
    """(N,) bool: the crossings that may move (joint_reach's, a byte a crossing: the encoder
    holds this and makes the reaches batch by batch).

    Loop i is crossings offsets[i] .. offsets[i + 1] - 1, of level loop_level[i]; crossing k
    lies at along[k] on the grid edge from below[k] to its 4-neighbour step[k] (isolines.py:
    Isolines.along, step, below). A sample's decision
    reads its own candidates alone, in point order, so the samples are taken ``band_rows``
    rows at a time: the candidates are listed band by band in point order (4 bytes a
    candidate), and each band chains its own per sample (4 bytes a sample of the band and a
    candidate of it); a crossing's loop and distance are found again when its sample is
    visited. The candidates are counted first, then listed and decided for runs of bands
    of at most ``max_candidates`` in all (one band at least; None: every band at once),
    one listing pass a run over the loops with candidates in its bands (the counting pass
    notes each loop's first and last band: 8 bytes a loop). ``workers`` threads list the
    candidates of consecutive runs of loops (each run's after the runs before it in each
    band: the same lists) and decide runs of bands (a crossing is a candidate at one sample alone): the
    same result for any count and any max_candidates. With ``release`` (a callable: the
    encoder's Pager.release, for inputs on its files), the loops are counted and listed in
    runs of at most RELEASE_POINTS points, ``workers`` runs at a time, and release() is
    called after each wave and each decided run of bands (the same lists)."""
    n = along.shape[0]
    hp = band.shape[0] // wp
    n_bands = (hp + band_rows - 1) // band_rows
    n_loops = offsets.shape[0] - 1
    moves = np.zeros(n, np.bool_)
    if n == 0:
        return moves
    args = (along, below, step, band, offsets, loop_level, tol, wp, float(frac), int(band_rows))
    workers = max(1, min(int(workers), n_loops))
    n_runs = workers if release is None else max(workers, -(-n // RELEASE_POINTS))
    cuts = np.unique(np.concatenate([[0], np.searchsorted(offsets, np.linspace(0, n, n_runs + 1)[1:-1]),
                                     [n_loops]]))
    runs = list(zip(cuts[:-1], cuts[1:]))
    counts = np.zeros((len(runs), n_bands), np.int64)
    span = np.empty((n_loops, 2), np.int32)  # each loop's first and last band of candidates

    def waves(job):  # the runs, ``workers`` at a time, released after each wave
        for w in range(0, len(runs), workers):
            _threaded([lambda i=i: job(i) for i in range(w, min(w + workers, len(runs)))])
            if release is not None:
                release()

    waves(lambda i: _list(*args, runs[i][0], runs[i][1], counts[i], _NO_CAND, False, 0, n_bands, span))
    per_band = counts.sum(axis=0)
    start = np.concatenate([[0], np.cumsum(per_band)]).astype(np.int64)
    fill = start[:-1] + np.cumsum(counts, axis=0) - counts  # each run's place in each band
    for g0, g1 in band_groups(per_band, max_candidates):
        base = start[g0]
        cand = np.empty(int(start[g1] - base), np.int32)
        at = fill - base
        waves(lambda i: _list(*args, runs[i][0], runs[i][1], at[i], cand, True, g0, g1, span))
        rel = start - base
        bcuts = np.unique(np.concatenate([[g0], np.searchsorted(rel, np.linspace(0, rel[g1], workers + 1)[1:-1]),
                                          [g1]]))
        bcuts = bcuts[(bcuts >= g0) & (bcuts <= g1)]
        _threaded([lambda a=a, b=b: _decide(along, below, step, offsets, loop_level, wp, hp, int(band_rows),
                                             cand, rel, a, b, moves) for a, b in zip(bcuts[:-1], bcuts[1:])])
        del cand
        if release is not None:
            release()
    return moves


def band_groups(per_band: np.ndarray, max_candidates=None) -> list:
    """Runs [g0, g1) of consecutive bands, each of at most max_candidates candidates in all
    or a single band (None: one run of every band)."""
    nb = per_band.shape[0]
    if max_candidates is None or nb == 0:
        return [(0, nb)]
    out, g0, total = [], 0, 0
    for b in range(nb):
        if b > g0 and total + per_band[b] > max_candidates:
            out.append((g0, b))
            g0, total = b, 0
        total += int(per_band[b])
    out.append((g0, nb))
    return out


_NO_CAND = np.zeros(0, np.int32)


def _threaded(jobs):
    """Run the jobs (the kernels release the GIL), on the project's pool when more than one."""
    if len(jobs) == 1:
        jobs[0]()
        return
    with threads.pool(len(jobs)) as pool:
        for f in [pool.submit(j) for j in jobs]:
            f.result()


@njit(cache=True, nogil=True)
def _list(along, below, step, band, offsets, loop_level, tol, wp, frac, band_rows, l0, l1, at, cand, fill, b0, b1,
          span):
    """The candidates of loops [l0, l1) in bands [b0, b1) band by band: counted (at[b] += 1
    for each of band b's; span[lp]: the first and last band of loop lp's candidates, (big,
    -1) when it has none) or, with ``fill``, listed into cand in point order, band b's from
    at[b] on (loops whose span misses the bands skipped)."""
    hp = band.shape[0] // wp
    for lp in range(l0, l1):
        if fill and (span[lp, 1] < b0 or span[lp, 0] >= b1):
            continue
        lev = loop_level[lp]
        first = hp
        last = -1
        for k in range(offsets[lp], offsets[lp + 1]):
            s, r = _candidate(along, below, step, band, lev, k, wp, hp, frac, tol)
            if s >= 0:
                b = r // band_rows
                first = min(first, b)
                last = max(last, b)
                if b < b0 or b >= b1:
                    continue
                if fill:
                    cand[at[b]] = k
                at[b] += 1
        if not fill:
            span[lp, 0] = first
            span[lp, 1] = last


@njit(cache=True, nogil=True)
def _decide(along, below, step, offsets, loop_level, wp, hp, band_rows, cand, start, b0, b1, moves):
    """The moves of the candidates of bands [b0, b1) (cand[start[b]:start[b + 1]]: band b's,
    in point order)."""
    widest = 0
    for b in range(b0, b1):
        widest = max(widest, start[b + 1] - start[b])
    head = np.empty(min(band_rows, hp) * wp, np.int32)
    nxt = np.empty(widest, np.int32)  # links between a band's candidates (their places in cand)
    ck = np.empty(0, np.int64)  # one sample's candidates: point, loop, distance
    cl = np.empty(0, np.int64)
    cd = np.empty(0)
    for b in range(b0, b1):
        s0 = b * band_rows * wp
        s1 = min((b + 1) * band_rows, hp) * wp
        head[: s1 - s0] = -1
        a0 = start[b]
        for a in range(start[b + 1] - 1, a0 - 1, -1):  # pushed last first: chains in point order
            s = _nearer(along, below, step, cand[a], wp)[0] - s0
            nxt[a - a0] = head[s]
            head[s] = a - a0
        longest = 0
        for s in range(s1 - s0):
            m = 0
            q = head[s]
            while q >= 0:
                m += 1
                q = nxt[q]
            longest = max(longest, m)
        if longest > ck.shape[0]:
            ck = np.empty(longest, np.int64)
            cl = np.empty(longest, np.int64)
            cd = np.empty(longest)
        for s in range(s0, s1):
            q = head[s - s0]
            if q < 0:
                continue
            r = s // wp
            sx = (s - r * wp - 1) * 0.5
            sy = (r - 1) * 0.5
            m = 0
            while q >= 0:
                k = cand[a0 + q]
                ck[m] = k
                cl[m] = np.searchsorted(offsets, k, "right") - 1
                lo = below[k]
                rl = lo // wp
                x, y = _xy(along, step[k], k, rl, lo - rl * wp)
                cd[m] = abs(x - sx) + abs(y - sy)  # _nearer's, to the bit
                m += 1
                q = nxt[q]
            # k moves if at most PER_LOOP - 1 of the sample's candidates of its loop come before
            # it (nearer, then first), and its level is the level of the sample's nearest
            # candidate (then the first)
            best = 0
            for i in range(m):
                if cd[i] < cd[best]:
                    best = i
            for i in range(m):
                before = 0
                for j in range(m):
                    if cl[j] == cl[i] and (cd[j] < cd[i] or (cd[j] == cd[i] and ck[j] < ck[i])):
                        before += 1
                if before < PER_LOOP and loop_level[cl[i]] == loop_level[cl[best]]:
                    moves[ck[i]] = True
