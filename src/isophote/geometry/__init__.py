"""Geometry of a channel's contours, shared by every consumer (the rasteriser, the SVG writer,
the overlay, warps, equalisation).

A segment is a (4, 2) array of cubic Bezier control points in source pixels (model.py states
the coordinates once); a channel's segments are an (S, 4, 2) array with a border flag each.

    chains.py    a channel's segments and owning contours, and back (join_segments)
    bezier.py    evaluation, de Casteljau subdivision, mapping cubics through a smooth map
    flatten.py   segments to line edges within a tolerance (the rasteriser's input)
    areas.py     exact signed areas and moments of cubic chains; polyline areas
    pen.py       the pen protocol (draw(channel, pen)) and its pens
"""

from .areas import polyline_areas, segment_moments, signed_areas
from .bezier import evaluate, evaluate_grid, map_cubics, split, subsegment
from .chains import chain_segments, join_segments, line_segment, segment_starts, segments
from .flatten import MAX_STEPS, contour_edges, flatten, flatten_selected
from .flatten_ref import flatten as flatten_ref
from .pen import (AreaPen, BoundsPen, ControlBoundsPen, EdgesPen, Pen, RecordingPen, SegmentPen,
                  TransformPen, draw, draw_segments)

__all__ = [
    "MAX_STEPS", "AreaPen", "BoundsPen", "ControlBoundsPen", "EdgesPen", "Pen", "RecordingPen",
    "SegmentPen", "TransformPen", "chain_segments", "contour_edges", "draw", "draw_segments", "evaluate",
    "evaluate_grid", "flatten", "flatten_ref", "flatten_selected", "join_segments", "line_segment", "map_cubics",
    "polyline_areas", "segment_moments", "segment_starts", "segments", "signed_areas", "split",
    "subsegment",
]
