"""The isophote SVG profile's constants, and what its writer and reader both use: the tone
curve rule of the profile (stricter than .isoph's: knots on 0..255). The contours'
orientation flags are the signs of geometry.signed_areas."""

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
UV_STROKES = {"A": "#7f7f7f"}  # the hidden (alpha) layer's outline colour


def check_svg_tone(tone: np.ndarray, label: str) -> None:
    """A tone curve as model.py defines it (FormatError otherwise)."""
    if tone.ndim != 2 or tone.shape[1] != 2 or not 2 <= tone.shape[0] <= MAX_TONE_KNOTS:
        raise FormatError(f"channel {label}: a tone curve must be 2 to {MAX_TONE_KNOTS} (x, y) knots")
    if not np.all(np.isfinite(tone)) or tone.min() < 0.0 or tone.max() > 255.0:
        raise FormatError(f"channel {label}: a tone knot is not finite or outside 0..255")
    if not (np.all(np.diff(tone[:, 0]) > 0) and np.all(np.diff(tone[:, 1]) >= 0)):
        raise FormatError(f"channel {label}: a tone curve must have x strictly increasing, y non-decreasing")
