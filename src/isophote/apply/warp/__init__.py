"""Warping a vector image (paper §6): the contours move, no pixel is resampled.

    warp(vi, transform)  ->  per channel (channel.py):
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

Modules: transforms.py (the maps), canvas.py (the output canvas, the moved frame),
channel.py (one channel's steps), clip.py (clipping to the canvas), caps.py, bands.py (band
maps on pixel centres). The geometry (segments, subdivision, the transform pen) is
isophote.geometry's.
"""

from __future__ import annotations

import math

import numpy as np

from ...errors import OptionError
from ...model import VectorImage
from .bands import band_map, winding_map
from .canvas import (MAX_DEPTH, background_values, check_canvas, moved_frame, move_segments, orientation,
                     output_canvas)
from .channel import BACKGROUND_GAP, warp_channel
from .clip import EDGE_EPS
from .transforms import (JACOBIAN_STEP, Affine, Perspective, PointMap, Swirl, Transform, as_transform,
                         perspective_from_points, rotation)

DEFAULT_TOLERANCE = 0.02  # output pixels: the error of a moved curve (encoder ribbons are >= 0.05)

__all__ = [
    "BACKGROUND_GAP", "DEFAULT_TOLERANCE", "EDGE_EPS", "JACOBIAN_STEP", "MAX_DEPTH", "Affine",
    "Perspective", "PointMap", "Swirl", "Transform", "as_transform", "background_values",
    "band_map", "move_segments", "output_canvas", "perspective_from_points", "rotation", "scale",
    "warp", "winding_map",
]


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
    t = checked_transform(vi, transform, tolerance)
    t, w, h = output_canvas(vi, t, canvas)
    check_canvas(w, h)
    reflect = orientation(t, vi) < 0
    frame, cover = moved_frame(vi, t, w, h, reflect, tolerance)
    backgrounds = background_values(vi, background)
    channels = tuple(warp_channel(ch, vi, t, w, h, reflect, frame, cover, backgrounds[ch.name], tolerance)
                     for ch in vi.channels)
    check_finite(channels)
    return VectorImage(width=w, height=h, colour=vi.colour, channels=channels,
                       source_depth=vi.source_depth, meta=dict(vi.meta))


def checked_transform(vi, transform, tolerance: float) -> Transform:
    """The transform as a :class:`Transform`, after the checks on the arguments."""
    if not isinstance(vi, VectorImage):
        raise OptionError(f"expected a VectorImage, got {type(vi).__name__}")
    if not (tolerance > 0):
        raise OptionError("tolerance must be positive")
    t = as_transform(transform)
    if isinstance(t, Perspective):
        t.check_frame(vi.width, vi.height)
    return t


def check_finite(channels) -> None:
    for ch in channels:
        if not (np.isfinite(ch.points).all() and np.isfinite(ch.cap_xy).all()):
            raise OptionError("the point map sent part of the image to a non-finite position")


def scale(vi: VectorImage, factor: float) -> VectorImage:
    """The image enlarged or reduced by ``factor`` as a new vector image (an exact affine
    warp onto a canvas of round(factor * size)). To render at another size, prefer
    ``vi.render(scale=...)``: same contours, and cap ramps in source pixels."""
    if not (factor > 0 and math.isfinite(factor)):
        raise OptionError("scale factor must be positive")
    w, h = max(1, round(vi.width * factor)), max(1, round(vi.height * factor))
    return warp(vi, Affine([[w / vi.width, 0, 0], [0, h / vi.height, 0]]), canvas=(w, h))
