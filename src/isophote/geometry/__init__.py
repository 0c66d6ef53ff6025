"""Geometry of a channel's contours, shared by every consumer (the rasteriser, the SVG writer,
the overlay, warps, equalisation): a channel's segments, flattening to line edges.

A segment is a (4, 2) array of cubic Bezier control points in source pixels (model.py states
the coordinates once); a channel's segments are an (S, 4, 2) array with a border flag each.
"""

from .flatten import MAX_STEPS, flatten, segments
from .flatten_ref import flatten as flatten_ref

__all__ = ["MAX_STEPS", "flatten", "flatten_ref", "segments"]
