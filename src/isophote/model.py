"""The data model: VectorImage and Channel.

.. warning:: COORDINATES, stated once for the whole package

   x runs to the right, y runs down, and the origin is the top-left corner of the image.
   Pixel (i, j) (row i, column j) is the unit square [j, j+1) x [i, i+1); its sample sits
   at its centre (j + 0.5, i + 0.5). All geometry (control points, cap positions) is in
   these source-pixel units; the image covers [0, width] x [0, height].

Chains
    A chain of n cubic Bezier segments is a (1 + 3n, 2) float64 array
    ``P0, C0a, C0b, P1, C1a, C1b, P2, ..., Pn``. Every contour is closed: Pn == P0.

Orientation
    Every contour is oriented so that the side whose values are >= its level lies to the
    LEFT of the direction of travel as seen on screen (y down). Hence the winding numbers of
    all contours of a channel add up, at any point inside the image, to the point's band:
    the number of the channel's levels that its value is >= ("a sample equal to a level
    counts as above it").

Bands
    Band b of a channel holds values in [levels[b-1], levels[b]) with levels[-1] = -inf and
    levels[L] = +inf. Band 0 lies below every level; band L above every level.
    ``base_band`` is the band of the root region (outside every contour): when the whole
    image border lies above some levels, their contours would only run round the frame, so
    they are not stored and the bands start from base_band instead
    (band = base_band + sum of windings).

Hierarchy (paper §4)
    ``parent[k]`` is the index of the innermost contour whose footprint contains contour k,
    or -1 for the image frame. A region is the footprint of a contour minus the footprints
    of its children (the root region is the frame minus its children).

Caps
    A region bounded by contours of one level only (a peak or a pit, or any region a single
    level closes against the border) cannot be interpolated between two levels. Its profile
    is C(d) = L + (cap_value - L) * min(1, d / min(d_max, CAP_RAMP)), where L is its level, d
    the distance to its contour and d_max the largest such distance inside it: a ramp of at
    most CAP_RAMP pixels from the level up (or down) to a plateau at cap_value, or a cone for
    caps narrower than that. The encoder chooses cap_value by least squares over the region's
    samples. A channel may set its own ``cap_ramp`` instead of CAP_RAMP; ``inf`` (DOME) makes
    every cap a dome that reaches cap_value only at its farthest point from the contour, so
    that no cap is a flat plateau (equalisation uses it: a plateau is a single value that no
    tone curve can spread). ``cap_xy`` is a sample of the region (it identifies the region; the encoder takes the
    sample farthest from its edges), in band
    ``cap_band``; ``cap_contour`` is the region's outer contour (-1 for the root region).
    A region with no contour at all is flat at cap_value.

Tone
    ``tone`` is None or a (K, 2) float64 array of knots (x, y), x strictly increasing,
    y non-decreasing, both on the 0..255 scale, K >= 2: a monotone curve applied to the
    channel's rendered values (piecewise linear; flat beyond the end knots). Edits that
    remap the levels (equalisation) use it to shape the values between the contours.

Storage
    A channel keeps its contours in flat arrays, not objects, so that a photograph's tens of
    thousands of contours cost no Python objects: contour k's chain is
    ``points[offsets[k]:offsets[k+1]]`` and its segments' border flags are
    ``border[(offsets[k] - k) // 3 : (offsets[k+1] - k - 1) // 3]``
    (use :meth:`Channel.chain` and :meth:`Channel.border_flags`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

CHANNEL_NAMES = ("Y", "U", "V", "A")
CAP_RAMP = 2.0  # pixels: the longest ramp of a cap's profile (see Caps above)
DOME = float("inf")  # a channel's cap_ramp for caps without a plateau (see Caps above)


def apply_tone_curve(values: np.ndarray, tone) -> np.ndarray:
    """A tone curve's knots (see Tone above; None = no curve) applied to values, keeping
    their dtype."""
    if tone is None:
        return values
    return np.interp(values, tone[:, 0], tone[:, 1]).astype(values.dtype, copy=False)


@dataclass(frozen=True, eq=False)
class Channel:
    """The contours of one colour channel.

    Attributes
    ----------
    name : str
        "Y", "U", "V" or "A".
    levels : (L,) float64 ndarray
        Strictly increasing level values on the 0..255 scale.
    contour_level : (C,) int32 ndarray
        Index into ``levels`` of each contour.
    offsets : (C + 1,) int64 ndarray
        Contour k's chain is ``points[offsets[k]:offsets[k+1]]``.
    points : (P, 2) float64 ndarray
        All chains, concatenated; each chain has 1 + 3n points. float32 in a master loaded
        with ``isophote.load(path, compact=True)`` for rendering alone (exact: the file's
        1/64 grid; the renderer reads them as the same float64 values).
    border : (S,) bool ndarray
        Per segment (all contours' segments concatenated): True where the segment runs along
        the image border and is therefore not an isoline (never a distance source).
    parent : (C,) int32 ndarray
        Enclosing contour, -1 for the image frame.
    cap_band, cap_contour : (K,) int32 ndarray
    cap_xy : (K, 2) float64 ndarray
    cap_value : (K,) float64 ndarray
        Cap annotations (see the module docstring); both float32 with the points in a
        compact master, exact as they are.
    base_band : int
        Band of the root region (see the module docstring).
    tone : (K, 2) float64 ndarray or None
        Monotone tone curve applied to rendered values (see the module docstring).
    cap_ramp : float
        The longest ramp of the caps' profiles in pixels, > 0; CAP_RAMP unless set, DOME
        (inf) for caps without a plateau (see the module docstring, Caps).
    """

    name: str
    levels: np.ndarray
    contour_level: np.ndarray
    offsets: np.ndarray
    points: np.ndarray
    border: np.ndarray
    parent: np.ndarray
    cap_band: np.ndarray
    cap_contour: np.ndarray
    cap_xy: np.ndarray
    cap_value: np.ndarray
    base_band: int = 0
    tone: np.ndarray | None = None
    cap_ramp: float = CAP_RAMP

    @property
    def n_contours(self) -> int:
        return int(self.contour_level.shape[0])

    @property
    def n_segments(self) -> int:
        return int(self.border.shape[0])

    def chain(self, k: int) -> np.ndarray:
        """(1 + 3n, 2) control points of contour k."""
        return self.points[self.offsets[k] : self.offsets[k + 1]]

    def segment_offsets(self) -> np.ndarray:
        """(C + 1,) int64: contour k's segments are ``border[so[k]:so[k+1]]``."""
        return (self.offsets - np.arange(self.offsets.shape[0])) // 3

    def border_flags(self, k: int) -> np.ndarray:
        so = self.segment_offsets()
        return self.border[so[k] : so[k + 1]]

    def chains(self):
        """Iterate over (level_index, chain, border_flags) for every contour."""
        so = self.segment_offsets()
        for k in range(self.n_contours):
            yield (
                int(self.contour_level[k]),
                self.points[self.offsets[k] : self.offsets[k + 1]],
                self.border[so[k] : so[k + 1]],
            )

    def draw(self, pen) -> None:
        """Draw every contour with a pen (isophote.geometry.pen: moveTo, curveTo for isoline
        segments, lineTo for border segments, closePath; or the batched add_segments)."""
        from .geometry.pen import draw

        draw(self, pen)

    def with_points(self, points: np.ndarray) -> "Channel":
        """The same channel with moved control points (same layout)."""
        return replace(self, points=np.ascontiguousarray(points, dtype=np.float64))

    def equals(self, other: "Channel") -> bool:
        """Exact equality of every field (used by round-trip tests)."""
        if self.name != other.name or self.base_band != other.base_band or self.cap_ramp != other.cap_ramp:
            return False
        for f in (
            "levels", "contour_level", "offsets", "points", "border", "parent",
            "cap_band", "cap_contour", "cap_xy", "cap_value",
        ):
            a, b = getattr(self, f), getattr(other, f)
            if a.shape != b.shape or a.dtype != b.dtype or not np.array_equal(a, b):
                return False
        if (self.tone is None) != (other.tone is None):
            return False
        return self.tone is None or (self.tone.shape == other.tone.shape and np.array_equal(self.tone, other.tone))

    def apply_tone(self, values: np.ndarray) -> np.ndarray:
        """The tone curve applied to rendered values (unchanged when there is none)."""
        return apply_tone_curve(values, self.tone)

    @staticmethod
    def empty(name: str, levels, base_band: int = 0) -> "Channel":
        return Channel(
            base_band=int(base_band),
            name=name,
            levels=np.asarray(levels, dtype=np.float64),
            contour_level=np.zeros(0, np.int32),
            offsets=np.zeros(1, np.int64),
            points=np.zeros((0, 2), np.float64),
            border=np.zeros(0, bool),
            parent=np.zeros(0, np.int32),
            cap_band=np.zeros(0, np.int32),
            cap_contour=np.zeros(0, np.int32),
            cap_xy=np.zeros((0, 2), np.float64),
            cap_value=np.zeros(0, np.float64),
        )


@dataclass(frozen=True, eq=False)
class VectorImage:
    """A vectorised photograph: contours per channel on a width x height canvas.

    ``colour`` is "yuv" (channels Y, U, V [, A]) or "grey" (Y [, A]). ``source_depth`` is the
    bit depth of the raster it was encoded from (8 or 16), kept for information only:
    renders choose their own depth.
    """

    width: int
    height: int
    colour: str
    channels: tuple
    source_depth: int = 8
    meta: dict = field(default_factory=dict)

    def channel(self, name: str) -> Channel:
        for ch in self.channels:
            if ch.name == name:
                return ch
        raise KeyError(name)

    @property
    def has_alpha(self) -> bool:
        return any(ch.name == "A" for ch in self.channels)

    def equals(self, other: "VectorImage") -> bool:
        return (
            self.width == other.width
            and self.height == other.height
            and self.colour == other.colour
            and self.source_depth == other.source_depth
            and len(self.channels) == len(other.channels)
            and all(a.equals(b) for a, b in zip(self.channels, other.channels))
        )

    # The operations live in their own modules; these are thin doors to them.
    def render(self, width=None, height=None, scale=None, **options):
        """Render to a raster; see :func:`isophote.render.render` for the options."""
        from .render import render

        return render(self, width=width, height=height, scale=scale, **options)

    def prepare(self, zooms=(1.0,)):
        """Prepare (once, kept with this image) what tiles and renders at these zooms share;
        see :mod:`isophote.render.tiles`."""
        from .render.prepare import prepare

        return prepare(self, zooms)

    def tile(self, region, size, **options):
        """The crop region = (x, y, w, h) rendered to size = (out_w, out_h), from the cached
        preparation: equal to ``render(crop=region, width=, height=)``."""
        from .render.prepare import prepare

        prepare(self, ())
        return self.render(width=int(size[0]), height=int(size[1]), crop=tuple(region), **options)

    def save(self, path) -> None:
        """Write an .isoph file (atomically)."""
        from .format.isoph import save

        save(self, path)
