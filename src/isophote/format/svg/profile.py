"""The isophote SVG profile's constants, and what its writer and reader both use: the tone
curve rule of the profile (stricter than .isoph's: knots on 0..255) and the contours' exact
signed areas (their orientation, written and checked on reading)."""

from __future__ import annotations

import numpy as np

from ...errors import FormatError
from ..limits import CAP_VALUE_LIMIT, COORD_LIMIT, MAX_TONE_KNOTS, QUANT

NS_SVG = "http://www.w3.org/2000/svg"
NS_ISO = "urn:x-isophote:svg:1"
NS_INKSCAPE = "http://www.inkscape.org/namespaces/inkscape"
LOCAL_SCALE = QUANT  # layer units per source pixel: 64, so the 1/64 grid is the integers
MAX_COORD = COORD_LIMIT / QUANT  # |coordinate| in source pixels, as in .isoph (2**24)
MAX_CAP_VALUE = CAP_VALUE_LIMIT / QUANT
GRADIENT_MIN_GAIN = 1e4  # squared error (0..255 scale, summed over RGB and pixels) a gradient must remove
UV_STROKES = {"U": "#2a7fff", "V": "#ff2a7f", "A": "#7f7f7f"}  # hidden layers' outline colours


def check_svg_tone(tone: np.ndarray, label: str) -> None:
    """A tone curve as model.py defines it (FormatError otherwise)."""
    if tone.ndim != 2 or tone.shape[1] != 2 or not 2 <= tone.shape[0] <= MAX_TONE_KNOTS:
        raise FormatError(f"channel {label}: a tone curve must be 2 to {MAX_TONE_KNOTS} (x, y) knots")
    if not np.all(np.isfinite(tone)) or tone.min() < 0.0 or tone.max() > 255.0:
        raise FormatError(f"channel {label}: a tone knot is not finite or outside 0..255")
    if not (np.all(np.diff(tone[:, 0]) > 0) and np.all(np.diff(tone[:, 1]) >= 0)):
        raise FormatError(f"channel {label}: a tone curve must have x strictly increasing, y non-decreasing")



def _signed_areas(points: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """(C,) exact signed areas of the closed cubic chains (shoelace sign convention)."""
    c = offsets.shape[0] - 1
    if c == 0:
        return np.zeros(0)
    nseg = (np.diff(offsets) - 1) // 3
    first = np.repeat(offsets[:-1], nseg) + 3 * (np.arange(int(nseg.sum())) - np.repeat(np.cumsum(nseg) - nseg, nseg))
    p = [points[first + i] for i in range(4)]

    def cross(a, b):
        return a[:, 0] * b[:, 1] - b[:, 0] * a[:, 1]

    seg = (6 * cross(p[0], p[1]) + 3 * cross(p[0], p[2]) + cross(p[0], p[3])
           + 3 * cross(p[1], p[2]) + 3 * cross(p[1], p[3]) + 6 * cross(p[2], p[3])) / 20.0
    return np.bincount(np.repeat(np.arange(c), nseg), weights=seg, minlength=c)

