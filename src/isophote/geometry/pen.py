"""A pen protocol for a channel's contours, in the spirit of fontTools' ``basePen``.

A pen receives closed contours as ``moveTo(pt)``, then ``curveTo(c1, c2, pt)`` for an isoline
segment or ``lineTo(pt)`` for a border segment (straight, along the image frame), then
``closePath()``. ``draw(channel, pen)`` (or ``channel.draw(pen)``) draws every contour of a
channel in order.

Contours are many (a photograph has 10^5 segments), so the protocol has a batched door too:
``pen.add_segments(segs, border, owner)`` takes (S, 4, 2) control points, (S,) border flags and
(S,) owning contour (0-based, in order) at once, and :func:`draw` uses it. :class:`Pen`
implements it by calling the per-segment methods; :class:`SegmentPen` does the reverse (it
gathers per-segment calls into arrays), so the pens below do their work on arrays whichever
door is used:

    RecordingPen        keeps the segments (``segments``, ``border``, ``owner``, ``value``)
    EdgesPen            line edges within a tolerance (the rasteriser's input, flatten.py)
    ControlBoundsPen    bounding box of the control points
    BoundsPen           bounding box of the curves themselves
    AreaPen             signed area of every contour (areas.py)
    TransformPen        moves the segments through a point map before passing them on:
                        affine maps move the control points exactly, other maps subdivide
                        within a tolerance (bezier.map_cubics)

A ``lineTo`` given to a :class:`SegmentPen` becomes the straight cubic with handles at the
thirds, as the encoder writes border segments.
"""

from __future__ import annotations

import numpy as np

from .chains import chain_segments, line_segment


class Pen:
    """The protocol, with ``add_segments`` drawn segment by segment."""

    def moveTo(self, pt):  # noqa: N802 (fontTools' names)
        raise NotImplementedError

    def lineTo(self, pt):  # noqa: N802
        raise NotImplementedError

    def curveTo(self, c1, c2, pt):  # noqa: N802
        raise NotImplementedError

    def closePath(self):  # noqa: N802
        pass

    def add_segments(self, segs, border, owner):
        """Draw segments given as arrays (the batched door)."""
        segs = np.asarray(segs, np.float64).reshape(-1, 4, 2)
        for k in range(len(segs)):
            if k == 0 or owner[k] != owner[k - 1]:
                if k:
                    self.closePath()
                self.moveTo(tuple(segs[k, 0]))
            if border[k]:
                self.lineTo(tuple(segs[k, 3]))
            else:
                self.curveTo(tuple(segs[k, 1]), tuple(segs[k, 2]), tuple(segs[k, 3]))
        if len(segs):
            self.closePath()


class SegmentPen(Pen):
    """A pen whose work is done on arrays: per-segment calls are gathered contour by contour
    and passed to :meth:`segments_drawn` (subclasses implement it)."""

    def __init__(self):
        self._contour = []  # segments of the open contour
        self._flags = []
        self._start = self._current = None
        self.n_contours = 0

    def moveTo(self, pt):  # noqa: N802
        self._start = self._current = np.asarray(pt, np.float64)

    def lineTo(self, pt):  # noqa: N802
        pt = np.asarray(pt, np.float64)
        self._contour.append(line_segment(self._current, pt))
        self._flags.append(True)
        self._current = pt

    def curveTo(self, c1, c2, pt):  # noqa: N802
        seg = np.array([self._current, c1, c2, pt], np.float64)
        self._contour.append(seg)
        self._flags.append(False)
        self._current = seg[3]

    def closePath(self):  # noqa: N802
        if self._current is not None and np.any(self._current != self._start):
            self.lineTo(self._start)
        if self._contour:
            n = len(self._contour)
            self.add_segments(np.asarray(self._contour), np.asarray(self._flags, bool), np.zeros(n, np.int64))
        self._contour, self._flags = [], []
        self._start = self._current = None

    def add_segments(self, segs, border, owner):
        n = int(owner[-1]) + 1 if len(owner) else 0
        self.segments_drawn(segs, border, owner + self.n_contours)
        self.n_contours += n

    def segments_drawn(self, segs, border, owner):
        raise NotImplementedError


def draw(channel, pen) -> None:
    """Draw every contour of a channel with ``pen`` (in contour order)."""
    segs, owner = chain_segments(channel.points, channel.offsets)
    pen.add_segments(segs, channel.border if len(segs) else np.zeros(0, bool), owner)


def draw_segments(segs, border, owner, pen) -> None:
    """Draw segments given as arrays (``owner``: the contour of each, 0-based, in order)."""
    pen.add_segments(segs, border, owner)


class RecordingPen(SegmentPen):
    """Keeps what it is given: ``segments`` (S, 4, 2), ``border`` (S,), ``owner`` (S,)."""

    def __init__(self):
        super().__init__()
        self._parts = []

    def segments_drawn(self, segs, border, owner):
        self._parts.append((segs, border, owner))

    def _joined(self, i, empty):
        if len(self._parts) == 1:
            return self._parts[0][i]
        return np.concatenate([p[i] for p in self._parts]) if self._parts else empty

    @property
    def segments(self) -> np.ndarray:
        return self._joined(0, np.zeros((0, 4, 2)))

    @property
    def border(self) -> np.ndarray:
        return self._joined(1, np.zeros(0, bool))

    @property
    def owner(self) -> np.ndarray:
        return self._joined(2, np.zeros(0, np.int64))

    @property
    def value(self) -> list:
        """The drawing as fontTools' RecordingPen lists it: [(operator, (points...)), ...]."""
        ops = []
        Pen.add_segments(_OpsPen(ops), self.segments, self.border, self.owner)
        return ops

    def replay(self, pen) -> None:
        pen.add_segments(self.segments, self.border, self.owner)


class _OpsPen(Pen):
    def __init__(self, ops):
        self.ops = ops

    def moveTo(self, pt):  # noqa: N802
        self.ops.append(("moveTo", (pt,)))

    def lineTo(self, pt):  # noqa: N802
        self.ops.append(("lineTo", (pt,)))

    def curveTo(self, c1, c2, pt):  # noqa: N802
        self.ops.append(("curveTo", (c1, c2, pt)))

    def closePath(self):  # noqa: N802
        self.ops.append(("closePath", ()))


class EdgesPen(RecordingPen):
    """Line edges within ``tol`` of the curves: :meth:`edges` gives (x0, y0, x1, y1, is_source)
    as :func:`isophote.geometry.flatten` does (border segments are one chord each)."""

    def __init__(self, tol: float):
        super().__init__()
        self.tol = float(tol)

    def edges(self):
        from .flatten import flatten

        return flatten(self.segments, self.border, self.tol)


class ControlBoundsPen(RecordingPen):
    """``bounds``: (xmin, ymin, xmax, ymax) of the control points (None when nothing was drawn)."""

    @property
    def bounds(self):
        pts = self.segments.reshape(-1, 2)
        if len(pts) == 0:
            return None
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


class BoundsPen(RecordingPen):
    """``bounds``: (xmin, ymin, xmax, ymax) of the curves (end points and the extrema where a
    coordinate's derivative vanishes inside a segment)."""

    @property
    def bounds(self):
        from .bezier import evaluate

        segs = self.segments
        if len(segs) == 0:
            return None
        pts = [segs[:, 0], segs[:, 3]]
        for axis in (0, 1):
            seg, t = _extrema(segs[:, :, axis])
            pts.append(evaluate(segs[seg], t))
        pts = np.concatenate(pts)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def _extrema(c: np.ndarray):
    """(segment, t) where the cubic coordinate with control values c (S, 4) has a zero
    derivative for 0 < t < 1: roots of a t^2 + b t + k."""
    a = -c[:, 0] + 3 * c[:, 1] - 3 * c[:, 2] + c[:, 3]
    b = 2 * (c[:, 0] - 2 * c[:, 1] + c[:, 2])
    k = c[:, 1] - c[:, 0]
    seg, ts = [], []
    lin = np.abs(a) < 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        seg.append(np.flatnonzero(lin))
        ts.append(-k[lin] / b[lin])
        disc = b * b - 4 * a * k
        ok = ~lin & (disc >= 0)
        r = np.sqrt(np.where(ok, disc, 0.0))
        for sgn in (-1.0, 1.0):
            seg.append(np.flatnonzero(ok))
            ts.append(((-b + sgn * r) / (2 * a))[ok])
    seg, t = np.concatenate(seg), np.concatenate(ts)
    inside = np.isfinite(t) & (t > 0) & (t < 1)
    return seg[inside], t[inside]


class AreaPen(RecordingPen):
    """``areas``: (C,) signed area of every contour drawn (areas.signed_areas: positive for a
    contour running clockwise on screen); ``value``: their sum."""

    @property
    def areas(self) -> np.ndarray:
        from .areas import cubic_signed_areas

        segs, owner = self.segments, self.owner
        seg = cubic_signed_areas(segs[:, 0], segs[:, 1], segs[:, 2], segs[:, 3])
        return np.bincount(owner, weights=seg, minlength=self.n_contours)

    @property
    def value(self) -> float:
        return float(self.areas.sum())


class TransformPen(SegmentPen):
    """Passes the segments on to ``pen`` moved by ``transform`` (a callable on (N, 2) points).

    With ``transform.affine`` true (isophote.apply.warp's Affine) the control points move: the
    moved cubic is the exact image. Otherwise ``transform.jacobian`` must exist and every
    segment is subdivided until the moved pieces are within ``tol`` of the exact image
    (bezier.map_cubics, at most ``max_depth`` halvings).
    """

    def __init__(self, pen, transform, tol: float | None = None, max_depth: int = 18):
        super().__init__()
        self.pen, self.transform, self.tol, self.max_depth = pen, transform, tol, max_depth

    def add_segments(self, segs, border, owner):
        t = self.transform
        if getattr(t, "affine", False):
            moved = t(segs.reshape(-1, 2)).reshape(-1, 4, 2) if len(segs) else segs
            self.pen.add_segments(moved, border, owner)
            return
        from .bezier import map_cubics

        if self.tol is None:
            raise ValueError("a non-affine TransformPen needs a tolerance")
        moved, new_border, src = map_cubics(segs, border, t, t.jacobian, self.tol, self.max_depth)
        self.pen.add_segments(moved, new_border, owner[src])
