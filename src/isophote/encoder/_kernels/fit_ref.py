"""Plain NumPy twin of fit.py: the same algorithm (see fit.py's docstring) with the same
floating-point expressions, written for reading, not speed; the tests compare them."""

from __future__ import annotations

import numpy as np

from ...shared.grid_ref import chord_frame, from_frame, rnd, rnd3, to_frame

from .fit import COARSEN_STEPS, FIRST_GUESS, GIVE_UP, ITERATIONS, MAX_SAMPLES, NEWTON_STEPS, QUANT, RIDGE, TANGENTIAL


def _bernstein(t):
    s = 1.0 - t
    return s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t


def _eval(p0, c, p3, t):
    """Points of the cubic p0, (c[0], c[1]), (c[2], c[3]), p3 at parameters t: (len(t), 2)."""
    b0, b1, b2, b3 = _bernstein(t)
    x = b0 * p0[0] + b1 * c[0] + b2 * c[2] + b3 * p3[0]
    y = b0 * p0[1] + b1 * c[1] + b2 * c[3] + b3 * p3[1]
    return np.stack([x, y], axis=1)


def _lsq(q, tol, i, j, u):
    p0, p3 = q[i, 2:], q[j, 2:]
    t = u[i + 1 : j]
    b0, b1, b2, b3 = _bernstein(t)
    w = 1.0 / (tol[i + 1 : j] * tol[i + 1 : j])  # the kernels' w
    r = q[i + 1 : j, :2] - b0[:, None] * p0 - b3[:, None] * p3
    a11 = np.sum(w * b1 * b1)
    a12 = np.sum(w * b1 * b2)
    a22 = np.sum(w * b2 * b2)
    r1 = np.sum((w * b1)[:, None] * r, axis=0)
    r2 = np.sum((w * b2)[:, None] * r, axis=0)
    lam = RIDGE * (a11 + a22)
    if not lam > 0.0:
        lam = 1.0
    a11 += lam
    a22 += lam
    r1 = r1 + lam * (p0 + (p3 - p0) / 3.0)
    r2 = r2 + lam * (p0 + 2.0 * (p3 - p0) / 3.0)
    det = a11 * a22 - a12 * a12
    c1 = (a22 * r1 - a12 * r2) / det
    c2 = (a11 * r2 - a12 * r1) / det
    return np.array([c1[0], c1[1], c2[0], c2[1]])


def _tdm(q, tol, i, j, u, c):
    p0, p3 = q[i, 2:], q[j, 2:]
    t = u[i + 1 : j]
    s = 1.0 - t
    b0, b1, b2, b3 = _bernstein(t)
    cc = np.array([[c[0], c[1]], [c[2], c[3]]])
    g = 3.0 * ((s * s)[:, None] * (cc[0] - p0) + (2.0 * s * t)[:, None] * (cc[1] - cc[0])
               + (t * t)[:, None] * (p3 - cc[1]))
    gl = g[:, 0] * g[:, 0] + g[:, 1] * g[:, 1]
    # M = TANGENTIAL I + (1 - TANGENTIAL) n n^T for the unit normal n of each foot point
    nn = np.zeros((len(t), 2, 2))
    ok = gl > 0.0
    nn[ok, 0, 0] = g[ok, 1] * g[ok, 1] / gl[ok]
    nn[ok, 1, 1] = g[ok, 0] * g[ok, 0] / gl[ok]
    nn[ok, 0, 1] = nn[ok, 1, 0] = -g[ok, 0] * g[ok, 1] / gl[ok]
    m = TANGENTIAL * np.eye(2) + (1.0 - TANGENTIAL) * nn
    m[~ok] = np.eye(2)
    w = 1.0 / (tol[i + 1 : j] * tol[i + 1 : j])
    r = q[i + 1 : j, :2] - b0[:, None] * p0 - b3[:, None] * p3
    basis = np.stack([b1, b2], axis=1)  # (k, 2)
    a = np.einsum("k,ka,kb,kxy->axby", w, basis, basis, m).reshape(4, 4)
    rhs = np.einsum("k,ka,kxy,ky->ax", w, basis, m, r).reshape(4)
    lam = RIDGE * np.trace(a)
    if not lam > 0.0:
        lam = 1.0
    return np.linalg.solve(a + lam * np.eye(4), rhs + lam * np.asarray(c))


def _point_err(q, tol, i, j, u, c):
    if j - i < 2:
        return 0.0
    d = _eval(q[i, 2:], c, q[j, 2:], u[i + 1 : j]) - q[i + 1 : j, :2]
    w = 1.0 / (tol[i + 1 : j] * tol[i + 1 : j])
    return float(np.max((d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]) * w))


def _newton(q, i, j, u, c):
    p0, p3 = q[i, 2:], q[j, 2:]
    cc = np.array([[c[0], c[1]], [c[2], c[3]]])
    t = u[i + 1 : j].copy()
    s = 1.0 - t
    d = _eval(p0, c, p3, t) - q[i + 1 : j, :2]
    d0, d1, d2 = cc[0] - p0, cc[1] - cc[0], p3 - cc[1]
    g = 3.0 * ((s * s)[:, None] * d0 + (2.0 * s * t)[:, None] * d1 + (t * t)[:, None] * d2)
    h = 6.0 * (s[:, None] * (d1 - d0) + t[:, None] * (d2 - d1))
    num = d[:, 0] * g[:, 0] + d[:, 1] * g[:, 1]
    den = g[:, 0] * g[:, 0] + g[:, 1] * g[:, 1] + d[:, 0] * h[:, 0] + d[:, 1] * h[:, 1]
    ok = den > 0.0
    t[ok] = np.clip(t[ok] - num[ok] / den[ok], 0.0, 1.0)
    u[i + 1 : j] = t
    u[i : j + 1] = np.maximum.accumulate(u[i : j + 1])


def _bulge_ok(q, tol, i, j, u, c):
    p0, p3, c1, c2 = q[i, 2:], q[j, 2:], np.array(c[:2]), np.array(c[2:])
    sec = np.array([p0 - 2.0 * c1 + c2, c1 - 2.0 * c2 + p3])
    curv = 6.0 * np.sqrt(np.max(sec[:, 0] * sec[:, 0] + sec[:, 1] * sec[:, 1]))
    tl = np.maximum(tol[i:j], tol[i + 1 : j + 1])  # per edge (= per interval)
    du = u[i + 1 : j + 1] - u[i:j]
    need = du * np.sqrt(curv / tl)
    ns = np.where(need > 1.0, np.minimum(need, MAX_SAMPLES).astype(np.int64), 1)
    margin = curv * (du / (ns + 1)) ** 2 / 8.0
    a, e = q[i:j, :2], q[i + 1 : j + 1, :2] - q[i:j, :2]
    # no backtracking at the inner samples u[k] + du[k] * m / (ns[k] + 1), m = 1 .. ns[k]:
    # B'(t) . edge >= 0
    k = np.repeat(np.arange(j - i), ns)
    m = np.arange(len(k)) - np.repeat(np.cumsum(ns) - ns, ns) + 1
    t = u[i:j][k] + du[k] * m / (ns[k] + 1)
    s_ = 1.0 - t
    d = (
        (s_ * s_)[:, None] * (c1 - p0)[None]
        + (2.0 * s_ * t)[:, None] * (c2 - c1)[None]
        + (t * t)[:, None] * (p3 - c2)[None]
    )
    if not np.all(d[:, 0] * e[k, 0] + d[:, 1] * e[k, 1] >= 0.0):
        return False
    # the chord bound: the curve within curv du^2 / 8 of the chord between its interval's
    # ends, the chord within the larger of their point errors of edge k
    e2 = np.zeros(j - i + 1)
    mv = q[[i, j], 2:] - q[[i, j], :2]  # the joints' moves onto the anchor grid
    e2[[0, -1]] = mv[:, 0] ** 2 + mv[:, 1] ** 2
    if j - i > 1:
        dd = _eval(p0, c, p3, u[i + 1 : j]) - q[i + 1 : j, :2]
        e2[1:-1] = dd[:, 0] * dd[:, 0] + dd[:, 1] * dd[:, 1]
    slack = tl - curv * du * du / 8.0
    sampled = np.flatnonzero(~((slack >= 0.0) & (np.maximum(e2[:-1], e2[1:]) <= slack * slack)))
    if sampled.size == 0:
        return True
    # elsewhere every two neighbouring samples (u[k], the inner ones, u[k+1]) near one same
    # edge, less the interval's margin
    cnt = ns[sampled] + 2
    k = np.repeat(sampled, cnt)
    m = np.arange(len(k)) - np.repeat(np.cumsum(cnt) - cnt, cnt)
    inner = (m > 0) & (m <= ns[k])
    t = np.where(inner, u[i:j][k] + du[k] * m / (ns[k] + 1), np.where(m == 0, u[i:j][k], u[i + 1 : j + 1][k]))
    x = _eval(p0, c, p3, t)
    mg = margin[k]
    ll = e[:, 0] * e[:, 0] + e[:, 1] * e[:, 1]
    inv = np.zeros(len(ll))
    np.divide(1.0, ll, out=inv, where=ll > 0.0)
    w = x[:, None, :] - a[None]
    h = np.clip((w[..., 0] * e[:, 0] + w[..., 1] * e[:, 1]) * inv, 0.0, 1.0)
    dx = a[:, 0] + h * e[:, 0] - x[:, None, 0]
    dy = a[:, 1] + h * e[:, 1] - x[:, None, 1]
    lim = tl[None, :] - mg[:, None]
    near = (lim >= 0.0) & (dx * dx + dy * dy <= lim * lim)  # (samples, edges)
    pair = k[1:] == k[:-1]
    return bool(np.all(np.any(near[:-1] & near[1:], axis=1)[pair]))


def _fit_span(q, tol, cum, i, j, u):
    """Controls (4,) of the span i..j, or None when it does not fit; sets u[i..j]."""
    if j == i + 1:
        u[i], u[j] = 0.0, 1.0
        a, b = q[i, 2:], q[j, 2:]
        return np.array([a[0] + (b[0] - a[0]) / 3.0, a[1] + (b[1] - a[1]) / 3.0,
                         a[0] + 2.0 * (b[0] - a[0]) / 3.0, a[1] + 2.0 * (b[1] - a[1]) / 3.0])
    length = cum[j] - cum[i]
    if length > 0.0:
        u[i:j] = (cum[i:j] - cum[i]) / length
    else:
        u[i:j] = (np.arange(i, j) - i) / (j - i)
    u[j] = 1.0
    c = None
    for it in range(ITERATIONS):
        c = _lsq(q, tol, i, j, u) if it == 0 else _tdm(q, tol, i, j, u, c)
        _newton(q, i, j, u, c)
        limit = GIVE_UP[it] ** 2 if it < len(GIVE_UP) else 1.0
        worst = _point_err(q, tol, i, j, u, c)
        if worst <= 1.0 and _bulge_ok(q, tol, i, j, u, c):
            return c
        if worst > limit:
            return None
    return None


def _check_fixed(q, tol, i, j, u, c, steps=NEWTON_STEPS):
    u[i], u[j] = 0.0, 1.0
    for _ in range(steps):
        _newton(q, i, j, u, c)
    return _point_err(q, tol, i, j, u, c) <= 1.0 and _bulge_ok(q, tol, i, j, u, c)


def _snap_joint(q, tol, ends, ctrl, u, a, b, cos_snap):
    p = q[ends[a + 1], 2:]
    din = p - ctrl[a][2:]
    dout = ctrl[b][:2] - p
    li, lo = np.sqrt(din @ din), np.sqrt(dout @ dout)
    if not (li > 0.0 and lo > 0.0):
        return
    dot = din[0] * dout[0] + din[1] * dout[1]
    cross = din[0] * dout[1] - din[1] * dout[0]
    if cross == 0.0 or dot <= cos_snap * li * lo:
        return
    bis = din + dout
    bis = bis / np.sqrt(bis[0] * bis[0] + bis[1] * bis[1])
    ca, cb = ctrl[a].copy(), ctrl[b].copy()
    ca[2:] = p - li * bis
    if a == b:
        cb = ca
    cb[:2] = p + lo * bis
    ut = u.copy()
    segs = [(a, ca)] if a == b else [(a, ca), (b, cb)]
    for g, cg in segs:
        if not _check_fixed(q, tol, ends[g], ends[g + 1], ut, cg):
            return
    for g, cg in segs:
        u[ends[g] : ends[g + 1] + 1] = ut[ends[g] : ends[g + 1] + 1]
        ctrl[g] = cg


def _coarsen(q, tol, ends, ctrl, u, max_shift):
    """Twin of _coarsen, with format/isoph.py's plain frame (entropy)."""
    for g in range(len(ctrl)):
        i, j = ends[g], ends[g + 1]
        top = max_shift if j - i >= 2 else 0
        c = ctrl[g]
        a = [rnd(q[i, 2] * QUANT), rnd(q[i, 3] * QUANT)]
        n = [rnd(q[j, 2] * QUANT), rnd(q[j, 3] * QUANT)]
        frame = chord_frame(n[0] - a[0], n[1] - a[1])
        t = [rnd3(n[0] - a[0]), rnd3(n[1] - a[1])]
        h = to_frame(frame, rnd(c[0] * QUANT) - a[0] - t[0], rnd(c[1] * QUANT) - a[1] - t[1])
        r = to_frame(frame, rnd(c[2] * QUANT) - n[0] + t[0], rnd(c[3] * QUANT) - n[1] + t[1])
        tried = None
        for shift in range(top, -1, -1):
            terms = [((v + (1 << (shift - 1))) >> shift) << shift if shift else v for v in (*h, *r)]
            if terms == tried:
                continue  # rounds as the coarser grid did: that one failed
            tried = terms
            hx, hy = from_frame(frame, terms[0], terms[1])
            rx, ry = from_frame(frame, terms[2], terms[3])
            cg = np.array([(a[0] + t[0] + hx) / QUANT, (a[1] + t[1] + hy) / QUANT,
                           (n[0] - t[0] + rx) / QUANT, (n[1] - t[1] + ry) / QUANT])
            if _check_fixed(q, tol, i, j, u.copy(), cg, COARSEN_STEPS):
                ctrl[g] = cg
                break
        else:
            v = c * QUANT
            near = np.floor(v + 0.5)
            other = np.where(near > v, near - 1.0, near + 1.0)
            for flip in range(1, 16):
                bits = np.array([(flip >> k) & 1 for k in range(4)], bool)
                cg = np.where(bits, other, near) / QUANT
                if _check_fixed(q, tol, i, j, u.copy(), cg, COARSEN_STEPS):
                    ctrl[g] = cg
                    break


def fit_open(q, tol, closed, cos_snap, coarsen=0):
    """(ends, ctrl) of the chain fitted to q (closed by repetition when `closed`); q is
    (n, 4): the points, and where each goes as a joint (_joints)."""
    n = len(q)
    cum = np.concatenate([[0.0], np.cumsum(np.sqrt(np.sum(np.diff(q[:, :2], axis=0) ** 2, axis=1)))])
    u = np.zeros(n)
    ends, ctrl = [0], []
    i, guess = 0, FIRST_GUESS
    while i < n - 1:
        lo, best, ubest = i + 1, _fit_span(q, tol, cum, i, i + 1, u), None
        # the previous segment's length first, then gallop on by half that, doubling
        hi, j, step = None, min(i + guess, n - 1), max(1, guess // 2)
        while lo < n - 1:
            c = _fit_span(q, tol, cum, i, j, u)
            if c is None:
                hi = j
                break
            lo, best, ubest = j, c, u[i : j + 1].copy()
            j = min(lo + step, n - 1)
            step *= 2
        while hi is not None and hi - lo > 1:
            mid = (lo + hi) // 2
            c = _fit_span(q, tol, cum, i, mid, u)
            if c is None:
                hi = mid
            else:
                lo, best, ubest = mid, c, u[i : mid + 1].copy()
        if ubest is not None:
            u[i : lo + 1] = ubest
        else:
            u[i], u[lo] = 0.0, 1.0
        ends.append(lo)
        ctrl.append(best)
        i, guess = lo, max(2, lo - i)
    m = len(ctrl)
    if cos_snap < 1.0:
        for a in range(m - 1):
            _snap_joint(q, tol, ends, ctrl, u, a, a + 1, cos_snap)
        if closed:
            _snap_joint(q, tol, ends, ctrl, u, m - 1, 0, cos_snap)
    if coarsen > 0:
        _coarsen(q, tol, ends, ctrl, u, coarsen)
    return ends, ctrl


def _joints(q, reach, closed, grid, on_file_grid=False):
    """Twin of _joint_at for every point: q (n, 2) becomes (n, 4)."""
    qa = q.copy()
    if grid > 0.0:
        lim = reach
        r = np.floor(q / grid + 0.5) * grid
        d = r - q
        mx = np.abs(d[:, 0]) <= lim
        d[~mx, 0] = 0.0
        my = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] <= lim * lim
        qa[mx, 0] = r[mx, 0]
        qa[my, 1] = r[my, 1]
        if not closed:
            qa[[0, -1]] = q[[0, -1]]
    if on_file_grid:
        qa = np.floor(qa * QUANT + 0.5) / QUANT
    return np.concatenate([q, qa], axis=1)


def fit_polyline(points, tol, closed, cos_snap, coarsen=0, anchor_grid=0.0, reach=None):
    """Reference twin of fit_many_kernel for one polyline: the (1+3m, 2) chain (reach
    None: 0, every joint stays at its point)."""
    points = np.asarray(points, dtype=np.float64)
    tol = np.asarray(tol, dtype=np.float64)
    reach = np.zeros_like(tol) if reach is None else np.asarray(reach, dtype=np.float64)
    if closed:
        prev = np.roll(points, 1, axis=0)
        nxt = np.roll(points, -1, axis=0)
        v1, v2 = points - prev, nxt - points
        ang = np.arctan2(np.abs(v1[:, 0] * v2[:, 1] - v1[:, 1] * v2[:, 0]),
                         v1[:, 0] * v2[:, 0] + v1[:, 1] * v2[:, 1])
        s = int(np.argmax(ang))
        q = np.roll(points, -s, axis=0)
        t = np.roll(tol, -s)
        rc = np.roll(reach, -s)
        q = np.concatenate([q, q[:1]])
        t = np.concatenate([t, t[:1]])
        rc = np.concatenate([rc, rc[:1]])
    else:
        q, t, rc = points.copy(), tol.copy(), reach
    q = _joints(q, rc, closed, anchor_grid, coarsen > 0)
    ends, ctrl = fit_open(q, t, closed, cos_snap, coarsen)
    rows = [q[0, 2:]]
    for g, c in enumerate(ctrl):
        rows += [c[:2], c[2:], q[ends[g + 1], 2:]]
    return np.array(rows, dtype=np.float64)
