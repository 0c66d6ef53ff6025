"""Warping a vector image (paper §6): the contours move, no pixel is resampled.

    warp(vi, transform)  ->  per channel:
        move the chains (affine: control points exactly; other maps: subdivided until the
        moved chain stays within ``tolerance`` of the exact image of the curve)
        ->  reverse them if the map is a reflection (the >= side must stay on the left)
        ->  frame: where the moved image does not cover the canvas, the uncovered regions
            become a background band (below)
        ->  clip to the canvas, closing along its border (border flags set there)
        ->  move the caps; re-home those whose point left the canvas

Transforms are forward point maps, source pixels -> output pixels, in the coordinates of
model.py (x right, y down, origin at the top-left corner; a pixel's centre at +0.5):
:class:`Affine` (rotation, scaling, shear, translation, reflection), :class:`Perspective`
(a homography, e.g. from four corner points) and :class:`Swirl` ship here; any callable
that maps an (N, 2) array of points to an (N, 2) array works too (:class:`PointMap`), as long
as it is smooth and one-to-one on the image.

Exactness
    An affine map sends a cubic Bezier to the cubic whose control points are the mapped
    control points: chains move exactly. Any other map sends it to a curve that is not a
    cubic; each segment is then replaced by Hermite cubics (the mapped end points, the
    end tangents mapped by the map's Jacobian) and split in half until every piece is within
    ``tolerance`` output pixels of the exact mapped curve (checked at t = 1/4, 1/2, 3/4).
    Border segments (straight, not isolines) are split until their chords are within the
    tolerance, since the renderer draws them as chords.

The canvas
    ``canvas="same"`` keeps the source's width and height (a rotation about the centre turns
    the picture inside a fixed frame, as scikit-image's ``rotate`` does); ``"fit"`` grows the
    canvas to the bounding box of the moved image and shifts it there (nothing is cut off,
    like Pillow's ``rotate(expand=True)``); ``(width, height)`` names it.

    Whatever leaves the canvas is clipped: every contour is cut where it crosses the canvas
    border and each outside excursion is replaced by a path along the border that winds
    round the canvas as the excursion did, so the winding numbers (and so the bands) of
    every point of the canvas are unchanged. Those border paths carry border flags, like
    the frame stretches of the encoder, so they are never isolines. Contours that leave the
    canvas entirely vanish, or, if they enclose it, become part of ``base_band``.

Uncovered regions
    Where the moved picture does not reach (the corners of a rotated image, the outside of
    a perspective) the output is filled with a flat ``background`` colour (black by
    default; transparent in an alpha channel). Each channel gains one level beyond its ends
    (below the first level, or above the last when the first sits at 0) and the moved frame
    of the source becomes border contours of that level and of the levels the root band was
    above (the "frame-only" levels the encoder leaves out). The uncovered regions are then a
    band of their own whose contours are all border stretches: a region with no isoline
    source, so the renderer fills it with its cap value, and a cap annotation with the
    background value is placed in each uncovered component (at its innermost pixel).

Caps
    A cap's point moves with the map. A cap whose point falls off the canvas while part of
    its region stays on it is re-homed: the region's pixels (found on a band map of the
    source) are mapped, and the one deepest inside the canvas becomes the cap's point; a
    cap whose region left the canvas altogether is dropped.

The ramp of a cap profile is the channel's cap_ramp (CAP_RAMP unless set; DOME stays
DOME) in output pixels after a warp (it is a property of the picture, model.py), so an enlarging warp has sharper cap shoulders than rendering the
unwarped image at a larger scale; to enlarge without any other change, render with
``scale``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..colour import rgb_to_yuv
from ..errors import OptionError
from ..shared.grid import QUANT  # coordinates are stored on the file's grid
from ..model import Channel, VectorImage

DEFAULT_TOLERANCE = 0.02  # output pixels: the error of a moved curve (encoder ribbons are >= 0.05)
MAX_DEPTH = 18  # halvings of one segment at most (2**-18 of a segment)
EDGE_EPS = 1e-6  # pixels: points this close outside the canvas count as on its border
BACKGROUND_GAP = 0.25  # grey levels between the background's new level and its neighbours
JACOBIAN_STEP = 1e-3  # pixels: central differences of a PointMap without a Jacobian


# =============================================================================================
# Transforms
# =============================================================================================


class Transform:
    """A forward point map, source pixels -> output pixels (model.py coordinates)."""

    affine = False

    def __call__(self, pts: np.ndarray) -> np.ndarray:  # (N, 2) -> (N, 2)
        raise NotImplementedError

    def jacobian(self, pts: np.ndarray) -> np.ndarray:
        """(N, 2, 2): d(out)/d(in) at each point; central differences unless overridden."""
        h = JACOBIAN_STEP
        cols = []
        for k in range(2):
            d = np.zeros(2)
            d[k] = h
            cols.append((self(pts + d) - self(pts - d)) / (2 * h))
        return np.stack(cols, axis=2)

    def then(self, other: "Transform") -> "Transform":
        """This map followed by ``other``."""
        if isinstance(self, Affine) and isinstance(other, Affine):
            return Affine(other.matrix3() @ self.matrix3())
        if isinstance(self, (Affine, Perspective)) and isinstance(other, (Affine, Perspective)):
            return Perspective(other.matrix3() @ self.matrix3())
        return PointMap(lambda p: other(self(p)))


@dataclass(frozen=True)
class Affine(Transform):
    """x' = a x + b y + c, y' = d x + e y + f (``matrix`` is [[a, b, c], [d, e, f]] or 3 x 3)."""

    matrix: np.ndarray

    affine = True

    def __post_init__(self):
        m = np.asarray(self.matrix, dtype=np.float64)
        if m.shape == (3, 3):
            m = m[:2]
        if m.shape != (2, 3) or not np.all(np.isfinite(m)):
            raise OptionError("an affine map needs six finite numbers a, b, c, d, e, f")
        if abs(np.linalg.det(m[:, :2])) < 1e-12:
            raise OptionError("the affine map is singular (it flattens the image)")
        object.__setattr__(self, "matrix", m)

    def matrix3(self) -> np.ndarray:
        return np.vstack([self.matrix, [0.0, 0.0, 1.0]])

    def __call__(self, pts):
        pts = np.asarray(pts, dtype=np.float64)
        return pts @ self.matrix[:, :2].T + self.matrix[:, 2]

    def jacobian(self, pts):
        return np.broadcast_to(self.matrix[:, :2], (len(pts), 2, 2)).copy()

    def inverse(self) -> "Affine":
        return Affine(np.linalg.inv(self.matrix3()))

    @property
    def determinant(self) -> float:
        return float(np.linalg.det(self.matrix[:, :2]))


@dataclass(frozen=True)
class Perspective(Transform):
    """A homography: (x', y') = (H [x, y, 1])[:2] / (H [x, y, 1])[2]."""

    matrix: np.ndarray

    def __post_init__(self):
        m = np.asarray(self.matrix, dtype=np.float64)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)) or abs(np.linalg.det(m)) < 1e-15:
            raise OptionError("a perspective map needs a non-singular 3 x 3 matrix")
        object.__setattr__(self, "matrix", m / (m[2, 2] if abs(m[2, 2]) > 1e-15 else 1.0))

    def matrix3(self) -> np.ndarray:
        return self.matrix

    def __call__(self, pts):
        pts = np.asarray(pts, dtype=np.float64)
        q = pts @ self.matrix[:, :2].T + self.matrix[:, 2]
        return q[:, :2] / q[:, 2:3]

    def jacobian(self, pts):
        pts = np.asarray(pts, dtype=np.float64)
        q = pts @ self.matrix[:, :2].T + self.matrix[:, 2]
        w = q[:, 2:3]
        out = q[:, :2] / w
        # d(u/w) = (du - out dw) / w
        return (self.matrix[None, :2, :2] - out[:, :, None] * self.matrix[None, 2:3, :2]) / w[:, :, None]

    def inverse(self) -> "Perspective":
        return Perspective(np.linalg.inv(self.matrix))

    def check_frame(self, width, height) -> None:
        """The frame must stay on one side of the horizon (w > 0 at its corners)."""
        corners = np.array([[0, 0], [width, 0], [width, height], [0, height]], float)
        w = corners @ self.matrix[2, :2] + self.matrix[2, 2]
        if not (np.all(w > 1e-9) or np.all(w < -1e-9)):
            raise OptionError("the perspective map sends part of the image to infinity (the horizon crosses it)")


@dataclass(frozen=True)
class Swirl(Transform):
    """The swirl of scikit-image's ``transform.swirl`` (same parameters, same picture), as a
    forward map: a point at distance rho from ``centre`` turns by
    -strength * exp(-rho / (radius * ln 2 / 5)) radians (plus ``rotation``, in radians)."""

    centre: tuple
    strength: float
    radius: float
    rotation: float = 0.0

    def __call__(self, pts):
        pts = np.asarray(pts, dtype=np.float64)
        cx, cy = self.centre
        dx, dy = pts[:, 0] - cx, pts[:, 1] - cy
        rho = np.hypot(dx, dy)
        r = self.radius / 5.0 * math.log(2.0)
        theta = np.arctan2(dy, dx) - self.rotation - self.strength * np.exp(-rho / r)
        return np.column_stack([cx + rho * np.cos(theta), cy + rho * np.sin(theta)])

    def inverse_map(self, pts):
        """The output -> source map (what a raster warp needs)."""
        return replace(self, strength=-self.strength, rotation=-self.rotation)(pts)


class PointMap(Transform):
    """Any smooth one-to-one callable ``fn((N, 2) points) -> (N, 2) points`` as a Transform;
    ``jacobian`` (optional) gives its (N, 2, 2) derivative, else central differences."""

    def __init__(self, fn, jacobian=None):
        if not callable(fn):
            raise OptionError("a point map must be callable")
        self.fn = fn
        self._jac = jacobian

    def __call__(self, pts):
        out = np.asarray(self.fn(np.asarray(pts, dtype=np.float64)), dtype=np.float64)
        if out.shape != np.shape(pts):
            raise OptionError(f"the point map returned shape {out.shape} for {np.shape(pts)} points")
        return out

    def jacobian(self, pts):
        if self._jac is not None:
            return np.asarray(self._jac(pts), dtype=np.float64)
        return super().jacobian(pts)


def rotation(degrees: float, centre) -> Affine:
    """Rotation by ``degrees`` about ``centre`` (x, y), counter-clockwise on screen for
    positive angles, as scikit-image's ``transform.rotate`` and Pillow's ``rotate``."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    cx, cy = centre
    # (dx, dy) -> (c dx + s dy, -s dx + c dy): a point right of the centre moves up (y down)
    return Affine([[c, s, cx - c * cx - s * cy], [-s, c, cy + s * cx - c * cy]])


def perspective_from_points(src, dst) -> Perspective:
    """The homography that sends the four points ``src`` to ``dst`` ((4, 2) each)."""
    src = np.asarray(src, dtype=np.float64).reshape(4, 2)
    dst = np.asarray(dst, dtype=np.float64).reshape(4, 2)
    rows, rhs = [], []
    for (x, y), (u, v) in zip(src, dst):
        rows.append([x, y, 1, 0, 0, 0, -u * x, -u * y])
        rows.append([0, 0, 0, x, y, 1, -v * x, -v * y])
        rhs += [u, v]
    a = np.asarray(rows)
    if abs(np.linalg.det(a)) < 1e-12:
        raise OptionError("the four points are degenerate (three on a line?)")
    h = np.linalg.solve(a, np.asarray(rhs))
    return Perspective(np.append(h, 1.0).reshape(3, 3))


def as_transform(t) -> Transform:
    if isinstance(t, Transform):
        return t
    if callable(t):
        return PointMap(t)
    m = np.asarray(t, dtype=np.float64)
    if m.shape in ((2, 3),) or m.size == 6:
        return Affine(m.reshape(2, 3))
    if m.shape == (3, 3) or m.size == 9:
        m = m.reshape(3, 3)
        return Affine(m) if np.allclose(m[2], [0, 0, 1]) else Perspective(m)
    raise OptionError("a transform is a Transform, a callable point map, or a 2 x 3 / 3 x 3 matrix")


# =============================================================================================
# Moving chains
# =============================================================================================


def _segments(points, offsets):
    """(S, 4, 2) segments of concatenated chains, and (S,) owning contour."""
    counts = (np.diff(offsets) - 1) // 3
    n = int(counts.sum())
    if n == 0:
        return np.zeros((0, 4, 2)), np.zeros(0, np.int64)
    within = np.arange(n) - np.repeat(np.cumsum(counts) - counts, counts)
    first = np.repeat(offsets[:-1], counts) + 3 * within
    return points[first[:, None] + np.arange(4)], np.repeat(np.arange(len(counts)), counts)


def _chains(segs, seg_contour, n_contours):
    """Inverse of _segments: (points, offsets) from segments in contour order."""
    counts = np.bincount(seg_contour, minlength=n_contours)
    if len(segs) == 0:
        return np.zeros((0, 2)), np.zeros(n_contours + 1, np.int64)
    body = segs[:, :3].reshape(-1, 2)
    # each contour: its segments' first three points, then the closing point
    ends = np.cumsum(counts)
    pieces_start = np.concatenate([[0], ends[:-1]])
    out, offs = [], [0]
    for k in range(n_contours):
        if counts[k] == 0:
            offs.append(offs[-1])
            continue
        a, b = pieces_start[k], ends[k]
        out.append(body[3 * a : 3 * b])
        out.append(segs[b - 1, 3][None])
        offs.append(offs[-1] + 3 * (b - a) + 1)
    return np.vstack(out), np.asarray(offs, np.int64)


def _blossom(seg, u1, u2, u3):
    """Polar form of cubics (M, 4, 2) at per-row parameters (M,)."""
    p = seg
    for u in (u1, u2, u3):
        p = (1.0 - u)[:, None, None] * p[:, :-1] + u[:, None, None] * p[:, 1:]
    return p[:, 0]


def _subsegment(seg, t0, t1):
    """Control points of the cubics restricted to [t0, t1]."""
    return np.stack(
        [_blossom(seg, t0, t0, t0), _blossom(seg, t0, t0, t1), _blossom(seg, t0, t1, t1), _blossom(seg, t1, t1, t1)],
        axis=1,
    )


def _bezier(seg, t):
    """Points of cubics (M, 4, 2) at per-row t (M,)."""
    u = 1.0 - t
    w = np.stack([u**3, 3 * u * u * t, 3 * u * t * t, t**3], axis=1)
    return np.einsum("mk,mkd->md", w, seg)


def move_segments(segs, border, transform: Transform, tol: float):
    """Map segments through a non-affine transform within ``tol``.

    Returns (new_segs (P, 4, 2), new_border (P,), source_index (P,)), pieces in chain order.
    """
    n = len(segs)
    if n == 0:
        return segs.copy(), border.copy(), np.zeros(0, np.int64)
    sid = np.arange(n)
    t0 = np.zeros(n)
    t1 = np.ones(n)
    out_seg, out_id, out_t0 = [], [], []
    probe = np.array([0.25, 0.5, 0.75])
    for depth in range(MAX_DEPTH + 1):
        if len(sid) == 0:
            break
        sub = _subsegment(segs[sid], t0, t1)
        brd = border[sid]
        a, d = transform(sub[:, 0]), transform(sub[:, 3])
        new = np.empty_like(sub)
        new[:, 0], new[:, 3] = a, d
        curved = ~brd
        if curved.any():
            ja = transform.jacobian(sub[curved, 0])
            jd = transform.jacobian(sub[curved, 3])
            new[curved, 1] = a[curved] + np.einsum("mij,mj->mi", ja, sub[curved, 1] - sub[curved, 0])
            new[curved, 2] = d[curved] + np.einsum("mij,mj->mi", jd, sub[curved, 2] - sub[curved, 3])
        new[brd, 1] = a[brd] + (d[brd] - a[brd]) / 3.0
        new[brd, 2] = a[brd] + 2.0 * (d[brd] - a[brd]) / 3.0
        err = np.zeros(len(sid))
        for t in probe:
            tt = np.full(len(sid), t)
            exact = transform(_bezier(sub, tt))
            err = np.maximum(err, np.hypot(*(exact - _bezier(new, tt)).T))
        ok = (err <= tol) | (depth == MAX_DEPTH) | ~np.isfinite(err)
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


# =============================================================================================
# Clipping to the canvas
# =============================================================================================


class _Frame:
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


def _line_segment(a, b):
    return np.array([a, a + (b - a) / 3.0, a + 2.0 * (b - a) / 3.0, b])


def _split_at_border(segs, border, w, h):
    """Cut cubics where they cross x = 0, x = w, y = 0 or y = h.

    Crossings are bracketed on 32 steps of t and refined by bisection (vectorised); a curve
    that pokes out and back within one step is not cut, and its piece is then judged by its
    middle. Returns (pieces (P, 4, 2), their border flags (P,)), in chain order.
    """
    m = len(segs)
    ts = np.linspace(0.0, 1.0, 33)
    u = 1.0 - ts
    basis = np.stack([u**3, 3 * u * u * ts, 3 * u * ts * ts, ts**3], axis=1)
    pts = np.einsum("tk,mkd->mtd", basis, segs)
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
        out_a = sgn * (_bezier(segs[seg_i], a)[rows, axis_i] - value) > 0
        for _ in range(52):
            mid = 0.5 * (a + b)
            out_m = sgn * (_bezier(segs[seg_i], mid)[rows, axis_i] - value) > 0
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
    return _subsegment(segs[sid], t0, t1), border[sid]


def _inside(p, w, h, eps=EDGE_EPS):
    return (-eps <= p[..., 0]) & (p[..., 0] <= w + eps) & (-eps <= p[..., 1]) & (p[..., 1] <= h + eps)


def _clip_contour(segs, border, frame: _Frame):
    """Clip one closed chain to the canvas.

    Returns ("keep", segs, border) with the clipped chain, ("drop",) if it vanished, or
    ("frame", winding) if it lies outside and winds round the canvas ``winding`` times (in
    the renderer's sense: +1 adds one to the band of every point of the canvas).
    """
    w, h = frame.w, frame.h
    pieces, flags = _split_at_border(segs, np.asarray(border, bool), w, h)
    mids = _bezier(pieces, np.full(len(pieces), 0.5))
    inside = _inside(mids, w, h)
    if inside.all():
        return "keep", _clamp_pieces(pieces, w, h), flags
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
    segs_out = _clamp_pieces(np.asarray(out), w, h)
    # exact joints
    segs_out[1:, 0] = segs_out[:-1, 3]
    segs_out[0, 0] = segs_out[-1, 3]
    return "keep", segs_out, np.asarray(out_flags, bool)


def _clamp_pieces(pieces, w, h):
    """Move the on-curve points of inside pieces onto the canvas (they are at most EDGE_EPS
    or a bisection error away); handles may stay outside."""
    p = pieces.copy()
    for k in (0, 3):
        p[:, k, 0] = np.clip(p[:, k, 0], 0.0, w)
        p[:, k, 1] = np.clip(p[:, k, 1], 0.0, h)
    return p


def _sweep_angles(pieces, centre):
    """Angle swept about ``centre`` along each piece (atan2 sense, y down)."""
    ts = np.linspace(0.0, 1.0, 17)
    u = 1.0 - ts
    basis = np.stack([u**3, 3 * u * u * ts, 3 * u * ts * ts, ts**3], axis=1)
    pts = np.einsum("tk,mkd->mtd", basis, pieces) - centre
    ang = np.arctan2(pts[..., 1], pts[..., 0])
    d = np.diff(ang, axis=1)
    d = (d + np.pi) % (2 * np.pi) - np.pi
    return d.sum(axis=1)


def _border_path(p, q, sweep, frame: _Frame):
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
            segs.append(_line_segment(np.asarray(a, float), np.asarray(b, float)))
    if not segs:
        segs.append(_line_segment(np.asarray(pts[0], float), np.asarray(pts[-1], float)))
    # the path must start and end exactly where the kept pieces do
    segs[0][0] = p
    segs[-1][3] = q
    return segs


# =============================================================================================
# Band maps (pixel centres), for coverage and for re-homing caps
# =============================================================================================


def winding_map(x0, y0, x1, y1, width, height):
    """(height, width) int32: sum of edge windings at every pixel centre (the renderer's
    rule: an edge going down adds +1 to the samples on its right)."""
    delta = np.zeros((height, width + 1), np.int64)
    lo, hi = np.minimum(y0, y1), np.maximum(y0, y1)
    dw = np.where(y1 > y0, 1, -1)
    i0 = np.clip(np.ceil(lo - 0.5), 0, height).astype(np.int64)
    i1 = np.clip(np.ceil(hi - 0.5), 0, height).astype(np.int64)
    cnt = np.maximum(i1 - i0, 0)
    cnt[y0 == y1] = 0
    if cnt.sum():
        e = np.repeat(np.arange(len(x0)), cnt)
        i = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt) + i0[e]
        yc = i + 0.5
        x = x0[e] + (yc - y0[e]) * (x1[e] - x0[e]) / (y1[e] - y0[e])
        k = np.clip(np.floor(x + 0.5), 0, width).astype(np.int64)
        np.add.at(delta, (i, k), dw[e])
    return np.cumsum(delta, axis=1)[:, :width].astype(np.int32)


def _edges(channel: Channel, tol: float = 0.05):
    from ..geometry import flatten, segments

    segs, border = segments(channel)
    x0, y0, x1, y1, _ = flatten(segs, border, tol)
    return x0, y0, x1, y1


def band_map(channel: Channel, width: int, height: int) -> np.ndarray:
    """(height, width) band of every pixel centre (base_band + windings)."""
    return winding_map(*_edges(channel), width, height) + channel.base_band


# =============================================================================================
# The operation
# =============================================================================================


def output_canvas(vi: VectorImage, transform: Transform, canvas):
    """(transform, width, height): the transform shifted onto the chosen canvas."""
    if isinstance(canvas, str) and canvas == "same":
        return transform, vi.width, vi.height
    if isinstance(canvas, str) and canvas == "fit":
        frame = _frame_chain(vi.width, vi.height)
        segs, _ = _segments(frame, np.array([0, len(frame)]))
        if transform.affine:
            moved = transform(frame)
        else:
            ms, _, _ = move_segments(segs, np.ones(len(segs), bool), transform, 0.05)
            moved = ms.reshape(-1, 2)
        lo = moved.min(axis=0)
        size = np.ceil(moved.max(axis=0) - lo - 1e-6)
        shift = Affine([[1, 0, -lo[0]], [0, 1, -lo[1]]])
        w, h = int(max(1, size[0])), int(max(1, size[1]))
        return transform.then(shift), w, h
    try:
        w, h = (int(v) for v in canvas)
    except (TypeError, ValueError):
        raise OptionError(f"canvas must be 'same', 'fit' or (width, height), got {canvas!r}") from None
    if w < 1 or h < 1:
        raise OptionError(f"canvas {w}x{h} is empty")
    return transform, w, h


def _frame_chain(w, h, subdivide: int = 1):
    """The source frame as a closed chain of border segments, running counter-clockwise on
    screen (its inside on its left), each side cut into ``subdivide`` pieces."""
    corners = np.array([[0, 0], [0, h], [w, h], [w, 0], [0, 0]], float)
    pts = [corners[0]]
    for a, b in zip(corners[:-1], corners[1:]):
        for k in range(subdivide):
            s0, s1 = a + (b - a) * k / subdivide, a + (b - a) * (k + 1) / subdivide
            pts += [s0 + (s1 - s0) / 3, s0 + 2 * (s1 - s0) / 3, s1]
    return np.asarray(pts)


def background_values(vi: VectorImage, background) -> dict:
    """Channel name -> the value of the flat background, from an RGB colour on 0..255."""
    rgb = np.asarray(background, dtype=np.float64).reshape(-1)
    if rgb.size == 1:
        rgb = np.repeat(rgb, 3)
    if rgb.size != 3 or not np.all((rgb >= 0) & (rgb <= 255)):
        raise OptionError("background must be an R,G,B colour on 0..255 (or one grey value)")
    yuv = rgb_to_yuv(rgb[None])[0] if vi.colour == "yuv" else np.array([rgb @ [0.299, 0.587, 0.114], 128, 128])
    return {"Y": float(yuv[0]), "U": float(yuv[1]), "V": float(yuv[2]), "A": 0.0}


def warp(vi: VectorImage, transform, canvas="same", background=(0, 0, 0),
         tolerance: float = DEFAULT_TOLERANCE) -> VectorImage:
    """Warp a vector image: its contours and caps move, nothing is resampled.

    Parameters
    ----------
    vi : VectorImage
    transform : Transform, callable, or 2 x 3 / 3 x 3 matrix
        Forward map from source pixels to output pixels (see the module docstring).
    canvas : "same", "fit" or (width, height)
        The output canvas (module docstring).
    background : (R, G, B) on 0..255
        Colour of the regions the moved picture does not cover (alpha 0 there when the image
        has an alpha channel).
    tolerance : float
        Largest distance, in output pixels, between a moved curve and the exact image of
        the source curve (non-affine maps only; affine maps are exact).

    Returns
    -------
    VectorImage on the output canvas.
    """
    if not isinstance(vi, VectorImage):
        raise OptionError(f"expected a VectorImage, got {type(vi).__name__}")
    if not (tolerance > 0):
        raise OptionError("tolerance must be positive")
    t = as_transform(transform)
    if isinstance(t, Perspective):
        t.check_frame(vi.width, vi.height)
    t, w, h = output_canvas(vi, t, canvas)
    if w * h > 400_000_000:
        raise OptionError(f"output canvas {w}x{h} is too large")
    reflect = _orientation(t, vi) < 0
    frame_src = _frame_chain(vi.width, vi.height, 1 if t.affine else 8)
    frame_segs, _ = _segments(frame_src, np.array([0, len(frame_src)]))
    frame_border = np.ones(len(frame_segs), bool)
    if t.affine:
        moved_frame = t(frame_segs.reshape(-1, 2)).reshape(-1, 4, 2)
    else:
        moved_frame, _, _ = move_segments(frame_segs, frame_border, t, tolerance)
    if reflect:
        moved_frame = moved_frame[::-1, ::-1]
    fx = moved_frame[:, [0, 3]]
    cover = winding_map(fx[:, 0, 0], fx[:, 0, 1], fx[:, 1, 0], fx[:, 1, 1], w, h) != 0
    backgrounds = background_values(vi, background)
    channels = tuple(
        _warp_channel(ch, vi, t, w, h, reflect, moved_frame, cover, backgrounds[ch.name], tolerance)
        for ch in vi.channels
    )
    for ch in channels:
        if not (np.isfinite(ch.points).all() and np.isfinite(ch.cap_xy).all()):
            raise OptionError("the point map sent part of the image to a non-finite position")
    return VectorImage(width=w, height=h, colour=vi.colour, channels=channels,
                       source_depth=vi.source_depth, meta=dict(vi.meta))


def _orientation(t: Transform, vi: VectorImage) -> float:
    if isinstance(t, Affine):
        return t.determinant
    c = np.array([[vi.width / 2.0, vi.height / 2.0]])
    return float(np.linalg.det(t.jacobian(c)[0]))


def _move_channel_segments(ch: Channel, t: Transform, reflect: bool, tol: float):
    segs, owner = _segments(ch.points, ch.offsets)
    border = ch.border.copy()
    if t.affine:
        moved = t(segs.reshape(-1, 2)).reshape(-1, 4, 2) if len(segs) else segs
        new_owner, new_border = owner, border
    else:
        moved, new_border, src = move_segments(segs, border, t, tol)
        new_owner = owner[src]
    if reflect and len(moved):
        # reverse every contour: segments in reverse order, each one reversed
        order = np.lexsort((-np.arange(len(moved)), new_owner))
        moved = moved[order][:, ::-1]
        new_border = new_border[order]
        new_owner = new_owner[order]
    return moved, new_border, new_owner


def _warp_channel(ch, vi, t, w, h, reflect, moved_frame, cover, bg_value, tol) -> Channel:
    moved, border, owner = _move_channel_segments(ch, t, reflect, tol)
    C = ch.n_contours
    levels = ch.levels.copy()
    contour_level = ch.contour_level.astype(np.int64).copy()
    parent = ch.parent.astype(np.int64).copy()
    cap_band = ch.cap_band.astype(np.int64).copy()
    base_band = int(ch.base_band)
    uncovered = not cover.all()
    extra_segs, extra_level, extra_parent = [], [], []
    bg_band = None
    if uncovered:
        L = levels.shape[0]
        # the background band: below everything (new level 0), or above everything; on the
        # side where the background value lies beyond the levels if there is one (then the
        # new level can sit next to the background value, see BACKGROUND_GAP), else on the
        # side that needs fewer frame contours
        below_room = L == 0 or levels[0] > 2 * BACKGROUND_GAP
        above_room = L == 0 or levels[-1] < 255.0 - 2 * BACKGROUND_GAP
        n_below, n_above = base_band + 1, L - base_band + 1
        if L and bg_value < levels[0] and below_room:
            use_below = True
        elif L and bg_value > levels[-1] and above_room:
            use_below = False
        else:
            use_below = below_room and (n_below <= n_above or not above_room)
        frame_rev = moved_frame[::-1, ::-1]  # the frame with its inside on its right
        if use_below:
            new_level = (min(max(bg_value, BACKGROUND_GAP), levels[0] - BACKGROUND_GAP) if L
                         else min(max(bg_value, BACKGROUND_GAP), 255.0 - BACKGROUND_GAP))
            levels = np.concatenate([[new_level], levels])
            contour_level += 1
            cap_band += 1
            # frame contours for new levels 0 .. base_band: inside on the left adds +1 each
            for k in range(base_band + 1):
                extra_segs.append(moved_frame)
                extra_level.append(k)
            base_band, bg_band = 0, 0
        else:
            new_level = min(max(bg_value, levels[-1] + BACKGROUND_GAP), 255.0 - BACKGROUND_GAP)
            levels = np.concatenate([levels, [new_level]])
            # frame contours for levels base_band .. L (new indices), inside below: -1 each
            for k in range(base_band, L + 1):
                extra_segs.append(frame_rev)
                extra_level.append(k)
            base_band = bg_band = L + 1
    # assemble contours: the old ones, then the frame contours (their parents chain);
    # owner is sorted by contour
    all_segs = []
    if C:
        splits = np.searchsorted(owner, np.arange(1, C))
        all_segs = np.split(moved, splits)
        all_border = np.split(border, splits)
    else:
        all_border = []
    first_frame = C
    for i, fs in enumerate(extra_segs):
        all_segs.append(fs)
        all_border.append(np.ones(len(fs), bool))
        extra_parent.append(-1 if i == 0 else first_frame + i - 1)
    if extra_segs:
        innermost = first_frame + len(extra_segs) - 1
        parent = np.where(parent == -1, innermost, parent)
    contour_level = np.concatenate([contour_level, np.asarray(extra_level, np.int64)])
    parent = np.concatenate([parent, np.asarray(extra_parent, np.int64)])
    # clip to the canvas
    frame = _Frame(w, h)
    keep_segs, keep_border, keep = [], [], np.zeros(len(all_segs), bool)
    clipped = {}  # the frame contours share one array: clip it once
    for k, (sg, bd) in enumerate(zip(all_segs, all_border)):
        if len(sg) == 0:
            continue
        pts = sg.reshape(-1, 2)
        if _inside(pts, w, h).all():
            keep_segs.append(_clamp_pieces(sg, w, h))
            keep_border.append(bd)
            keep[k] = True
            continue
        if (pts[:, 0] < 0).all() or (pts[:, 0] > w).all() or (pts[:, 1] < 0).all() or (pts[:, 1] > h).all():
            continue  # wholly on one side of the canvas: it cannot wind round it
        if id(sg) not in clipped:
            clipped[id(sg)] = _clip_contour(sg, bd, frame)
        res = clipped[id(sg)]
        if res[0] == "keep":
            keep_segs.append(res[1])
            keep_border.append(res[2])
            keep[k] = True
        elif res[0] == "frame":
            base_band += res[1]
    new_index = np.full(len(all_segs), -1, np.int64)
    new_index[keep] = np.arange(int(keep.sum()))

    def remap(idx):
        """Index of the nearest kept ancestor (or the contour itself), -1 for the frame."""
        out = np.asarray(idx, np.int64).copy()
        for _ in range(len(all_segs) + 1):
            bad = (out >= 0) & (new_index[np.maximum(out, 0)] < 0)
            if not bad.any():
                break
            out[bad] = parent[out[bad]]
        return np.where(out >= 0, new_index[np.maximum(out, 0)], -1)

    new_parent = remap(parent[keep])
    if keep_segs:
        segs_all = np.concatenate(keep_segs)
        owner_all = np.repeat(np.arange(len(keep_segs)), [len(s) for s in keep_segs])
        points, offsets = _chains(segs_all, owner_all, len(keep_segs))
        border_all = np.concatenate(keep_border)
    else:
        points, offsets, border_all = np.zeros((0, 2)), np.zeros(1, np.int64), np.zeros(0, bool)
    points = np.round(points * QUANT) / QUANT
    # closure after rounding: the closing point equals the first
    for k in range(len(offsets) - 1):
        points[offsets[k + 1] - 1] = points[offsets[k]]
    L_new = levels.shape[0]
    base_band = int(min(max(base_band, 0), L_new))
    out = Channel(
        name=ch.name,
        levels=levels,
        contour_level=contour_level[keep].astype(np.int32),
        offsets=offsets,
        points=points,
        border=border_all,
        parent=new_parent.astype(np.int32),
        cap_band=np.zeros(0, np.int32),
        cap_contour=np.zeros(0, np.int32),
        cap_xy=np.zeros((0, 2)),
        cap_value=np.zeros(0),
        base_band=base_band,
        tone=ch.tone,  # a value curve (equalisation's): the geometry moves, the values stay
        cap_ramp=ch.cap_ramp,  # in output pixels, as the module docstring says; DOME stays DOME
    )
    # caps
    cap_xy, cap_keep = _move_caps(ch, vi, t, w, h)
    cap_contour = remap(ch.cap_contour.astype(np.int64))
    xy = [cap_xy[cap_keep]]
    cb = [cap_band[cap_keep]]
    cc = [cap_contour[cap_keep]]
    cv = [ch.cap_value[cap_keep]]
    if uncovered:
        pts = _background_points(cover)
        xy.append(pts)
        cb.append(np.full(len(pts), bg_band, np.int64))
        cc.append(np.full(len(pts), -1, np.int64))
        cv.append(np.full(len(pts), np.round(bg_value * QUANT) / QUANT))
    cap_xy = np.round(np.concatenate(xy) * QUANT) / QUANT
    return replace(
        out,
        cap_band=np.concatenate(cb).astype(np.int32),
        cap_contour=np.concatenate(cc).astype(np.int32),
        cap_xy=cap_xy.reshape(-1, 2),
        cap_value=np.concatenate(cv).astype(np.float64),
    )


def _background_points(cover: np.ndarray) -> np.ndarray:
    """One point per uncovered component: its pixel farthest from the covered part."""
    from scipy import ndimage

    lab, n = ndimage.label(~cover)
    if n == 0:
        return np.zeros((0, 2))
    dist = ndimage.distance_transform_edt(~cover)
    idx = ndimage.maximum_position(dist, lab, index=np.arange(1, n + 1))
    return np.array([[j + 0.5, i + 0.5] for i, j in idx], float).reshape(-1, 2)


CAP_MARGIN = 0.5  # pixels: a re-homed cap point lies at least this far inside the canvas


def _move_caps(ch: Channel, vi: VectorImage, t: Transform, w: int, h: int):
    """(K, 2) moved cap points and (K,) bool: the caps that stay."""
    k = ch.cap_xy.shape[0]
    if k == 0:
        return np.zeros((0, 2)), np.zeros(0, bool)
    xy = t(ch.cap_xy)
    ok = np.isfinite(xy).all(axis=1) & (xy[:, 0] >= 0) & (xy[:, 0] <= w) & (xy[:, 1] >= 0) & (xy[:, 1] <= h)
    lost = np.flatnonzero(~ok)
    if lost.size:
        xy, ok = _rehome_caps(ch, vi, t, w, h, xy, ok, lost)
    return xy, ok


def _rehome_caps(ch, vi, t, w, h, xy, ok, lost):
    """Caps whose point left the canvas: find the pixel of their source region that lands
    deepest inside the canvas."""
    from scipy import ndimage

    bands = band_map(ch, vi.width, vi.height)
    labelled = {}  # band -> (labels, pixel order, starts): components of that band
    xy = xy.copy()
    ok = ok.copy()
    for c in lost:
        x, y = ch.cap_xy[c]
        b = int(ch.cap_band[c])
        # the cap's sample, or a neighbour in its band (cap points sit on half pixels)
        i0, j0 = int(math.floor(y)), int(math.floor(x))
        cands = [(i, j) for i in (i0, i0 - 1, i0 + 1) for j in (j0, j0 - 1, j0 + 1)
                 if 0 <= i < vi.height and 0 <= j < vi.width and bands[i, j] == b]
        if not cands:
            continue
        if b not in labelled:
            lab, n = ndimage.label(bands == b)
            flat = lab.ravel()
            order = np.argsort(flat, kind="stable")
            labelled[b] = (lab, order, np.searchsorted(flat[order], np.arange(n + 2)))
        lab, order, starts = labelled[b]
        r = lab[cands[0]]
        pix = order[starts[r] : starts[r + 1]]
        if len(pix) > 20000:
            pix = pix[:: len(pix) // 20000 + 1]
        q = t(np.column_stack([pix % vi.width + 0.5, pix // vi.width + 0.5]))
        depth = np.minimum(np.minimum(q[:, 0], w - q[:, 0]), np.minimum(q[:, 1], h - q[:, 1]))
        best = int(np.argmax(depth))
        if depth[best] >= CAP_MARGIN:
            xy[c] = q[best]
            ok[c] = True
    return xy, ok


def scale(vi: VectorImage, factor: float) -> VectorImage:
    """The image enlarged or reduced by ``factor`` as a new vector image (an exact affine
    warp onto a canvas of round(factor * size)). To render at another size, prefer
    ``vi.render(scale=...)``: same contours, and cap ramps in source pixels."""
    if not (factor > 0 and math.isfinite(factor)):
        raise OptionError("scale factor must be positive")
    w, h = max(1, round(vi.width * factor)), max(1, round(vi.height * factor))
    return warp(vi, Affine([[w / vi.width, 0, 0], [0, h / vi.height, 0]]), canvas=(w, h))
