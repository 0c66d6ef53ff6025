"""Plain NumPy twin of marching.py (same function names, same results; tests compare them)."""

from __future__ import annotations

import numpy as np

from .marching import CUBIC_ITERATIONS, CUBIC_STEP


def march(vals, band, levels):
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


def march_loops(vals, band, levels, grid, grid_eps):
    """NumPy twin of :func:`march_loops`: march, a plain walk along the keys, gathers,
    and np.gradient for the gradient magnitude."""
    seg = march(vals, band, levels)
    hp, wp = vals.shape
    start = {int(k): s for s, k in enumerate(seg["skey"])}
    nxt = np.array([start.get(int(k), -1) for k in seg["ekey"]], np.int64)
    seen = np.zeros(len(nxt), bool)
    loops = []
    for i in np.argsort(seg["skey"], kind="stable"):  # each loop from its smallest key
        if seen[i]:
            continue
        lp = []
        j = i
        while not seen[j]:
            seen[j] = True
            lp.append(j)
            j = nxt[j]
        loops.append(np.asarray(lp, np.int64))
    inner = [lp for lp in loops if not np.all(seg["border"][lp])]
    frame_levels = np.array([seg["level"][lp[0]] for lp in loops if np.all(seg["border"][lp])], np.int64)
    order = np.concatenate(inner) if inner else np.zeros(0, np.int64)
    below, above, t = seg["below"][order], seg["above"][order], seg["t"][order]
    rb, cb = np.divmod(below, wp)
    ra, ca = np.divmod(above, wp)
    inner_b = (rb > 0) & (cb > 0) & (rb < hp - 1) & (cb < wp - 1)
    f = np.asarray(vals, np.float64).ravel()
    step = above - below
    before, beyond = below - step, above + step

    def on_pad(i):
        r, c = np.divmod(i, wp)
        return (r == 0) | (c == 0) | (r == hp - 1) | (c == wp - 1)

    k = np.flatnonzero(inner_b)
    v0, v1 = f[below[k]], f[above[k]]
    vm = np.where(on_pad(before[k]), v0, f[np.clip(before[k], 0, f.size - 1)])
    v2 = np.where(on_pad(beyond[k]), v1, f[np.clip(beyond[k], 0, f.size - 1)])
    t = t.copy()
    t[k] = _cubic_t(vm, v0, v1, v2, t[k])
    points = np.column_stack([((cb - 1) + t * (ca - cb)) * 0.5, ((rb - 1) + t * (ra - rb)) * 0.5])
    eps_p = np.zeros((hp, wp))
    eps_p[1:-1, 1:-1] = grid_eps
    gy, gx = np.gradient(np.asarray(grid, np.float64), 0.5)
    grad_p = np.zeros((hp, wp))
    grad_p[1:-1, 1:-1] = np.hypot(gx, gy)
    ef, gf = eps_p.ravel(), grad_p.ravel()
    level = np.array([seg["level"][lp[0]] for lp in inner], np.int32)
    offsets = np.concatenate([[0], np.cumsum([len(lp) for lp in inner])]).astype(np.int64)
    return (True, points, seg["border"][order], below, above, t, ef[below], ef[above], gf[below],
            gf[above], level, offsets, frame_levels)


def _cubic_t(vm, v0, v1, v2, t):
    """NumPy twin of _cubic_t, over arrays: the same steps, element by element."""
    d = v1 - v0
    a = np.maximum(0.5 * (v1 - vm) / d, 0.0)
    b = np.maximum(0.5 * (v2 - v0) / d, 0.0)
    r = a * a + b * b
    big = r > 9.0
    f = 3.0 / np.sqrt(np.where(big, r, 9.0))
    a = np.where(big, a * f, a)
    b = np.where(big, b * f, b)
    c2 = 3.0 - 2.0 * a - b
    c3 = a + b - 2.0
    x = np.array(t, np.float64)
    lo = np.zeros_like(x)
    hi = np.ones_like(x)
    out = x.copy()
    live = np.ones(x.shape, bool)
    for _ in range(CUBIC_ITERATIONS):
        k = np.flatnonzero(live)
        if k.size == 0:
            break
        xk = x[k]
        g = ((c3[k] * xk + c2[k]) * xk + a[k]) * xk - t[k]
        root = g == 0.0
        out[k[root]] = xk[root]
        live[k[root]] = False
        k, xk, g = k[~root], xk[~root], g[~root]
        below = g < 0.0
        lo[k] = np.where(below, xk, lo[k])
        hi[k] = np.where(below, hi[k], xk)
        dg = (3.0 * c3[k] * xk + 2.0 * c2[k]) * xk + a[k]
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = np.where(dg > 0.0, xk - g / np.where(dg > 0.0, dg, 1.0), 0.5 * (lo[k] + hi[k]))
        xn = np.where((lo[k] < xn) & (xn < hi[k]), xn, 0.5 * (lo[k] + hi[k]))
        done = np.abs(xn - xk) <= CUBIC_STEP
        out[k[done]] = xn[done]
        live[k[done]] = False
        x[k] = xn
        out[k[~done]] = xn[~done]
    return out
