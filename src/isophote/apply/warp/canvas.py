"""The output canvas of a warp, the source frame moved onto it, and what it leaves uncovered."""

from __future__ import annotations

import numpy as np

from ...colour import rgb_to_yuv
from ...errors import OptionError
from ...geometry.chains import chain_segments
from ...geometry.pen import ControlBoundsPen, RecordingPen, TransformPen, draw_segments
from ...model import VectorImage
from .bands import winding_map
from .transforms import Affine, Transform

MAX_DEPTH = 18  # halvings of one segment at most (2**-18 of a segment)
MAX_CANVAS = 400_000_000  # output pixels: a larger canvas is refused


def move_segments(segs, border, transform: Transform, tol: float, pen=None):
    """Segments (S, 4, 2) of one contour set moved through ``transform``: exactly (control
    points) for an affine map, else subdivided within ``tol`` (at most MAX_DEPTH halvings).

    Returns (new_segs (P, 4, 2), new_border (P,), source_index (P,)), pieces in chain order.
    """
    rec = RecordingPen() if pen is None else pen
    index = np.arange(len(segs))
    draw_segments(segs, border, index, TransformPen(rec, transform, tol, MAX_DEPTH))
    return rec.segments, rec.border, rec.owner


def frame_segments(w, h, subdivide: int = 1) -> np.ndarray:
    """(4 subdivide, 4, 2) the source frame as a closed chain of straight segments running
    counter-clockwise on screen (its inside on its left), each side cut into ``subdivide``."""
    corners = np.array([[0, 0], [0, h], [w, h], [w, 0], [0, 0]], float)
    pts = [corners[0]]
    for a, b in zip(corners[:-1], corners[1:]):
        for k in range(subdivide):
            s0, s1 = a + (b - a) * k / subdivide, a + (b - a) * (k + 1) / subdivide
            pts += [s0 + (s1 - s0) / 3, s0 + 2 * (s1 - s0) / 3, s1]
    segs, _ = chain_segments(np.asarray(pts), np.array([0, len(pts)]))
    return segs


def output_canvas(vi: VectorImage, transform: Transform, canvas):
    """(transform, width, height): the transform shifted onto the chosen canvas."""
    if isinstance(canvas, str) and canvas == "same":
        return transform, vi.width, vi.height
    if isinstance(canvas, str) and canvas == "fit":
        pen = ControlBoundsPen()
        frame = frame_segments(vi.width, vi.height)
        move_segments(frame, np.ones(len(frame), bool), transform, 0.05, pen=pen)
        x0, y0, x1, y1 = pen.bounds
        size = np.ceil(np.array([x1, y1]) - np.array([x0, y0]) - 1e-6)
        shift = Affine([[1, 0, -x0], [0, 1, -y0]])
        w, h = int(max(1, size[0])), int(max(1, size[1]))
        return transform.then(shift), w, h
    try:
        w, h = (int(v) for v in canvas)
    except (TypeError, ValueError):
        raise OptionError(f"canvas must be 'same', 'fit' or (width, height), got {canvas!r}") from None
    if w < 1 or h < 1:
        raise OptionError(f"canvas {w}x{h} is empty")
    return transform, w, h


def check_canvas(w: int, h: int) -> None:
    if w * h > MAX_CANVAS:
        raise OptionError(f"output canvas {w}x{h} is too large")


def orientation(t: Transform, vi: VectorImage) -> float:
    """The sign of the map's Jacobian (at the image centre for a non-affine map): < 0 for a
    reflection."""
    if isinstance(t, Affine):
        return t.determinant
    c = np.array([[vi.width / 2.0, vi.height / 2.0]])
    return float(np.linalg.det(t.jacobian(c)[0]))


def moved_frame(vi: VectorImage, t: Transform, w: int, h: int, reflect: bool, tol: float):
    """(segments, cover): the source frame moved (its inside kept on its left) and the
    (h, w) bool mask of the output pixels it covers."""
    frame = frame_segments(vi.width, vi.height, 1 if t.affine else 8)
    segs, _, _ = move_segments(frame, np.ones(len(frame), bool), t, tol)
    if reflect:
        segs = segs[::-1, ::-1]
    fx = segs[:, [0, 3]]
    cover = winding_map(fx[:, 0, 0], fx[:, 0, 1], fx[:, 1, 0], fx[:, 1, 1], w, h) != 0
    return segs, cover


def background_values(vi: VectorImage, background) -> dict:
    """Channel name -> the value of the flat background, from an RGB colour on 0..255."""
    rgb = np.asarray(background, dtype=np.float64).reshape(-1)
    if rgb.size == 1:
        rgb = np.repeat(rgb, 3)
    if rgb.size != 3 or not np.all((rgb >= 0) & (rgb <= 255)):
        raise OptionError("background must be an R,G,B colour on 0..255 (or one grey value)")
    yuv = rgb_to_yuv(rgb[None])[0] if vi.colour == "yuv" else np.array([rgb @ [0.299, 0.587, 0.114], 128, 128])
    return {"Y": float(yuv[0]), "U": float(yuv[1]), "V": float(yuv[2]), "A": 0.0}


