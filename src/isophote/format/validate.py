"""The checks both containers share: what the .isoph and the SVG readers and writers refuse.

Every failure is a FormatError (a LimitError for a size over a limit) with a one-line message
(docs/format.md, "Validation").
"""

from __future__ import annotations

import json

import numpy as np

from ..errors import FormatError, LimitError
from ..model import VectorImage
from .limits import (
    CHANNEL_LAYOUTS, COLOUR_CODES, MAX_HEIGHT, MAX_META_BYTES, MAX_TONE_KNOTS, MAX_WIDTH,
    SOURCE_DEPTHS,
)

__all__ = [
    "check_image_kind", "check_levels", "check_cap_ramp", "check_tone", "check_range",
    "is_forest", "check_semantics", "parse_meta", "meta_bytes",
]


def check_image_kind(vi, too_big=LimitError) -> None:
    """The image-level rules every writer shares: a VectorImage, a size within the limits
    (``too_big`` is raised beyond them), a known colour, source depth and channel layout."""
    if not isinstance(vi, VectorImage):
        raise FormatError(f"expected a VectorImage, got {type(vi).__name__}")
    width, height = int(vi.width), int(vi.height)
    if width < 1 or height < 1:
        raise FormatError(f"image size {width} x {height} is empty")
    if width > MAX_WIDTH or height > MAX_HEIGHT:
        raise too_big(f"image size {width} x {height} exceeds the {MAX_WIDTH} x {MAX_HEIGHT} limit")
    if vi.colour not in COLOUR_CODES:
        raise FormatError(f"unknown colour {vi.colour!r} (grey or yuv)")
    if vi.source_depth not in SOURCE_DEPTHS:
        raise FormatError(f"source depth {vi.source_depth} is not 8 or 16")
    names = tuple(getattr(ch, "name", None) for ch in vi.channels)
    if names not in CHANNEL_LAYOUTS[vi.colour]:
        raise FormatError(f"channels {names} do not fit colour {vi.colour!r}")


def check_levels(levels: np.ndarray, label: str) -> None:
    if not np.all(np.isfinite(levels)):
        raise FormatError(f"channel {label}: a level is not finite")
    if levels.shape[0] > 1 and not np.all(levels[1:] > levels[:-1]):
        raise FormatError(f"channel {label}: levels are not strictly increasing")


def check_cap_ramp(cap_ramp, label: str) -> float:
    """A cap ramp as a float: a number, positive, finite or +infinity (DOME)."""
    try:
        value = float(cap_ramp)
    except (TypeError, ValueError):
        raise FormatError(f"channel {label}: cap_ramp must be a number, not {cap_ramp!r}") from None
    if not value > 0.0:  # NaN fails too
        raise FormatError(f"channel {label}: cap ramp {value!r} is not positive")
    return value


def check_tone(tone: np.ndarray, label: str) -> None:
    """A tone curve: (T, 2) knots, 2 <= T <= MAX_TONE_KNOTS, finite, x strictly increasing,
    y non-decreasing (model.py)."""
    if tone.ndim != 2 or tone.shape[1] != 2:
        raise FormatError(f"channel {label}: tone must be a (K, 2) array of knots")
    if tone.shape[0] > MAX_TONE_KNOTS:
        raise LimitError(f"channel {label}: {tone.shape[0]} tone knots exceed the limit of {MAX_TONE_KNOTS}")
    if tone.shape[0] < 2:
        raise FormatError(f"channel {label}: a tone curve needs at least 2 knots, not {tone.shape[0]}")
    if not np.all(np.isfinite(tone)):
        raise FormatError(f"channel {label}: a tone knot is not finite")
    if not np.all(tone[1:, 0] > tone[:-1, 0]):
        raise FormatError(f"channel {label}: tone knots' x are not strictly increasing")
    if not np.all(tone[1:, 1] >= tone[:-1, 1]):
        raise FormatError(f"channel {label}: tone knots' y decrease (the curve must be monotone)")


def check_range(a: np.ndarray, lo: int, hi: int, what: str) -> None:
    """Every value of ``a`` in [lo, hi)."""
    if a.size and (int(a.min()) < lo or int(a.max()) >= hi):
        bad = int(np.flatnonzero((a < lo) | (a >= hi))[0])
        raise FormatError(f"{what} {int(a[bad])} (entry {bad}) is outside [{lo}, {hi})")


def is_forest(parent: np.ndarray) -> bool:
    """True when following parent links (in [-1, C)) from every contour reaches -1 (no
    cycle). O(C), iterative: deep nesting cannot overflow a stack (_kernels/forest.py)."""
    from ._kernels.forest import is_forest as kernel

    c = parent.shape[0]
    if np.all(parent < np.arange(c)):  # parents before their children: a forest at once
        return True
    return bool(kernel(np.ascontiguousarray(parent, np.int64)))


def check_semantics(label, n_levels, contour_level, parent, cap_band, cap_contour) -> None:
    """A channel's indices: levels in [0, L), parents in [-1, C) without cycles, cap bands in
    [0, L], cap contours in [-1, C)."""
    c = contour_level.shape[0]
    check_range(contour_level, 0, n_levels, f"channel {label}: contour level")
    check_range(parent, -1, c, f"channel {label}: parent")
    if not is_forest(parent):
        raise FormatError(f"channel {label}: parent links form a cycle")
    check_range(cap_band, 0, n_levels + 1, f"channel {label}: cap band")
    check_range(cap_contour, -1, c, f"channel {label}: cap contour")


def parse_meta(b: bytes) -> dict:
    """meta from its UTF-8 JSON bytes: an object, with no NaN or infinity."""
    if not b:
        return {}

    def finite(text):  # JSON has no NaN or infinity, and the writer cannot write them back
        value = float(text)
        if not np.isfinite(value):
            raise ValueError(f"{text} is not a finite number")
        return value

    def no_constant(name):
        raise ValueError(f"{name} is not JSON")

    try:
        meta = json.loads(b.decode("utf-8"), parse_float=finite, parse_constant=no_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise FormatError(f"meta is not valid UTF-8 JSON ({type(e).__name__})") from None
    if not isinstance(meta, dict):
        raise FormatError(f"meta is a JSON {type(meta).__name__}, not an object")
    return meta


def meta_bytes(meta) -> bytes:
    """meta as canonical JSON bytes (sorted keys, no spaces; b"" for none), within the limit."""
    if not meta:
        return b""
    if not isinstance(meta, dict):
        raise FormatError(f"meta must be a dict, not {type(meta).__name__}")

    def default(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        raise TypeError(f"{type(o).__name__} is not JSON-serialisable")

    try:
        # Through JSON once first, so that the keys are strings (sortable) and values plain.
        plain = json.loads(json.dumps(meta, allow_nan=False, default=default))
        text = json.dumps(plain, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    except (TypeError, ValueError, RecursionError) as e:
        raise FormatError(f"meta cannot be written as JSON: {e}") from None
    b = text.encode("utf-8")
    if len(b) > MAX_META_BYTES:
        raise LimitError(f"meta of {len(b)} bytes as JSON exceeds the {MAX_META_BYTES}-byte limit")
    return b
