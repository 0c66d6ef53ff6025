"""Evaluation and subdivision of cubic Beziers, vectorised over (M, 4, 2) arrays of control
points. Subdivision is de Casteljau's construction in its polar (blossom) form:
the piece of a cubic over [t0, t1] has control points b(t0,t0,t0), b(t0,t0,t1), b(t0,t1,t1),
b(t1,t1,t1).
"""

from __future__ import annotations

import numpy as np


def bernstein(ts: np.ndarray) -> np.ndarray:
    """(T, 4) cubic Bernstein weights at the parameters ``ts``."""
    u = 1.0 - ts
    return np.stack([u**3, 3 * u * u * ts, 3 * u * ts * ts, ts**3], axis=1)


def evaluate(segs: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(M, 2) points of cubics (M, 4, 2) at per-row parameters t (M,)."""
    return np.einsum("mk,mkd->md", bernstein(t), segs)


def evaluate_grid(segs: np.ndarray, ts: np.ndarray) -> np.ndarray:
    """(M, T, 2) points of every cubic (M, 4, 2) at every parameter of ``ts`` (T,)."""
    return np.einsum("tk,mkd->mtd", bernstein(ts), segs)


def blossom(segs: np.ndarray, u1, u2, u3) -> np.ndarray:
    """(M, 2) polar form of cubics (M, 4, 2) at per-row parameters (M,) each."""
    p = segs
    for u in (u1, u2, u3):
        p = (1.0 - u)[:, None, None] * p[:, :-1] + u[:, None, None] * p[:, 1:]
    return p[:, 0]


def subsegment(segs: np.ndarray, t0, t1) -> np.ndarray:
    """(M, 4, 2) control points of the cubics restricted to [t0, t1] (per row)."""
    return np.stack([blossom(segs, t0, t0, t0), blossom(segs, t0, t0, t1),
                     blossom(segs, t0, t1, t1), blossom(segs, t1, t1, t1)], axis=1)


def split(segs: np.ndarray, t):
    """(left, right): every cubic cut at its parameter t (scalar or (M,)), de Casteljau."""
    t = np.broadcast_to(np.asarray(t, np.float64), (len(segs),))
    return subsegment(segs, np.zeros(len(segs)), t), subsegment(segs, t, np.ones(len(segs)))


def map_cubics(segs: np.ndarray, border: np.ndarray, fn, jacobian, tol: float, max_depth: int):
    """Segments sent through a smooth point map ``fn`` within ``tol``.

    Each cubic is replaced by the Hermite cubic of the mapped end points and end tangents
    (``jacobian`` maps them) and halved until that is within ``tol`` of the mapped curve at
    t = 1/4, 1/2, 3/4 (at most ``max_depth`` halvings); straight (border) segments stay
    straight, judged by their chords. Returns (pieces (P, 4, 2), border (P,), source index
    (P,)), in chain order.
    """
    n = len(segs)
    if n == 0:
        return segs.copy(), border.copy(), np.zeros(0, np.int64)
    sid, t0, t1 = np.arange(n), np.zeros(n), np.ones(n)
    out_seg, out_id, out_t0 = [], [], []
    for depth in range(max_depth + 1):
        if len(sid) == 0:
            break
        sub = subsegment(segs[sid], t0, t1)
        new = _hermite_image(sub, border[sid], fn, jacobian)
        err = _probe_error(sub, new, fn)
        ok = (err <= tol) | (depth == max_depth) | ~np.isfinite(err)
        out_seg.append(new[ok])
        out_id.append(sid[ok])
        out_t0.append(t0[ok])
        bad = ~ok
        tm = 0.5 * (t0[bad] + t1[bad])
        sid = np.concatenate([sid[bad], sid[bad]])
        t0, t1 = np.concatenate([t0[bad], tm]), np.concatenate([tm, t1[bad]])
    segs_out = np.concatenate(out_seg)
    ids = np.concatenate(out_id)
    order = np.lexsort((np.concatenate(out_t0), ids))
    return segs_out[order], border[ids[order]], ids[order]


def _hermite_image(sub, brd, fn, jacobian):
    """The cubics through the mapped end points with the mapped end tangents (straight ones
    stay straight)."""
    a, d = fn(sub[:, 0]), fn(sub[:, 3])
    new = np.empty_like(sub)
    new[:, 0], new[:, 3] = a, d
    curved = ~brd
    if curved.any():
        ja = jacobian(sub[curved, 0])
        jd = jacobian(sub[curved, 3])
        new[curved, 1] = a[curved] + np.einsum("mij,mj->mi", ja, sub[curved, 1] - sub[curved, 0])
        new[curved, 2] = d[curved] + np.einsum("mij,mj->mi", jd, sub[curved, 2] - sub[curved, 3])
    new[brd, 1] = a[brd] + (d[brd] - a[brd]) / 3.0
    new[brd, 2] = a[brd] + 2.0 * (d[brd] - a[brd]) / 3.0
    return new


PROBES = (0.25, 0.5, 0.75)  # where a mapped piece is compared with the mapped curve


def _probe_error(sub, new, fn):
    err = np.zeros(len(sub))
    for t in np.array(PROBES):
        tt = np.full(len(sub), t)
        exact = fn(evaluate(sub, tt))
        err = np.maximum(err, np.hypot(*(exact - evaluate(new, tt)).T))
    return err
