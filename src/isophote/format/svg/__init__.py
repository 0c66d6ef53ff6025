"""SVG: a VectorImage as an SVG 1.1 document that every viewer shows and isophote reads back.

This docstring is the specification of the isophote SVG profile.

What a file holds
=================
One document does two jobs:

- a PREVIEW that any browser, Inkscape or resvg shows as the photograph: isophote's own
  flat-fill render (``render(fill="flat")``) drawn by the viewer. Every channel's contours
  are filled flat (nonzero rule) with their region's flat value (the middle of its band's
  levels, through the tone curve; preview.py), stacked by the painter's algorithm (every
  parent before its children, so each contour paints its whole footprint and its children
  paint over it: no gaps between regions), over a rectangle in the root region's value.
  The contours are painted as POLYLINES (polyline.py: each cubic cut into chords within
  0.2 px, the vertices moved out so that each region keeps its area), not as the cubics:
  viewers flatten a cubic themselves into 2 to 8 chords inside its arc, which on dense
  photographs moves an eighth of the pixels to the neighbouring band. The polylines of one
  channel, one depth and one colour share a path. A yuv image paints Y, U and V as the red,
  green and blue components of one group (U and V blended on with
  ``mix-blend-mode:lighten``), and an ``feColorMatrix`` filter turns that (Y, U, V) into
  RGB with colour.py's matrix (plus a quarter level: resvg truncates the filter's result to
  8 bits, Chromium rounds it); a grey image paints Y in grey. Edges are crisp by default
  (``shape-rendering="crispEdges"``: each pixel shows the region at its centre, as the flat
  render at 1x does; ``to_svg(vi, crisp=False)`` anti-aliases). The preview is opaque. It
  is not data: the reader ignores the preview group.
- the DATA: every contour of every channel, its level, its parent, its border flags, every
  cap annotation, the levels, base band and tone curve of each channel, and the image's
  size, colour, source depth and meta, as the contours' exact cubic paths in one hidden
  layer per channel (outlines, for an editor that shows them). ``from_svg(to_svg(vi))``
  equals ``vi`` exactly (``VectorImage.equals``, dtypes included, for any valid image, on
  the 1/64 grid or not).
- ``to_svg(vi, lines=False)`` (``isophote svg --curves``) writes no polylines: the Y, U and
  V data layers are visible and ARE the preview's paths (filled with their region's colour,
  in painter's order, inside the filter group), the layout an editor wants; about a third
  smaller, but up to 1.7 dB further from the flat render on dense photographs
  (benchmarks/results/svg_preview.md).

Layout::

    <svg xmlns="http://www.w3.org/2000/svg" xmlns:iso="urn:x-isophote:svg:1"
         xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape"
         version="1.1" width="W" height="H" viewBox="0 0 W H"
         iso:format="1" iso:width="W" iso:height="H" iso:colour="yuv" iso:source-depth="8">
      <metadata><iso:meta>{"json":"object"}</iso:meta></metadata>     (only if meta)
      <defs><filter id="isophote-yuv" ...><feColorMatrix .../></filter></defs>  (yuv only)
      <g id="isophote-preview" filter="url(#isophote-yuv)" shape-rendering="crispEdges">
        <g transform="scale(0.015625)">                                (Y; grey: no filter)
          <rect width="64W" height="64H" fill="#yy0000"/>            (the root region)
          <path fill="#yy0000" d="Mx yl dx dy dx dy ... zMx yl ... z"/>  (one depth, one colour)
          ...
        </g>
        <g transform="scale(0.015625)" style="mix-blend-mode:lighten"> U: fill="#00uu00" ... </g>
        <g transform="scale(0.015625)" style="mix-blend-mode:lighten"> V: fill="#0000vv" ... </g>
      </g>
      <g id="isophote-Y" inkscape:groupmode="layer" inkscape:label="Y"
         transform="scale(0.015625)" iso:channel="Y" iso:levels="7.5 17.5 ..."
         iso:base-band="0" iso:caps="contour band x y value ..."
         [iso:tone="x0 y0 x1 y1 ..."] [iso:cap-ramp="R" or "dome"]
         style="display:none" fill="none" stroke="#000" stroke-width="16">
        <path iso:c="k level parent orientation segments" [iso:b="0011..."]
              d="Mx yc dx dy dx dy dx dy ... z m dx dy ..."/>
        ...
      </g>
      <g id="isophote-U" ...> ... </g>  <g id="isophote-V" ...> ... </g>
      <g id="isophote-A" ... style="display:none" fill="none" stroke="#..."> ... </g>
    </svg>

With ``lines=False`` the preview group is absent and the Y, U and V layers sit inside
``<g filter="url(#isophote-yuv)" shape-rendering="crispEdges">``, visible, with
``stroke="none"`` (U and V with ``style="mix-blend-mode:lighten"``), a root rectangle each,
and a ``fill`` on every path.

The canvas is ``iso:width`` x ``iso:height`` source pixels (model.py's coordinates; the
viewBox says the same to viewers). Inside a channel layer, coordinates are in 1/64 source
pixel (the layer's ``scale(0.015625)``): points on the encoder's 1/64 grid are integers, so
they print short and exactly, and relative ``c`` commands (differences of integers) are
exact too. A chain with any point off that grid is written with absolute ``C`` commands and
Python's shortest round-trip float repr of 64 x the coordinate (exact: scaling by a power of
two is exact). ``z`` closes the path; the last cubic already ends on the first point.

Per contour, ``iso:c`` holds five integers: the contour's index k in the channel, its level
index, its parent's index (-1: the frame), the sign of its signed area as written (+1, -1
or 0) and its number of segments as written. Paths are written parents first (painter's
order), not in index order; k restores the order. ``iso:b`` (only on contours that have
border segments) is one '0'/'1' per segment.

Caps: the layer's ``iso:caps`` lists the channel's caps in order, five numbers each:
``contour band x y value``. For the root region (contour -1), (x, y) is the cap's position
in the layer's units, exactly. A contour's caps also travel in its path data, as MARKERS:
after the closing ``z``, one moveto per cap, in cap order ("m dx dy", relative to the
chain's start and then to the previous marker; absolute "M x y" off the grid). A subpath
that is only a moveto draws nothing in the preview, but editors transform it with the rest
of the path (Inkscape bakes moves, rotations and flips into path data, markers included),
so caps turn and mirror with their contour. For those caps (x, y) is a fallback, the offset
from the contour's first point to the nearest layer unit, used when the markers are gone
(Inkscape's Simplify drops them). ``value`` and the levels are shortest round-trip decimals.

Tone: ``iso:tone`` (only on a channel that has a tone curve, model.py's Channel.tone) lists
the curve's knots as "x y" pairs in order, shortest round-trip decimals (exact): at least
two knots, at most MAX_TONE_KNOTS (.isoph's limit), every number in [0, 255], x strictly increasing, y
non-decreasing. No attribute: no tone curve. The preview's values go through the tone
curve, as the render's do.

Cap ramp: ``iso:cap-ramp`` (only on a channel whose Channel.cap_ramp is not model.py's
CAP_RAMP) is the ramp in pixels, a positive number, or "dome" for DOME (caps without a
plateau, as equalisation leaves them). No attribute: CAP_RAMP.

Preview colours: each region's flat value rounded to 8 bits (browsers keep 8 bits per
component in the group the filter reads): at most 0.5 off in Y, U and V, 1.4 in R, G, B,
plus the quarter level the filter adds (preview.STORE_OFFSET). The preview is not data (the
reader ignores the preview group, fills, rectangles, filter and blend modes). Its cost: the
polylines (a few bytes a chord, at most 64 chords a cubic; 1.3-1.5x the curves SVG on the
wide corpus), a rectangle per layer and the filter; never anything per pixel. With
``lines=False``: one fill attribute per contour (15 bytes).
Colour profiles: a yuv master that carries an ICC profile in meta (icc.py) keeps it in the
SVG's meta, and its preview's filter ends in an affine map to sRGB fitted to LittleCMS on
the image's own colours (preview.icc_affine; measured:
benchmarks/results/design_choices.md#svg-icc-affine); a grey image's preview shows its
coded values as sRGB.

Reading edited files
====================
What a drawing program may do, and what ``from_svg`` makes of it (to the data layers: in
the default layout the visible polylines are only the preview, so edit the file written
with ``lines=False``, ``isophote svg --curves``, or show the hidden layers):

- transforms on a path, a group or a layer (matrix, translate, scale, rotate, skewX, skewY,
  any composition): applied to the control points (a cubic under an affine map is the map
  of its control points, exactly) and to the caps' markers.
- rewritten path data: absolute or relative M, L, H, V, C, S, Q, T, A and Z, with any
  number syntax SVG allows. Lines, quadratics and the implicit closing line become cubics
  (lines and quadratics exactly, arcs as quarter-turn pieces within 3e-4 of their radius). A contour must stay one
  subpath; an open one is closed with a line.
- more or fewer segments than written (node editing, simplifying): the stored border flags
  no longer match, so a segment is a border segment when all four control points lie on
  one edge of the frame (the encoder's border segments all do, and no others). A path with
  other markers than caps (some dropped) places its caps by the fallback offsets.
- mirroring and reversing: a contour whose signed area changed sign (a flip, a path
  reversal) is reversed back, so its >= side stays on its left (model.py's orientation).
- deleting a contour: the others are renumbered in order; children of a deleted contour
  hang from the frame (-1), caps of its region are dropped (the renderer uses neither
  parents nor cap contours, only band windings and cap positions).
- z-order, grouping, ids, styles, colours, layer visibility, other namespaces, and paths,
  shapes or text without ``iso:c`` (a drawing program's additions, the preview's rectangles and
  filter): ignored.

Checked with Inkscape 1.2 (tests/format/test_svg.py, where it is installed): open and save keeps
the image exactly; rotate, flip and align (move) are honoured, caps included.

Validation
==========
Never trust a file. Every problem is a FormatError (a LimitError for a size over a limit)
with a one-line reason, never another exception type: text over MAX_SVG_BYTES (also after
gunzip, which stops reading at the limit), a DTD with entity declarations (refused before parsing: no
entity expansion at all), XML that does not parse, a root that is not an isophote SVG,
unknown format version, colour, depth or channel layout, bad numbers (not finite, beyond
the .isoph limits), malformed transforms or path data, duplicate contours, levels, parents,
bands out of range, parent cycles, tone curves that are not monotone or leave 0..255. The
work is linear in the size of the text.

Where it lives
==============
write.py (to_svg, save_svg), preview.py (the preview's region values, paints and filter),
pathdata.py (SVG path data and transforms in general, and the fast path for the writer's own layout), read.py
(from_svg, load_svg, is_svg), profile.py (the profile's constants and its tone rule; the
orientation flags are geometry.signed_areas' signs); the limits and the checks shared with .isoph are
format/limits.py and format/validate.py.
"""

from __future__ import annotations

from ..limits import MAX_SVG_BYTES, SVG_FORMAT_VERSION
from .pathdata import parse_path, parse_transform
from .profile import NS_ISO
from .read import from_svg, is_svg, load_svg
from .write import save_svg, to_svg

__all__ = [
    "to_svg", "from_svg", "save_svg", "load_svg", "is_svg", "parse_path", "parse_transform",
    "SVG_FORMAT_VERSION", "NS_ISO", "MAX_SVG_BYTES",
]
