"""Clipping closed chains to the canvas, closing them along its border.

Every contour is cut where it crosses the canvas border and each outside excursion is
replaced by a path along the border that winds round the canvas as the excursion did, so the
winding numbers (and so the bands) of every point of the canvas are unchanged. Those border
paths carry border flags. Contours that leave the canvas entirely vanish or, if they enclose
it, add to ``base_band``.
"""

from __future__ import annotations

import math

import numpy as np

from ...geometry.bezier import evaluate, evaluate_grid, subsegment
from ...geometry.chains import line_segment

EDGE_EPS = 1e-6  # pixels: points this close outside the canvas count as on its border


class Frame:
    """The canvas border as a closed path, walked clockwise on screen from (0, 0):
    perimeter position s in [0, P): top edge, right edge, bottom edge, left edge."""

    def __init__(self, w, h):
        self.w, self.h = float(w), float(h)
        self.per = 2.0 * (self.w + self.h)
        self.corner_s = np.array([0.0, self.w, self.w + self.h, 2 * self.w + self.h])
        self.corners = np.array([[0, 0], [self.w, 0], [self.w, self.h], [0, self.h]], float)
        self.c = np.array([self.w / 2, self.h / 2])

    def position(self, p) -> float:
        """Perimeter position of a point on the border."""
        x, y = float(p[0]), float(p[1])
        dist = [abs(y), abs(x - self.w), abs(y - self.h), abs(x)]
        e = int(np.argmin(dist))
        if e == 0:
            return min(max(x, 0.0), self.w)
        if e == 1:
            return self.w + min(max(y, 0.0), self.h)
        if e == 2:
            return self.w + self.h + (self.w - min(max(x, 0.0), self.w))
        s = 2 * self.w + self.h + (self.h - min(max(y, 0.0), self.h))
        return s % self.per

    def point(self, s) -> np.ndarray:
        s = s % self.per
        w, h = self.w, self.h
        if s <= w:
            return np.array([s, 0.0])
        if s <= w + h:
            return np.array([w, s - w])
        if s <= 2 * w + h:
            return np.array([w - (s - w - h), h])
        return np.array([0.0, h - (s - 2 * w - h)])

    def angle(self, s) -> float:
        """Unwrapped angle about the centre (atan2 in screen coordinates, increasing
        clockwise on screen), continuous and increasing in s, with angle(s + P) = angle(s) + 2 pi."""
        k, r = divmod(s, self.per)
        p = self.point(r) - self.c
        a = math.atan2(p[1], p[0])
        a0 = math.atan2(-self.c[1], -self.c[0])  # angle at s = 0 (the top-left corner)
        while a < a0:
            a += 2 * math.pi
        while a >= a0 + 2 * math.pi:
            a -= 2 * math.pi
        if r > 0 and a == a0:
            a += 2 * math.pi
        return a + 2 * math.pi * k

    def path(self, s_from, s_to):
        """Corner points strictly between perimeter positions s_from and s_to (unwrapped),
        walking forward if s_to > s_from, backward otherwise."""
        lo, hi = min(s_from, s_to), max(s_from, s_to)
        first = math.floor(lo / self.per) - 1
        cs = []
        for k in range(int(first), int(math.floor(hi / self.per)) + 2):
            for c in self.corner_s:
                v = c + k * self.per
                if lo + 1e-12 < v < hi - 1e-12:
                    cs.append(v)
        cs.sort(reverse=s_to < s_from)
        return [self.point(v) for v in cs]


def _split_at_border(segs, border, w, h):
    """Cut cubics where they cross x = 0, x = w, y = 0 or y = h.

    Crossings are bracketed on 32 steps of t and refined by bisection (vectorised); a curve
    that pokes out and back within one step is not cut, and its piece is then judged by its
    middle. Returns (pieces (P, 4, 2), their border flags (P,)), in chain order.
    """
    m = len(segs)
    ts = np.linspace(0.0, 1.0, 33)
    pts = evaluate_grid(segs, ts)
    # o = s (coordinate - c) is positive outside the line's half-plane; a point on the line
    # counts as inside, as everywhere in the clipper
    seg_i, lo_t, hi_t, axis_i, value, sgn = [], [], [], [], [], []
    for axis, c, sg in ((0, 0.0, -1.0), (0, w, 1.0), (1, 0.0, -1.0), (1, h, 1.0)):
        out = sg * (pts[:, :, axis] - c) > 0
        mi, ti = np.nonzero(out[:, :-1] != out[:, 1:])
        seg_i.append(mi)
        lo_t.append(ts[ti])
        hi_t.append(ts[ti + 1])
        axis_i.append(np.full(len(mi), axis))
        value.append(np.full(len(mi), c))
        sgn.append(np.full(len(mi), sg))
    seg_i, a, b = np.concatenate(seg_i), np.concatenate(lo_t), np.concatenate(hi_t)
    axis_i, value, sgn = np.concatenate(axis_i), np.concatenate(value), np.concatenate(sgn)
    if len(seg_i):
        rows = np.arange(len(seg_i))
        out_a = sgn * (evaluate(segs[seg_i], a)[rows, axis_i] - value) > 0
        for _ in range(52):
            mid = 0.5 * (a + b)
            out_m = sgn * (evaluate(segs[seg_i], mid)[rows, axis_i] - value) > 0
            same = out_m == out_a
            a = np.where(same, mid, a)
            b = np.where(same, b, mid)
        cut_t = 0.5 * (a + b)
    else:
        cut_t = np.zeros(0)
    # every segment's cut list: 0, its crossings, 1
    all_seg = np.concatenate([np.arange(m), np.arange(m), seg_i])
    all_t = np.concatenate([np.zeros(m), np.ones(m), cut_t])
    order = np.lexsort((all_t, all_seg))
    all_seg, all_t = all_seg[order], all_t[order]
    same_seg = all_seg[1:] == all_seg[:-1]
    t0, t1, sid = all_t[:-1][same_seg], all_t[1:][same_seg], all_seg[:-1][same_seg]
    keep = t1 - t0 > 1e-12
    t0, t1, sid = t0[keep], t1[keep], sid[keep]
    return subsegment(segs[sid], t0, t1), border[sid]


def on_canvas(p, w, h, eps=EDGE_EPS):
    return (-eps <= p[..., 0]) & (p[..., 0] <= w + eps) & (-eps <= p[..., 1]) & (p[..., 1] <= h + eps)


def clip_contour(segs, border, frame: Frame):
    """Clip one closed chain to the canvas.

    Returns ("keep", segs, border) with the clipped chain, ("drop",) if it vanished, or
    ("frame", winding) if it lies outside and winds round the canvas ``winding`` times (in
    the renderer's sense: +1 adds one to the band of every point of the canvas).
    """
    w, h = frame.w, frame.h
    pieces, flags = _split_at_border(segs, np.asarray(border, bool), w, h)
    mids = evaluate(pieces, np.full(len(pieces), 0.5))
    inside = on_canvas(mids, w, h)
    if inside.all():
        return "keep", clamp_pieces(pieces, w, h), flags
    sweep = _sweep_angles(pieces, frame.c)
    if not inside.any():
        turns = int(round(sweep.sum() / (2 * math.pi)))
        # atan2 grows clockwise on screen; a contour with the canvas on its left runs
        # counter-clockwise on screen and adds +1 to the band
        return ("frame", -turns) if turns else ("drop",)
    # start at an inside piece that follows an outside one
    n = len(pieces)
    start = int(np.flatnonzero(inside & ~np.roll(inside, 1))[0])
    order = (np.arange(n) + start) % n
    out, out_flags = [], []
    i = 0
    while i < n:
        k = order[i]
        if inside[k]:
            out.append(pieces[k])
            out_flags.append(flags[k])
            i += 1
            continue
        j = i
        total = 0.0
        while j < n and not inside[order[j]]:
            total += sweep[order[j]]
            j += 1
        p_exit = pieces[order[i]][0]
        q_entry = pieces[order[j % n]][0] if j < n else pieces[order[0]][0]
        for seg in _border_path(p_exit, q_entry, total, frame):
            out.append(seg)
            out_flags.append(True)
        i = j
    if not out:
        return ("drop",)
    segs_out = clamp_pieces(np.asarray(out), w, h)
    # exact joints
    segs_out[1:, 0] = segs_out[:-1, 3]
    segs_out[0, 0] = segs_out[-1, 3]
    return "keep", segs_out, np.asarray(out_flags, bool)


def clamp_pieces(pieces, w, h):
    """Move the on-curve points of inside pieces onto the canvas (they are at most EDGE_EPS
    or a bisection error away); handles may stay outside."""
    p = pieces.copy()
    for k in (0, 3):
        p[:, k, 0] = np.clip(p[:, k, 0], 0.0, w)
        p[:, k, 1] = np.clip(p[:, k, 1], 0.0, h)
    return p


def _sweep_angles(pieces, centre):
    """Angle swept about ``centre`` along each piece (atan2 sense, y down)."""
    pts = evaluate_grid(pieces, np.linspace(0.0, 1.0, 17)) - centre
    ang = np.arctan2(pts[..., 1], pts[..., 0])
    d = np.diff(ang, axis=1)
    d = (d + np.pi) % (2 * np.pi) - np.pi
    return d.sum(axis=1)


def _border_path(p, q, sweep, frame: Frame):
    """Straight segments along the canvas border from p to q, winding round the canvas as an
    excursion that swept ``sweep`` radians did (so that the two paths are homotopic outside
    the canvas)."""
    sp, sq = frame.position(p), frame.position(q)
    ap = frame.angle(sp)
    aq = frame.angle(sq)
    k = round((ap + sweep - aq) / (2 * math.pi))
    sq_lift = sq + k * frame.per
    corners = frame.path(sp, sq_lift)
    if not corners and np.hypot(*(np.asarray(q) - np.asarray(p))) < 1e-12:
        return []  # out and back in at the same point: nothing to add
    pts = [frame.point(sp)] + corners + [frame.point(sq)]
    segs = []
    for a, b in zip(pts[:-1], pts[1:]):
        if np.hypot(*(b - a)) > 1e-12:
            segs.append(line_segment(np.asarray(a, float), np.asarray(b, float)))
    if not segs:
        segs.append(line_segment(np.asarray(pts[0], float), np.asarray(pts[-1], float)))
    # the path must start and end exactly where the kept pieces do
    segs[0][0] = p
    segs[-1][3] = q
    return segs



def clip_contours(contours, flags, w, h):
    """Clip every closed chain (a list of (n, 4, 2) segment arrays and their border flags) to
    the canvas.

    Returns (kept segments, kept flags, keep (C,) bool, winding): the clipped chains of the
    contours that stay, which ones stay, and the number of times the dropped contours wind
    round the canvas (to add to ``base_band``). Contours given as the same array object are
    clipped once.
    """
    frame = Frame(w, h)
    keep_segs, keep_border, keep = [], [], np.zeros(len(contours), bool)
    winding = 0
    clipped = {}  # the frame contours share one array: clip it once
    for k, (sg, bd) in enumerate(zip(contours, flags)):
        if len(sg) == 0:
            continue
        pts = sg.reshape(-1, 2)
        if on_canvas(pts, w, h).all():
            keep_segs.append(clamp_pieces(sg, w, h))
            keep_border.append(bd)
            keep[k] = True
            continue
        if (pts[:, 0] < 0).all() or (pts[:, 0] > w).all() or (pts[:, 1] < 0).all() or (pts[:, 1] > h).all():
            continue  # wholly on one side of the canvas: it cannot wind round it
        if id(sg) not in clipped:
            clipped[id(sg)] = clip_contour(sg, bd, frame)
        res = clipped[id(sg)]
        if res[0] == "keep":
            keep_segs.append(res[1])
            keep_border.append(res[2])
            keep[k] = True
        elif res[0] == "frame":
            winding += res[1]
    return keep_segs, keep_border, keep, winding
